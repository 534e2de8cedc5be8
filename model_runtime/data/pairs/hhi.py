"""HHI pairs (stand-in for Inter-X), `build_hhi_pairs`: a real ego clip (or a copy derived from one) and a
partner, one rule per pair:
    approach_face  a walking ego: a standing partner waits ~1 m beyond the point where the walk ends
                   (0.9-1.2 m, plus 0.3 s of the final speed: captured walks end mid-stride), facing
                   back along the walk, so the approach ends in front of and facing the partner.
    greet          a bow / wave / call / bye / raise-hand clip: a standing partner ~1.5 m in front of
                   the ego, facing it, so the gesture is addressed to it.
    avoid_blocker  a walk-turn clip: a standing partner on the straight-ahead line of the pre-turn walk,
                   0.6-1.1 m past the farthest point the ego's body reaches on that line, facing the
                   ego, so the turn reads as turning away from someone blocking the way.
    turn_to_face   a turned copy of a standing clip (`<name>#turn<k>`, data/turns.py, since no clip turns on
                   the spot): a standing partner 1.0-2.4 m ahead of where the turn ends, facing the ego, so
                   the turn reads as turning to face someone.
    arrive_face    a walk slowed to rest (`<name>#arriveface<k>`, data/meeting.py): a standing partner 0.9-1.2 m
                   ahead of where it stops, facing it, so the walk ends at rest in front of and facing them.
    avoid_walker   a walk bent around a real walker crossing or coming head-on (`<name>#avoid<k>`,
                   data/avoidance.py); the partner is that walker, at least AVOID_CLEARANCE away.
    step_aside     a standing clip shifted off a real walker's line (`<name>#stepaside<k>`, data/avoidance.py),
                   or turning and walking off it (`<name>#walkaside<k>`, data/walk_aside.py); the partner is
                   that walker, at least AVOID_CLEARANCE away.
    follow         a walk re-timed behind a real walker on its line (`<name>#follow<k>`, data/following.py);
                   the partner is that walker, never closer than FOLLOW_MIN_GAP (pelvis to pelvis).
    face_arrival   a standing clip turned toward a real walker who walks up to it and stops in front of it
                   (`<name>#greeted<k>`, data/face_arrivals.py); the partner is that walker, at least
                   AVOID_CLEARANCE away.
    two_person     one person of a real two-person capture (`<take>#twoperson<k>`, data/two_person_pairs.py); the
                   partner is the other person of the same take, as captured: no clearance is asked (real people
                   touch when they shake hands).
The first five place bodies from *other* real standing clips, moved rigidly, with a random body scale in
[0.9, 1.1] and a random timing offset in [-0.5, 0.5] s, never closer than MIN_CLEARANCE to the ego. The
walking partners of the last four were made with their copy and are stored as clips
(new_clips.partner_clip_name); their clearance is checked again here on their FK joints. A mirrored copy
(`<name>#mirror0`) is a real motion reflected and follows the real-clip rules.

An earlier "follow" rule put a walking leader ahead on the ego's real walk and was dropped: it taught the module
to walk on toward a person ahead, into a partner standing 3 m away (model_runtime/train.py). The follow kind
here only exists where the partner keeps walking, on a small share of the walks (data/following.py).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry import normalized
from ..library import ClipLibrary, derived_kind
from ..new_clips import partner_clip_name
from .clips import MOVING_DISTANCE, ClipCache, PathInfo, facing_xy, is_gesture
from .placement import min_clearance, place_standing, standing_frames, standing_partners, standing_source

MIN_CLEARANCE = 0.45      # m between any ego joint and any partner joint; accepted pairs keep at least this
AVOID_CLEARANCE = 0.3     # m: the same for the walking partners of avoid_walker, step_aside and face_arrival
FOLLOW_MIN_GAP = 1.0      # m between the pelvises (floor plane) of a follow pair, at every frame
SCALE_RANGE = (0.9, 1.1)  # partner body scale
MAX_SHIFT = 5             # partner timing offset, frames (0.5 s at 10 fps)
ARRIVE_DISTANCE = (0.9, 1.2)   # m from where an arrive_face copy stops to its partner's pelvis
HHI_KINDS = ("approach_face", "greet", "avoid_blocker", "turn_to_face", "arrive_face", "avoid_walker", "step_aside",
             "follow", "face_arrival", "two_person")
# the pair kind of each kind of derived copy (library.derived_kind); a mirrored copy takes the real-clip rules
COPY_KINDS = {"turn": "turn_to_face", "arriveface": "arrive_face", "avoid": "avoid_walker",
              "stepaside": "step_aside", "follow": "follow", "greeted": "face_arrival",
              "walkaside": "step_aside", "ctlavoid": "avoid_walker", "ctlgreeted": "face_arrival",
              "twoperson": "two_person"}
# the partner is the copy's partner clip
WALKING_PARTNER_KINDS = ("avoid_walker", "step_aside", "follow", "face_arrival", "two_person")


@dataclass(eq=False)
class HHIPair:
    """An ego clip and an invented partner, frame-aligned with the ego clip's T frames."""
    ego: int                    # clip index in the library
    partner: np.ndarray         # (T, 22, 3) float32 world joints
    kind: str                   # one of HHI_KINDS


def _hhi_kinds(path: PathInfo, caption: str) -> list[str]:
    """Rules that fit a clip, its defining one first."""
    if path.turning:
        # approach_face first: on a turning walk the partner waits where the turn leads, the only
        # "turn towards someone" signal in the data (it has no in-place turns); avoid_blocker next
        return ["approach_face", "avoid_blocker"]
    if path.moving:
        return ["approach_face"]
    if is_gesture(caption) and path.travel < MOVING_DISTANCE:
        return ["greet"]
    return []


def _hhi_one(kind: str, ego: int, clips: ClipCache, rng: np.random.Generator, standing: list[int]
             ) -> np.ndarray | None:
    ej, path = clips.joints(ego), clips.path(ego)
    t = len(ej)
    scale = float(rng.uniform(*SCALE_RANGE))
    shift = int(rng.integers(-MAX_SHIFT, MAX_SHIFT + 1))
    src, src_frames = standing_source(clips, rng, standing, ego)
    frames = standing_frames(src_frames, t, shift)
    if kind == "approach_face":
        end = ej[-1, 0, :2].astype(np.float64)
        d = float(rng.uniform(0.9, 1.2)) + 0.3 * min(path.end_speed, 2.0)
        side = np.array([-path.h_end[1], path.h_end[0]])
        target = end + d * path.h_end + float(rng.uniform(-0.15, 0.15)) * side
        face = normalized(end - target)
        return place_standing(src, frames, int(frames[-1]), target, face, scale)
    if kind == "arrive_face":
        end = ej[-1, 0, :2].astype(np.float64)
        face = facing_xy(ej[-1].astype(np.float64))
        side = np.array([-face[1], face[0]])
        target = end + float(rng.uniform(*ARRIVE_DISTANCE)) * face + float(rng.uniform(-0.1, 0.1)) * side
        return place_standing(src, frames, int(frames[-1]), target, -face, scale)
    if kind == "turn_to_face":
        end = ej[-1, 0, :2].astype(np.float64)
        face = normalized(path.facing[-3:].mean(0))
        side = np.array([-face[1], face[0]])
        target = end + float(rng.uniform(1.0, 2.4)) * face + float(rng.uniform(-0.15, 0.15)) * side
        return place_standing(src, frames, int(frames[-1]), target, -face, scale)
    if kind == "greet":
        mean_face = normalized(path.facing.mean(0))
        centre = ej[:, 0, :2].mean(0)
        target = centre + float(rng.uniform(1.3, 1.7)) * mean_face
        return place_standing(src, frames, int(frames[t // 2]), target, -mean_face, scale)
    if kind == "avoid_blocker":
        # on the straight-ahead line, just past the farthest point the ego's body reaches on that line
        on = path.xy[path.onset]
        rel = ej[:, :, :2].reshape(-1, 2) - on
        side = np.array([-path.h_start[1], path.h_start[0]])
        band = np.abs(rel @ side) < 0.35
        reach = float((rel @ path.h_start)[band].max()) if band.any() else 0.0
        d = max(reach, 0.0) + float(rng.uniform(0.6, 1.1))
        if d > 3.0:
            return None
        target = on + d * path.h_start
        return place_standing(src, frames, int(frames[path.onset]), target, -path.h_start, scale)
    raise ValueError(f"unknown HHI pair kind {kind!r}; use one of {', '.join(HHI_KINDS)}")


def build_hhi_pairs(lib: ClipLibrary, clip_ids: list[int], seed: int = 0, per_clip: int = 2,
                    kinds: tuple[str, ...] = HHI_KINDS) -> list[HHIPair]:
    """Up to `per_clip` HHI pairs per clip of `clip_ids` (rules in the module docstring), of the given kinds;
    one for a copy made with its own walking partner.

    Clips no rule fits (e.g. dance, jumps, side steps, partner clips) give none. Deterministic for a seed; a
    clip's pairs do not depend on which other clips are in `clip_ids`. Every pair keeps the partner at least
    MIN_CLEARANCE (AVOID_CLEARANCE for avoid_walker and step_aside) from the ego at every frame (placements
    that do not are resampled, then skipped).
    """
    index = {name: i for i, name in enumerate(lib.names)}
    standing = standing_partners(lib)
    walkers = [index.get(partner_clip_name(lib.names[i]), i) for i in clip_ids]
    clips = ClipCache(lib, list(clip_ids) + walkers + standing)   # FK of the clips this build reads
    out: list[HHIPair] = []
    for ego in clip_ids:
        rng = np.random.default_rng([seed, int(ego)])
        copy = derived_kind(lib.names[ego])
        rules = _hhi_kinds(clips.path(ego), lib.captions[ego]) if copy in ("", "mirror") else \
            [COPY_KINDS[copy]] if copy in COPY_KINDS else []
        fits = [k for k in rules if k in kinds]
        if not fits or per_clip <= 0:
            continue
        if fits[0] in WALKING_PARTNER_KINDS:     # one partner per copy: the walker it was made with
            pair = _walking_partner_pair(fits[0], ego, clips, index)
            out += [pair] if pair is not None else []
            continue
        order = fits[:1] + [fits[1:][i] for i in rng.permutation(len(fits) - 1)]
        for n in range(per_clip):
            kind = order[n % len(order)]
            for _ in range(8):
                partner = _hhi_one(kind, ego, clips, rng, standing)
                if partner is not None and np.isfinite(partner).all() and \
                        min_clearance(clips.joints(ego), partner) >= MIN_CLEARANCE:
                    out.append(HHIPair(int(ego), partner.astype(np.float32), kind))
                    break
    return out


def _walking_partner_pair(kind: str, ego: int, clips: ClipCache, index: dict[str, int]) -> HHIPair | None:
    """The pair of a copy made with its own walking partner (or captured with its real one), if that partner clip
    is in the library and keeps the kind's distance on the FK joints."""
    k = index.get(partner_clip_name(clips.lib.names[ego]))
    if k is None or clips.lib.frames(k) != clips.lib.frames(ego):
        return None
    ej, pj = clips.joints(ego), clips.joints(k)
    if not np.isfinite(pj).all():
        return None
    if kind == "two_person":
        ok = True                 # captured together: their distances are real, whatever they are
    elif kind == "follow":
        ok = np.linalg.norm(ej[:, 0, :2] - pj[:, 0, :2], axis=-1).min() >= FOLLOW_MIN_GAP and \
            min_clearance(ej, pj) >= MIN_CLEARANCE
    else:
        ok = min_clearance(ej, pj) >= AVOID_CLEARANCE
    return HHIPair(int(ego), pj.astype(np.float32), kind) if ok else None
