"""Turn-then-walk arrivals: a person standing turns on the spot toward a goal beside or behind them, walks there
and stops.

Why: the goal family asks for goals 0-180 deg off the ego's facing, and every HSI copy so far
(detours.add_arrivals) starts out walking toward a goal ahead; no clip of the data turns on the spot and then
walks off (their turns happen mid-walk). Measured with the HSI module trained without these (val split, goal
family, test-time control off): of the goals more than 100 deg off facing, 2 of 24 reached; the ego walks on
forward, away from them.

Each copy is

1. a stretch of a calm real standing clip of the same split, turned rigidly about its pelvis from `angle` off
   the walk's heading to the walk's heading (45-180 deg either way, data/turns.py's pivot turn and speed);
2. a set-off into a straight stretch of a real forward walk (startups.set_off: cross-fade, speed-up from rest);
3. that walk slowed to rest and cross-faded into another calm standing clip (detours.arrive).

The feet pivot rather than step during the turn (as in the turned copies of data/turns.py) and slide during the
cross-fades; the walk itself is real. Copies are named `<source walk>#turnarrive<k>`, keep the walk's caption,
licence and held-out split, and feed the HSI stage, whose goal is where the copy stands at its end
(pairs/goals.py).
"""
from __future__ import annotations

import numpy as np

from .detours import BLEND_FRAMES, STAND_FRAMES, WALK_FRAMES, walk_to_rest
from .library import ClipLibrary
from .new_clips import NewClip, copy_name, extend_library, new_clip
from .pairs import ClipCache, is_gesture
from .startups import set_off
from .stretches import by_split, calm_standing, walks
from .turns import pivot_turn, turn_duration, turn_profile

KIND = "turnarrive"
COPIES = 2                        # per source walk
TURN_RANGE = (np.radians(45.0), np.pi)   # |angle| between the standing facing and the walk's heading
ONSET_FRAMES = (2, 4)             # standing frames before the turn starts
SETTLE_FRAMES = (1, 3)            # standing frames between the end of the turn and the set-off's cross-fade


def turn_frames(angle: float) -> int:
    """Whole frames a pivot turn by `angle` takes (turns.turn_profile's duration, rounded up)."""
    return int(np.ceil(turn_duration(angle)))


def turned_stance(rotations: np.ndarray, pelvis: np.ndarray, onset: int, angle: float) -> tuple[np.ndarray, np.ndarray]:
    """A standing stretch that starts `angle` (radians, counter-clockwise seen from above) away from its own last
    facing and turns back to it from frame `onset` on: its frames after the turn are the stretch unchanged."""
    yaw = turn_profile(len(pelvis), onset, angle) - angle
    return pivot_turn(rotations, pelvis, yaw)


def turn_then_walk(lib: ClipLibrary, clips: ClipCache, i: int, angle: float, walk: int, stances: list[int],
                   rests: list[int], onset_frames: tuple[int, int], rng: np.random.Generator
                   ) -> tuple[np.ndarray, np.ndarray, int, int] | None:
    """(rotations, pelvis, stance clip, frame the turn starts) of a standing stretch
    of a clip of `stances`, turned away by `angle` and turning back after `onset_frames` frames, setting off into a
    straight stretch of about `walk` frames of walk i, slowed to rest in a clip of `rests`; None when walk i has no
    such stretch. Clips of `stances` must hold the longest stance (onset, turn, settle and cross-fade)."""
    got = walk_to_rest(lib, clips, i, walk, rests, rng)
    if got is None:
        return None
    m_rot, m_pel, start, _ = got
    s = stances[int(rng.integers(len(stances)))]
    onset = int(rng.integers(onset_frames[0], onset_frames[1] + 1))
    sn = onset + turn_frames(angle) + int(rng.integers(SETTLE_FRAMES[0], SETTLE_FRAMES[1] + 1)) + BLEND_FRAMES
    sa, s0 = int(lib.offsets[s]), int(rng.integers(0, lib.frames(s) - sn + 1))
    s_rot, s_pel = turned_stance(lib.rotations[sa + s0:sa + s0 + sn], lib.pelvis[sa + s0:sa + s0 + sn], onset, angle)
    rot, pel = set_off(s_rot, s_pel, clips.joints(s)[s0 + sn - 1], m_rot, m_pel, clips.joints(i)[start])
    return rot, pel, s, onset


def add_turn_arrivals(lib: ClipLibrary, clip_ids: list[int], seed: int = 0) -> tuple[ClipLibrary, list[int]]:
    """A new library: `lib` plus COPIES turn-then-walk arrivals of every real forward walk of `clip_ids` with a
    long enough straight stretch, their standing parts taken from calm standing clips of the same split.
    Returns (library, indices of the copies). Deterministic for a seed; `lib`'s own clips keep their indices."""
    clips = ClipCache(lib)     # walks and calm_standing take real clips only
    longest_stance = ONSET_FRAMES[1] + turn_frames(TURN_RANGE[1]) + SETTLE_FRAMES[1] + BLEND_FRAMES
    need = max(longest_stance, STAND_FRAMES[1] + BLEND_FRAMES)
    pools = by_split(lib, [i for i in calm_standing(lib, clips, clip_ids, need) if not is_gesture(lib.captions[i])])
    copies: list[NewClip] = []
    for i in walks(lib, clips, clip_ids):
        pool = pools[lib.is_held_out(i)]
        if not pool:
            continue
        rng = np.random.default_rng([seed, int(i), 31])
        for k in range(COPIES):
            angle = float(rng.uniform(*TURN_RANGE)) * (1.0 if rng.random() < 0.5 else -1.0)
            got = turn_then_walk(lib, clips, i, angle, int(rng.integers(WALK_FRAMES[0], WALK_FRAMES[1] + 1)), pool,
                                 pool, ONSET_FRAMES, rng)
            if got is not None:
                copies.append(new_clip(lib, i, copy_name(lib, i, KIND, k), lib.captions[i], got[0], got[1]))
    return extend_library(lib, copies)
