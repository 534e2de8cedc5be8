"""Start-up copies: a person standing still who then sets off into a real clip's motion.

Why: no clip of the data starts from standing. All 353 run, dash and jog clips are already moving in their first
half second (median 2.3 m/s), and in the whole 4 h library no clip goes from under 0.3 m/s to a walk or a run
within 3 s. The runtime starts every ego standing, so the prior had never seen what follows a standing history
when the text says "run" or "walk backwards": measured on the val split, "a person runs" took 3-4 s to reach 2 m/s
and the text family's run prompts averaged 1.05 m/s over 10 s (real runs: 2.6 m/s).

Each copy is

1. a stretch of a calm real standing clip of the same split (no gesture, no crouch: stretches.calm_standing),
   0.8-1.4 s, moved rigidly so that
   its last frame stands where the moving clip starts, facing the way the moving clip's body faces there;
2. a cross-fade over BLEND_FRAMES frames from that stance into the moving clip's first pose;
3. the moving clip's first SPEED_IN steps played over SPEED_OUT frames at a rate easing from 0 to 1 (the
   reverse of detours.slow_to_rest's ease-out), then its next 0.8-1.4 s as captured.

The feet slide during the cross-fade (the stance and the first moving pose differ); everything after it is the
real clip. Copies are named `<source>#startup0` (`#startup1` from the mirrored copy, 2 and 3 from reversed
walks), keep the source's caption (that is the point: the text says
what the person sets off to do), licence and held-out split (`library.source_name`). Sources are real clips and
their mirrored copies (data/mirror.py), so set-offs are as often to the left as to the right, and, where the
windows include them, reversed forward walks (data/reversals.py): setting off backwards.
"""
from __future__ import annotations

import numpy as np

from .detours import BLEND_FRAMES, cross_fade, place_stand, resample
from .library import DERIVED, ClipLibrary, is_derived, source_name
from .new_clips import NewClip, extend_library, new_clip
from .pairs import FPS, ClipCache, facing_xy, is_gesture
from .stretches import calm_standing

START_SPEED = 0.5           # m/s of pelvis travel over a source's first START_FRAMES frames: it starts moving
START_FRAMES = 5
SPEED_IN, SPEED_OUT = 4, 8  # the first SPEED_IN steps are played over SPEED_OUT frames (rate 0 -> 1)
# Short copies: what they teach is the set-off; longer ones made a third of the prior's frames (measured on the 4 h
# library with (10, 20) / (20, 30)) and would tilt the prior toward setting off.
STAND_FRAMES = (8, 14)      # frames of standing before the cross-fade
MOVE_FRAMES = (8, 14)       # frames of the moving clip kept after the speed-up
STAND_HEIGHT = 0.8          # m: the standing clip's pelvis stays above this (no crouching or sitting)
# The copies a start-up is made from, and the number that names it: real clips, their mirrored copies
# (data/mirror.py) and reversed forward walks (data/reversals.py; standing, then setting off backwards).
STARTUP_NUMBER = {"": 0, "mirror0": 1, "reversed0": 2, "reversed1": 3}


def variant(name: str) -> str:
    """"" for a real clip, "mirror0", "reversed1", ... for a derived one (`<source>#<variant>`)."""
    return name.split(DERIVED, 1)[1] if is_derived(name) else ""


def speed_up_from_rest(rotations: np.ndarray, pelvis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The clip with its first SPEED_IN steps played over SPEED_OUT frames at a rate easing from 0 to 1
    (quadratic ease-in; the rate reaches exactly 1 because SPEED_OUT = 2 SPEED_IN), then the rest as captured."""
    x = np.arange(SPEED_OUT) / SPEED_OUT
    q, p = resample(rotations, pelvis, SPEED_IN * x ** 2)
    return np.concatenate((q, rotations[SPEED_IN:])), np.concatenate((p, pelvis[SPEED_IN:]))


def set_off(stand_rot: np.ndarray, stand_pel: np.ndarray, stand_joints_last: np.ndarray, move_rot: np.ndarray,
            move_pel: np.ndarray, move_joints0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A standing stretch, moved to end where and as the moving clip starts, cross-faded into the moving clip
    sped up from rest. rotations (T, 22, 4) w-first, pelvis (T, 3); *_joints: (22, 3) FK joints of the standing
    stretch's last frame and the moving clip's first."""
    # place_stand places a clip by its first frame: place the reversed stretch, then turn it back
    s_rot, s_pel = place_stand(stand_rot[::-1].copy(), stand_pel[::-1].copy(), stand_joints_last,
                               move_pel[0, :2].astype(np.float64), facing_xy(move_joints0[None].astype(np.float64))[0])
    s_rot, s_pel = s_rot[::-1], s_pel[::-1]
    m_rot, m_pel = speed_up_from_rest(move_rot, move_pel)
    b_rot, b_pel = cross_fade(s_rot[-BLEND_FRAMES:], s_pel[-BLEND_FRAMES:],
                              np.repeat(m_rot[:1], BLEND_FRAMES, 0), np.repeat(m_pel[:1], BLEND_FRAMES, 0))
    return (np.concatenate((s_rot[:-BLEND_FRAMES], b_rot, m_rot)).astype(move_rot.dtype),
            np.concatenate((s_pel[:-BLEND_FRAMES], b_pel, m_pel)).astype(move_pel.dtype))


def starts_moving(pelvis: np.ndarray) -> bool:
    """Whether a clip's pelvis travels at START_SPEED or faster over its first START_FRAMES frames."""
    if len(pelvis) <= START_FRAMES + SPEED_IN + MOVE_FRAMES[0]:
        return False
    d = np.linalg.norm(pelvis[START_FRAMES, :2].astype(np.float64) - pelvis[0, :2])
    return d * FPS / START_FRAMES >= START_SPEED


def add_startups(lib: ClipLibrary, clip_ids: list[int], seed: int = 0) -> tuple[ClipLibrary, list[int]]:
    """A new library: `lib` plus one start-up copy of every clip of `clip_ids` (real or mirrored) that starts
    moving, each set off from a standing clip of the same split. Returns (library, indices of the copies).

    Deterministic for a seed; `lib`'s own clips keep their indices."""
    ids = [i for i in clip_ids if variant(lib.names[i]) in STARTUP_NUMBER]
    movers = [i for i in ids if starts_moving(lib.pelvis[lib.offsets[i]:lib.offsets[i + 1]])]
    clips = ClipCache(lib, movers + [i for i in ids if not is_derived(lib.names[i])])
    stands = [i for i in calm_standing(lib, clips, ids, STAND_FRAMES[1] + BLEND_FRAMES)
              if not is_gesture(lib.captions[i]) and lib.pelvis[lib.offsets[i]:lib.offsets[i + 1], 2].min() > STAND_HEIGHT]
    pools = {side: [i for i in stands if lib.is_held_out(i) == side] for side in (False, True)}
    copies: list[NewClip] = []
    for i in movers:
        pool = pools[lib.is_held_out(i)]
        if not pool:
            continue
        rng = np.random.default_rng([seed, int(i), 23])
        s = pool[int(rng.integers(len(pool)))]
        sn = int(rng.integers(STAND_FRAMES[0], STAND_FRAMES[1] + 1)) + BLEND_FRAMES
        s0 = int(rng.integers(0, lib.frames(s) - sn + 1))
        sa, a = int(lib.offsets[s]), int(lib.offsets[i])
        mn = min(lib.frames(i), SPEED_IN + int(rng.integers(MOVE_FRAMES[0], MOVE_FRAMES[1] + 1)))
        rot, pel = set_off(lib.rotations[sa + s0:sa + s0 + sn], lib.pelvis[sa + s0:sa + s0 + sn],
                           clips.joints(s)[s0 + sn - 1], lib.rotations[a:a + mn], lib.pelvis[a:a + mn],
                           clips.joints(i)[0])
        # `<source>#startup0` from the real clip, `<source>#startup1` from its mirrored copy, 2 and 3 from the
        # reversed copies of the two
        name = f"{source_name(lib.names[i])}{DERIVED}startup{STARTUP_NUMBER[variant(lib.names[i])]}"
        copies.append(new_clip(lib, i, name, lib.captions[i], rot, pel))
    return extend_library(lib, copies)
