"""Walk-aside copies for the HHI stage (`<source walk>#walkaside<k>`): a standing person gets out of a walker's
way by turning and walking a few real steps off its line, then stopping.

Why: the step-aside copies (data/avoidance.py) slide a standing clip sideways with its feet planted. Modules trained
on more of them stepped a standing ego 0-0.5 m aside where the copies moved 0.6-1.4 m (README, "Getting out of a
walker's way"): a body gliding sideways is not motion the VAE has learned to encode. These copies make room with
real footwork, built as the turn-then-walk arrivals are (data/turn_arrivals.py):

1. a stretch of a calm real standing clip of the same split, turned rigidly about its pelvis from where it
   faced toward the way out (any angle: the walker comes from any direction);
2. a set-off into a short straight stretch of a real forward walk (startups.set_off), that walk slowed to rest
   and cross-faded into another calm standing clip (detours.come_to_rest): about a metre of walking;
3. the walker: a straight stretch of another real walk of the same split, re-timed to 0.8-1.6 m/s and moved so
   that its line passes 0-0.3 m from where the ego stood, reaching that point REACT_S after the ego starts to
   turn (at the walker's pace). The way out is across that line (within ESCAPE_SPREAD of square to it), away from
   it, or to the walker's right where the line passes within KEEP_RIGHT_WITHIN.

Copies that do not keep TARGET_CLEARANCE from the walker are redrawn, then skipped. A copy ends AFTER_PASS frames
after the walker passes. It keeps the standing clip's caption (the module, not the text, makes room), the walk's
licence and the held-out split of both; its walker is stored as a clip (`new_clips.partner_clip_name`) that the
pair builder (pairs.hhi, kind step_aside) checks again on its FK joints. Only the "walkaside" window recipe makes
these copies, in place of the sliding step-aside copies.
"""
from __future__ import annotations

import numpy as np

from .avoidance import KEEP_RIGHT_WITHIN
from .detours import BLEND_FRAMES, STAND_FRAMES
from .geometry import normalized
from .library import ClipLibrary
from .new_clips import NewClip, copy_name, new_clip, partner_clip_name
from .pairs import FPS, ClipCache, pose_joints
from .stretches import Stretch, WalkPool, calm_standing, clearance, moved, partner_walk, rotate_xy, yaw_of
from .turn_arrivals import SETTLE_FRAMES, turn_frames, turn_then_walk

KIND = "walkaside"
COPIES = 2                        # per source walk
WALK_FRAMES = (6, 12)             # frames of real walking before it slows to rest
ONSET_FRAMES = (4, 12)            # standing frames before the turn starts
REACT_S = (2.0, 3.5)              # s from the start of the turn to the walker reaching the ego's spot
LINE_OFFSET = (0.0, 0.3)          # m between the walker's line and the ego's spot
ESCAPE_SPREAD = np.radians(60.0)  # the way out is within this of square to the walker's line
AFTER_PASS = 10                   # frames kept after the walker passes
TARGET_CLEARANCE = (0.3, 0.4)     # m joint to joint a copy keeps from its walker (the pair builder checks 0.3)
ATTEMPTS = 6


def _way_out(rng: np.random.Generator) -> tuple[float, float, float, bool]:
    """(walker heading, way out, each as an angle from the ego's first facing; miss in m; way out on the walker's
    right): the walker from any direction; the way out across its line, away from it, turned toward where the ego
    faces as far as ESCAPE_SPREAD allows (the shortest turn that gets out of the way)."""
    heading = float(rng.uniform(-np.pi, np.pi))
    miss = float(rng.uniform(*LINE_OFFSET))
    on_right = miss < KEEP_RIGHT_WITHIN or rng.random() < 0.5
    square = heading + (-np.pi / 2 if on_right else np.pi / 2)          # square to its line, on that side
    off = float(np.angle(np.exp(-1j * square)))                         # from there to the ego's facing
    return heading, square + float(np.clip(off, -ESCAPE_SPREAD, ESCAPE_SPREAD)), miss, on_right


def _walk_aside_one(lib: ClipLibrary, clips: ClipCache, i: int, stands: list[int], walkers: WalkPool,
                    rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, int, Stretch] | None:
    """(ego rotations, ego pelvis, stance clip, placed walker) for walk i, or None."""
    heading, out, miss, on_right = _way_out(rng)
    angle = float(np.angle(np.exp(1j * out)))                # the turn from the stance's facing to the way out
    got = turn_then_walk(lib, clips, i, angle, int(rng.integers(WALK_FRAMES[0], WALK_FRAMES[1] + 1)), stands, stands,
                         ONSET_FRAMES, rng)
    if got is None:
        return None
    rot, pel, stand, onset = got
    spot = pel[0, :2].astype(np.float64)
    walked = normalized(pel[-1, :2].astype(np.float64) - pel[onset + turn_frames(angle), :2])   # world way out
    face0 = rotate_xy(walked, -angle)
    walk_dir = rotate_xy(face0, heading)
    side = np.array([walk_dir[1], -walk_dir[0]]) * (1.0 if on_right else -1.0)   # toward the way-out side
    tc = onset + int(round(float(rng.uniform(*REACT_S)) * FPS))
    frames = min(len(pel), tc + AFTER_PASS)
    if frames < tc + AFTER_PASS // 2:
        return None
    rot, pel = rot[:frames], pel[:frames]
    walker = partner_walk(lib, clips, walkers, frames, i, rng)
    if walker is None:
        return None
    walker = moved(walker, yaw_of(walk_dir) - yaw_of(walker.heading), tc, spot - miss * side)
    joints = pose_joints(rot, pel).astype(np.float32)
    if clearance(joints, walker.joints) < float(rng.uniform(*TARGET_CLEARANCE)):
        return None
    return rot, pel, stand, walker


def walk_aside_copies(lib: ClipLibrary, clips: ClipCache, egos: WalkPool, walkers: dict[bool, WalkPool],
                      stands: dict[bool, list[int]], seed: int) -> list[NewClip]:
    """COPIES walk-aside copies (and their walker clips) of each walk of `egos`; stances and rests come from
    `stands` (walk_aside_stands) and walkers from `walkers`, each on the walk's side of the split."""
    out: list[NewClip] = []
    for i in egos.ids.tolist():
        side = lib.is_held_out(i)
        if not stands[side]:
            continue
        rng = np.random.default_rng([seed, int(i), 33])
        for k in range(COPIES):
            for _ in range(ATTEMPTS):
                got = _walk_aside_one(lib, clips, i, stands[side], walkers[side], rng)
                if got is not None:
                    rot, pel, stand, walker = got
                    name = copy_name(lib, i, KIND, k)
                    out += [new_clip(lib, i, name, lib.captions[stand], rot, pel),
                            new_clip(lib, walker.source, partner_clip_name(name), lib.captions[walker.source],
                                     walker.rotations, walker.pelvis, ego=False)]
                    break
    return out


def walk_aside_stands(lib: ClipLibrary, clips: ClipCache, ids: list[int]) -> dict[bool, list[int]]:
    """The calm standing clips among `ids` that a copy's stance and rest can come from, by split: long enough for
    the longest stance (turn_then_walk) and for a rest (detours.come_to_rest)."""
    longest_stance = ONSET_FRAMES[1] + turn_frames(np.pi) + SETTLE_FRAMES[1] + BLEND_FRAMES
    calm = calm_standing(lib, clips, ids, max(longest_stance, STAND_FRAMES[1] + BLEND_FRAMES))
    return {side: [s for s in calm if lib.is_held_out(s) == side] for side in (False, True)}
