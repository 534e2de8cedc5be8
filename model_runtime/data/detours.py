"""Synthetic arrivals and detours: the scene reaction the open data does not hold.

The box scenario (evaluation) asks the ego to walk around a box on the straight line to a goal and stop there. No clip
in CMU or Bandai Namco does either: a scan of the 4 h library found no walk that ends standing (all 645
Bandai dataset-2 walks start and end mid-stride) and no walk around an obstacle. Measured without this: the HSI
module left the ego 20 % of frames inside the box and 3.0 m from the goal (it walked on past it). So the HSI
stage also trains on copies of real straight walks, each

1. optionally bent into a detour (`bend_path`): the heading swings away by 25-45 degrees, holds, swings back
   across the line by twice that, holds as long, and straightens, so the path leaves its straight line and
   rejoins it. Each frame's body turns with the heading about its own pelvis and the pelvis path is
   re-integrated from the turned velocities; the feet slide a little while the heading changes.
2. brought to a stop (`arrive`): slowed to rest by a time warp over its last 0.4 s of walking (played over
   0.8 s, ease-out) at a frame where the ankles pass each other, then cross-faded over 0.5 s into a real
   standing clip (no gesture) placed at that pelvis position and facing, which plays for 1.5-3 s.

Copies are named `<source>#detour<k>` / `<source>#arrive<k>` and keep the source's caption (the goal, not the
text, tells the module where to stop), licence and held-out split (`library.source_name`). The HSI scenes
(`pairs.build_hsi_scenes`) put a box on the straight line beside a detour's widest point and the goal where the
copy stands. The copies only feed the HSI stage; the VAE and the prior never see them.
"""
from __future__ import annotations

import numpy as np
import torch

from ..skeleton import JOINT_INDEX, quat_slerp
from .library import DERIVED, ClipLibrary, is_derived
from .pairs import FPS, STANDING_RANGE, ClipCache, facing_xy, is_gesture, pose_joints
from .turns import pivot_turn, smoothstep, turn_roots

WALK_SPEED = (0.7, 2.0)              # m/s mean pelvis speed of a source walk
STRAIGHTNESS = 0.3                   # m: a source walk's pelvis stays this close to its start-end line
# Steep and short: 0.5-1.3 m out, the widest point 0.8-1.6 m of walking after the swing starts, so the box beside
# it is already inside the ego-local occupancy window (1.8 m ahead) when the swing begins (with 30-55 degrees
# and 6-14 held frames it was often beyond it, and the module learned to head for the goal but not around boxes)
DETOUR_ANGLE = (np.radians(35.0), np.radians(60.0))
HEADING_RATE = np.radians(120.0)     # rad/s while the detour's heading changes
DETOUR_HOLD = (3, 9)                 # frames held at each side of the line
WALK_FRAMES = (15, 45)              # frames of walking before the stop (a detour needs its own length on top)
SLOW_IN, SLOW_OUT = 4, 8             # the last SLOW_IN walking frames are played over SLOW_OUT frames
BLEND_FRAMES = 5
COPIES = ("detour", "detour", "arrive")   # per source walk
STAND_FRAMES = (15, 30)
ANKLES = (JOINT_INDEX["left_ankle"], JOINT_INDEX["right_ankle"])


def detour_profile(frames: int, onset: int, angle: float, hold: int) -> np.ndarray:
    """(frames,) heading added per frame: 0 -> angle -> -angle -> 0, antisymmetric about its middle, so a walk
    at a steady speed ends back on its original line."""
    d = max(2.0, abs(angle) / HEADING_RATE * FPS)
    t = np.arange(frames, dtype=np.float64)
    t2 = onset + d + hold
    t3 = t2 + 2 * d + hold
    return angle * (smoothstep((t - onset) / d) - 2 * smoothstep((t - t2) / (2 * d)) + smoothstep((t - t3) / d))


def detour_frames(angle: float, hold: int) -> int:
    """Frames from a detour's onset until its heading is straight again."""
    d = max(2.0, abs(angle) / HEADING_RATE * FPS)
    return int(np.ceil(4 * d + 2 * hold))


def bend_path(rotations: np.ndarray, pelvis: np.ndarray, yaw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Turn each frame's body by yaw[t] about its own pelvis and re-integrate the pelvis path from the turned
    per-frame steps (starting where the clip starts). rotations (T, 22, 4) w-first, pelvis (T, 3)."""
    rot, _ = turn_roots(rotations, yaw)
    return rot, bend_pelvis(pelvis, yaw)


def bend_pelvis(pelvis: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """The pelvis path of `bend_path` alone: each per-frame step turned by the mean yaw of its two frames and
    re-integrated from the first frame (height unchanged)."""
    step = np.diff(pelvis[:, :2].astype(np.float64), axis=0)
    mid = 0.5 * (yaw[1:] + yaw[:-1])
    c, s = np.cos(mid), np.sin(mid)
    turned = np.stack((c * step[:, 0] - s * step[:, 1], s * step[:, 0] + c * step[:, 1]), -1)
    pel = pelvis.copy()
    pel[1:, :2] = (pelvis[0, :2].astype(np.float64) + np.cumsum(turned, 0)).astype(pel.dtype)
    return pel


def resample(rotations: np.ndarray, pelvis: np.ndarray, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pose at fractional frame times (slerp / lerp between neighbouring frames)."""
    lo = np.clip(np.floor(times).astype(np.int64), 0, len(pelvis) - 1)
    hi = np.minimum(lo + 1, len(pelvis) - 1)
    w = (times - lo)[:, None]
    q = quat_slerp(torch.from_numpy(rotations[lo].astype(np.float64)), torch.from_numpy(rotations[hi].astype(np.float64)),
                   torch.from_numpy(w[:, :, None])).numpy()
    return q.astype(rotations.dtype), ((1 - w) * pelvis[lo] + w * pelvis[hi]).astype(pelvis.dtype)


def slow_to_rest(rotations: np.ndarray, pelvis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The clip with its last SLOW_IN steps played over SLOW_OUT frames at a rate easing from 1 to 0
    (quadratic ease-out: the rate starts at exactly 1 because SLOW_OUT = 2 SLOW_IN)."""
    t = len(pelvis)
    x = np.arange(1, SLOW_OUT + 1) / SLOW_OUT
    times = (t - 1 - SLOW_IN) + SLOW_IN * (1 - (1 - x) ** 2)
    q, p = resample(rotations, pelvis, times)
    keep = t - SLOW_IN
    return np.concatenate((rotations[:keep], q)), np.concatenate((pelvis[:keep], p))


def place_stand(rotations: np.ndarray, pelvis: np.ndarray, joints0: np.ndarray, at_xy: np.ndarray,
                facing: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Move a standing clip rigidly (yaw + floor translation) so its first frame's pelvis is at at_xy, facing
    `facing` (2,). joints0: (22, 3) joints of its first frame."""
    f0 = facing_xy(joints0[None].astype(np.float64))[0]
    a = np.arctan2(facing[1], facing[0]) - np.arctan2(f0[1], f0[0])
    rot, pel = pivot_turn(rotations, pelvis, np.full(len(pelvis), a))
    pel[:, :2] = (pel[:, :2].astype(np.float64) + (at_xy - pelvis[0, :2])).astype(pel.dtype)
    return rot, pel


def cross_fade(a_rot: np.ndarray, a_pel: np.ndarray, b_rot: np.ndarray, b_pel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Frames going from poses a to poses b (both (n, 22, 4) w-first and (n, 3)): slerp / lerp with smoothstep
    weights rising over the n frames, never exactly 0 or 1. Returned in a's dtypes."""
    n = len(a_pel)
    w = smoothstep(np.arange(1, n + 1) / (n + 1))
    rot = quat_slerp(torch.from_numpy(a_rot.astype(np.float64)), torch.from_numpy(b_rot.astype(np.float64)),
                     torch.from_numpy(w[:, None, None])).numpy().astype(a_rot.dtype)
    return rot, ((1 - w[:, None]) * a_pel + w[:, None] * b_pel).astype(a_pel.dtype)


def arrive(walk_rot: np.ndarray, walk_pel: np.ndarray, stand_rot: np.ndarray, stand_pel: np.ndarray,
           stand_joints0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A walk slowed to rest, then cross-faded into a standing clip placed where and as the walk stopped."""
    rot, pel = slow_to_rest(walk_rot, walk_pel)
    j_end = pose_joints(rot[-1:], pel[-1:])[0]
    s_rot, s_pel = place_stand(stand_rot, stand_pel, stand_joints0, pel[-1, :2].astype(np.float64),
                               facing_xy(j_end[None])[0])
    b_rot, b_pel = cross_fade(np.repeat(rot[-1:], BLEND_FRAMES, 0), np.repeat(pel[-1:], BLEND_FRAMES, 0),
                              s_rot[:BLEND_FRAMES], s_pel[:BLEND_FRAMES])
    return (np.concatenate((rot, b_rot, s_rot[BLEND_FRAMES:])),
            np.concatenate((pel, b_pel, s_pel[BLEND_FRAMES:])))


def straight_starts(xy: np.ndarray, length: int) -> np.ndarray:
    """Starts of the `length`-frame stretches of a smoothed pelvis path that walk straight at a walking pace:
    every point within STRAIGHTNESS of the stretch's chord, chord speed within WALK_SPEED."""
    if length < 2 or len(xy) < length:
        return np.zeros(0, np.int64)
    seg = np.moveaxis(np.lib.stride_tricks.sliding_window_view(np.asarray(xy, np.float64), length, axis=0), -1, 1)
    line = seg[:, -1] - seg[:, 0]                                   # (starts, 2) chords
    dist = np.linalg.norm(line, axis=1)
    speed = dist / ((length - 1) / FPS)
    n = np.stack((-line[:, 1], line[:, 0]), -1) / np.maximum(dist, 1e-12)[:, None]
    off = np.abs(((seg - seg[:, :1]) * n[:, None, :]).sum(-1)).max(1)
    return np.flatnonzero((WALK_SPEED[0] <= speed) & (speed <= WALK_SPEED[1]) & (off < STRAIGHTNESS)).astype(np.int64)


def stop_frame(joints: np.ndarray, lo: int, hi: int) -> int:
    """Frame in [lo, hi) where the ankles are closest in the floor plane (the swing foot passes the other)."""
    gap = np.linalg.norm(joints[lo:hi, ANKLES[0], :2] - joints[lo:hi, ANKLES[1], :2], axis=-1)
    return lo + int(np.argmin(gap))


def straight_walk(clips: ClipCache, i: int, walk: int, rng: np.random.Generator) -> tuple[int, int] | None:
    """(start, exclusive end) of a random straight stretch of clip i about `walk` frames long, ending where the
    ankles pass each other (stop_frame); None when the clip has no such stretch."""
    starts = straight_starts(clips.path(i).xy[:-1], walk + 1)   # the stop may fall up to one frame late
    if not len(starts):
        return None
    start = int(starts[int(rng.integers(len(starts)))])
    return start, stop_frame(clips.joints(i), start + walk - 6, start + walk + 1) + 1


def come_to_rest(lib: ClipLibrary, clips: ClipCache, rotations: np.ndarray, pelvis: np.ndarray, stands: list[int],
                 rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A walk slowed to rest in a random stretch (STAND_FRAMES, plus the cross-fade) of a random clip of `stands`
    (`arrive`)."""
    s = stands[int(rng.integers(len(stands)))]
    sa, sn = int(lib.offsets[s]), int(rng.integers(STAND_FRAMES[0], STAND_FRAMES[1] + 1)) + BLEND_FRAMES
    s0 = int(rng.integers(0, lib.frames(s) - sn + 1))
    return arrive(rotations, pelvis, lib.rotations[sa + s0:sa + s0 + sn], lib.pelvis[sa + s0:sa + s0 + sn],
                  clips.joints(s)[s0])


def walk_to_rest(lib: ClipLibrary, clips: ClipCache, i: int, walk: int, stands: list[int], rng: np.random.Generator
                 ) -> tuple[np.ndarray, np.ndarray, int, int] | None:
    """(rotations, pelvis, start, exclusive end) of a random straight stretch of clip i about `walk` frames long
    (straight_walk) slowed to rest in a clip of `stands` (come_to_rest); None when the clip has no such stretch.
    The walk's own frames are start..end of the clip; it comes to rest SLOW_IN - 1 frames after their last one."""
    span = straight_walk(clips, i, walk, rng)
    if span is None:
        return None
    a, (start, stop) = int(lib.offsets[i]), span
    rot, pel = come_to_rest(lib, clips, lib.rotations[a + start:a + stop], lib.pelvis[a + start:a + stop], stands, rng)
    return rot, pel, start, stop


def add_arrivals(lib: ClipLibrary, clip_ids: list[int], seed: int = 0) -> tuple[ClipLibrary, list[int]]:
    """A new library: `lib` plus, for every forward walk of `clip_ids` with a long enough straight stretch,
    one copy per entry of COPIES (two detour-and-stop copies and one plain stop, each of a random straight
    stretch; each ends in a standing clip of the same split). Returns (library, indices of the copies).

    Deterministic for a seed; `lib`'s own clips keep their indices."""
    ids = [i for i in clip_ids if not is_derived(lib.names[i])]
    clips = ClipCache(lib)     # batched FK and path analysis, cached
    walks = [i for i in ids if clips.path(i).moving and clips.path(i).forwardness >= 0.8]
    stands = [i for i in ids if lib.frames(i) >= STAND_FRAMES[1] + BLEND_FRAMES
              and np.ptp(lib.pelvis[lib.offsets[i]:lib.offsets[i + 1], :2], axis=0).max() <= STANDING_RANGE
              and not is_gesture(lib.captions[i])]
    pools = {side: [i for i in stands if lib.is_held_out(i) == side] for side in (False, True)}
    names, caps, srcs = list(lib.names), list(lib.captions), list(lib.sources)
    rots, pels, off = [lib.rotations], [lib.pelvis], list(lib.offsets)
    errors = list(lib.fit_error_mm) if lib.fit_error_mm else []
    new: list[int] = []
    for i in walks:
        pool = pools[lib.is_held_out(i)] or stands
        if not pool:
            break
        a = int(lib.offsets[i])
        rng = np.random.default_rng([seed, int(i), 11])
        for k, kind in enumerate(COPIES):
            walk = int(rng.integers(WALK_FRAMES[0], WALK_FRAMES[1] + 1))
            if kind == "detour":
                angle = float(rng.uniform(*DETOUR_ANGLE)) * (1.0 if rng.random() < 0.5 else -1.0)
                hold = int(rng.integers(DETOUR_HOLD[0], DETOUR_HOLD[1] + 1))
                onset = int(rng.integers(3, 9))
                walk = max(walk, onset + detour_frames(angle, hold) + 6)
            span = straight_walk(clips, i, walk, rng)
            if span is None:
                continue
            w_rot, w_pel = lib.rotations[a + span[0]:a + span[1]], lib.pelvis[a + span[0]:a + span[1]]
            if kind == "detour":
                w_rot, w_pel = bend_path(w_rot, w_pel, detour_profile(len(w_pel), onset, angle, hold))
            rot, pel = come_to_rest(lib, clips, w_rot, w_pel, pool, rng)
            names.append(f"{lib.names[i]}{DERIVED}{kind}{k}")
            caps.append(lib.captions[i])
            srcs.append(lib.sources[i])
            if errors:
                errors.append(lib.fit_error_mm[i])
            rots.append(rot)
            pels.append(pel)
            off.append(off[-1] + len(pel))
            new.append(len(names) - 1)
    out = ClipLibrary(names, caps, srcs, np.concatenate(rots), np.concatenate(pels), np.asarray(off, np.int64), errors)
    return out, new
