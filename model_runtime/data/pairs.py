"""Interaction training data built from single-person clips: stand-ins for Inter-X (HHI) and LINGO (HSI).

There is no open two-person or scene-paired capture in the project's data (see shared/data/README.md),
so the interaction stages train on pairs generated here. The rule everywhere: the ego's motion is the
*real*, unmodified clip; only the partner or the scene is invented, and it is placed so that the real
motion reads as a plausible reaction to it. Every generator checks what it guarantees (a partner never
closer than MIN_CLEARANCE to the ego; no ego joint below 1.5 m inside an obstacle, checked on the
voxel grid the model will read) and resamples or skips a placement that breaks it.

HHI (stand-in for Inter-X), `build_hhi_pairs`, one of five rules per pair:
    approach_face  a walking ego: a standing partner waits ~1 m beyond the point where the walk ends
                   (0.9-1.2 m, plus 0.3 s of the final speed: captured walks end mid-stride), facing
                   back along the walk, so the approach ends in front of and facing the partner.
    follow         a walking ego: a walking partner ~1.5 m ahead on the ego's own path (time-shifted),
                   so the ego follows it, turns included.
    greet          a bow / wave / call / bye / raise-hand clip: a standing partner ~1.5 m in front of
                   the ego, facing it, so the gesture is addressed to it.
    avoid_blocker  a walk-turn clip: a standing partner on the straight-ahead line of the pre-turn walk,
                   0.6-1.1 m past the farthest point the ego's body reaches on that line, facing the
                   ego, so the turn reads as turning away from someone blocking the way.
    turn_to_face   a turned copy of a standing clip (`<name>#turn<k>`, data/turns.py: the one exception to
                   the rule below, since no clip turns on the spot): a standing partner 1.0-2.4 m ahead of
                   where the turn ends, facing the ego, so the turn reads as turning to face someone.
Partners are bodies from *other* real clips (standing clips for the waiting partners, straight walks
for the leader), moved rigidly (standing) or re-rooted along the path (leader), with a random body
scale in [0.9, 1.1] and a random timing offset in [-0.5, 0.5] s.

HSI (stand-in for LINGO), `build_hsi_scenes`, procedural obstacles (boxes, walls, tables, low steps)
and a goal taken from the ego's own path (`hsi_goal`): where the clip stops, or, for a clip still walking at
its end (captured walks end mid-stride), 1.5 s further along its final heading, so that a goal under the ego
always means "stop here" and one ahead "keep going":
    block_turn     a turning clip: an obstacle on the straight-ahead continuation of the pre-turn path,
                   just beyond the turn, so the captured turn avoids it (plus maybe one beside the path).
    beside_path    a moving clip: 1-3 obstacles beside the swept volume of a stretch of the path.
    corridor       a moving clip: two walls along a stretch of the path, one on each side.
    static         an in-place clip (gestures, dance): 1-2 obstacles around the swept volume.
    detour         a detour-and-stop copy of a straight walk (`<name>#detour<k>`, data/detours.py: like the
                   turned copies, an exception to the rule below, since no clip walks around anything or
                   stops at a target): a box or table on the walk's original straight line beside the
                   detour's widest point, as wide as the detour leaves room for; the goal is where it stops.
Every obstacle is pushed out of the ego's swept volume (all joints, plus a body margin) along one axis,
so the real path stays free; the voxelised scene is then checked joint by joint.

The loaders for the real datasets' published layouts live beside this module; these builders only
exist because those datasets are not available here.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import torch

from ..quat import unit_vectors as _unit
from ..skeleton import LEFT_HIP, RIGHT_HIP, forward_kinematics, quat_to_matrix
from .library import ClipLibrary, derived_kind, is_derived

if TYPE_CHECKING:  # voxel.py is NumPy-only and imported lazily (see HSIScene.grid)
    from ..voxel import OccupancyGrid

FPS = 10
MIN_CLEARANCE = 0.45      # m between any ego joint and any partner joint; accepted pairs keep at least this
SCALE_RANGE = (0.9, 1.1)  # partner body scale
MAX_SHIFT = 5             # partner timing offset, frames (0.5 s at 10 fps)
MOVING_DISTANCE = 1.0     # m of pelvis travel for a clip to count as locomotion
STANDING_RANGE = 0.5      # m: a clip whose pelvis stays within this (horizontal extent) is "standing"
TURN_ANGLE = np.radians(45.0)   # heading change that makes a walk a "walk-turn"
ONSET_ANGLE = np.radians(20.0)  # deviation from the initial heading that marks where the turn starts
GESTURE_WORDS = ("bow", "wave", "waving", "bye", "call", "guide", "respond", "raise", "greet", "salute",
                 "hello", "beckon")
SCENE_CHECK_HEIGHT = 1.5  # m: ego joints below this must never be inside an obstacle
BODY_MARGIN = 0.15        # m kept between obstacle faces and any ego joint (flesh, hands and feet)
VOXEL_SIZE = 0.05


# ----------------------------------------------------------------------------- clip analysis
def clip_joints(lib: ClipLibrary, i: int) -> np.ndarray:
    """(T, 22, 3) float32 world joints of clip i (FK of its pose)."""
    rot, pel = lib.pose(i)
    return forward_kinematics(rot, pel)[0].numpy().astype(np.float32)


def facing_xy(joints: np.ndarray) -> np.ndarray:
    """(..., 22, 3) -> (..., 2) unit horizontal facing from the hips (+Z x (right hip - left hip))."""
    across = joints[..., RIGHT_HIP, :2] - joints[..., LEFT_HIP, :2]
    f = np.stack((-across[..., 1], across[..., 0]), -1)
    return f / np.maximum(np.linalg.norm(f, axis=-1, keepdims=True), 1e-9)


def _angle_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Unsigned angle (radians) between 2-D vectors, broadcast over leading axes."""
    cross = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return np.abs(np.arctan2(cross, (a * b).sum(-1)))


def _smooth(x: np.ndarray, k: int = 9) -> np.ndarray:
    """Moving average over frames with edge padding (removes the pelvis' gait sway)."""
    if len(x) < 3:
        return x.copy()
    k = min(k, len(x) - (1 - len(x) % 2))
    pad = k // 2
    xp = np.concatenate((np.repeat(x[:1], pad, 0), x, np.repeat(x[-1:], pad, 0)), 0)
    c = np.cumsum(np.concatenate((np.zeros_like(x[:1]), xp), 0), 0)
    return (c[k:] - c[:-k]) / k


@dataclass
class PathInfo:
    """What the generators need to know about a clip's pelvis path (world xy, metres)."""
    xy: np.ndarray          # (T, 2) smoothed pelvis path
    travel: float           # path length, m
    extent: float           # largest horizontal extent of the raw pelvis path, m
    forwardness: float      # mean cos(facing, travel direction) over moving frames (1 = walks forward)
    h_start: np.ndarray     # (2,) initial travel heading
    h_end: np.ndarray       # (2,) final travel heading
    turn: float             # angle between h_start and h_end, radians
    onset: int              # frame where the heading first leaves h_start by ONSET_ANGLE (-1: never)
    end_speed: float        # m/s over the last half second
    facing: np.ndarray      # (T, 2) hip facing

    @property
    def moving(self) -> bool:
        return self.travel >= MOVING_DISTANCE and self.forwardness >= 0.5

    @property
    def turning(self) -> bool:
        return self.moving and self.turn >= TURN_ANGLE and self.onset > 0

    @property
    def standing(self) -> bool:
        return self.extent <= STANDING_RANGE


def analyse_path(joints: np.ndarray) -> PathInfo:
    """Travel, headings and the turn of a clip, from its pelvis path (smoothed over ~1 gait cycle)."""
    raw = joints[:, 0, :2].astype(np.float64)
    xy = _smooth(raw)
    step = np.diff(xy, axis=0)
    seg = np.linalg.norm(step, axis=1)
    travel = float(seg.sum())
    extent = float(np.ptp(raw, axis=0).max()) if len(raw) > 1 else 0.0
    facing = facing_xy(joints.astype(np.float64))
    moving = np.flatnonzero(seg * FPS > 0.3)
    t = len(xy)
    if len(moving) < 2 or travel < 0.3:
        return PathInfo(xy, travel, extent, 0.0, facing[0], facing[-1], 0.0, -1, 0.0, facing)
    a, b = int(moving[0]), int(moving[-1]) + 1
    span = max(3, min(10, (b - a) // 3))
    h_start = _unit(xy[min(a + span, b)] - xy[a])
    h_end = _unit(xy[b] - xy[max(b - span, a)])
    dirs = step[moving] / seg[moving, None]
    forwardness = float(np.mean((dirs * facing[moving]).sum(-1)))
    # the heading over a +-3 frame window, against the initial heading
    w = 3
    idx = np.arange(t)
    hd = xy[np.minimum(idx + w, t - 1)] - xy[np.maximum(idx - w, 0)]
    ok = np.linalg.norm(hd, axis=1) > 1e-6
    dev = np.where(ok, _angle_between(hd, h_start[None]), 0.0)
    late = np.flatnonzero((dev > ONSET_ANGLE) & (idx >= a + span))
    onset = int(late[0]) if len(late) else -1
    k = min(5, t - 1)
    end_speed = float(np.linalg.norm(raw[-1] - raw[-1 - k]) * FPS / k) if k > 0 else 0.0
    return PathInfo(xy, travel, extent, forwardness, h_start, h_end, float(_angle_between(h_start, h_end)),
                    onset, end_speed, facing)


def is_gesture(caption: str) -> bool:
    """Bow / wave / call / bye / guide / respond / raise-hand captions: things done *to* someone."""
    c = caption.lower()
    return any(w in c for w in GESTURE_WORDS)


# ----------------------------------------------------------------------------- placing partner bodies
def _rot2(c: float, s: float) -> np.ndarray:
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _yaw_between(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """3x3 rotation about +Z taking 2-D direction src to dst."""
    a = np.arctan2(dst[1], dst[0]) - np.arctan2(src[1], src[0])
    return _rot2(np.cos(a), np.sin(a))


def _scale_body(j: np.ndarray, scale: float) -> np.ndarray:
    """Scale each frame's body about the floor point under its pelvis (shape changes, path does not)."""
    anchor = j[:, :1, :].copy()
    anchor[..., 2] = 0.0
    return anchor + scale * (j - anchor)


def place_standing(src: np.ndarray, frames: np.ndarray, ref: int, target_xy: np.ndarray,
                   target_facing: np.ndarray, scale: float) -> np.ndarray:
    """Move a source clip rigidly so that at its frame `ref` the pelvis is at target_xy facing target_facing.

    src (Ts, 22, 3) world joints; frames (T,) source frame per ego frame. Returns (T, 22, 3).
    """
    r = _yaw_between(facing_xy(src[ref]), target_facing)
    pel = np.array([src[ref, 0, 0], src[ref, 0, 1], 0.0])
    t = np.array([target_xy[0], target_xy[1], 0.0]) - r @ pel
    out = src[frames].astype(np.float64) @ r.T + t
    return _scale_body(out, scale)


def _loop_frames(n: int, ts: int, start: int, body: np.ndarray) -> np.ndarray:
    """n source frame indices from `start`, jumping back to the most similar earlier pose at the end."""
    start = int(np.clip(start, 0, ts - 1))
    if ts - start >= n:
        return np.arange(start, start + n)
    last = body[-1]
    cand = np.arange(0, max(1, ts - 10))
    back = int(cand[np.argmin(((body[cand] - last) ** 2).sum((1, 2)))]) if ts > 11 else 0
    out, f = [], start
    for _ in range(n):
        out.append(f)
        f = f + 1 if f + 1 < ts else back + 1 if back + 1 < ts else 0
    return np.asarray(out)


def place_on_path(src: np.ndarray, src_path: PathInfo, frames: np.ndarray, path_xy: np.ndarray,
                  path_heading: np.ndarray, scale: float) -> np.ndarray:
    """Re-root a walking source clip onto a path: each frame's body, taken relative to the source's own
    pelvis and travel heading, is put at path_xy[t] heading path_heading[t]. Keeps the gait and the
    pelvis sway; the route is the ego's. Returns (T, 22, 3)."""
    xy = src_path.xy
    ts = len(xy)
    idx = np.arange(ts)
    hd = xy[np.minimum(idx + 5, ts - 1)] - xy[np.maximum(idx - 5, 0)]
    bad = np.linalg.norm(hd, axis=1) < 1e-6
    hd[bad] = src_path.facing[bad]
    th_src = np.arctan2(hd[:, 1], hd[:, 0])[frames]
    th_dst = np.arctan2(path_heading[:, 1], path_heading[:, 0])
    body = src[frames].astype(np.float64)
    body[..., :2] -= src[frames, :1, :2]
    a = th_dst - th_src
    c, s = np.cos(a)[:, None], np.sin(a)[:, None]
    x, y = body[..., 0].copy(), body[..., 1].copy()
    body[..., 0], body[..., 1] = c * x - s * y, s * x + c * y
    body[..., :2] += path_xy[:, None, :]
    return _scale_body(body, scale)


def min_clearance(a: np.ndarray, b: np.ndarray) -> float:
    """Smallest distance between any joint of a and any joint of b over all frames: (T, J, 3) each."""
    d = np.linalg.norm(a[:, :, None, :] - b[:, None, :, :], axis=-1)
    return float(d.min())


def _extended_path(path: PathInfo, extra: float) -> tuple[np.ndarray, np.ndarray]:
    """The smoothed path as (points (N, 2), cumulative arclength (N,)), continued `extra` m past the end
    along the final heading."""
    n_ext = max(2, int(np.ceil(extra / 0.05)))
    ext = path.xy[-1] + np.outer(np.arange(1, n_ext + 1) * 0.05, path.h_end)
    pts = np.concatenate((path.xy, ext), 0)
    s = np.concatenate(([0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))))
    return pts, s


def _point_at(pts: np.ndarray, s: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points and unit tangents at arclengths q on a polyline (pts, s)."""
    q = np.clip(q, 0.0, s[-1])
    i = np.clip(np.searchsorted(s, q, side="right") - 1, 0, len(s) - 2)
    seg = pts[i + 1] - pts[i]
    ln = np.maximum(s[i + 1] - s[i], 1e-9)
    p = pts[i] + seg * ((q - s[i]) / ln)[:, None]
    # tangent over a 0.3 m chord: steadier than one polyline segment
    lo = np.clip(np.searchsorted(s, q - 0.15) - 1, 0, len(s) - 1)
    hi = np.clip(np.searchsorted(s, q + 0.15), 0, len(s) - 1)
    tan = pts[hi] - pts[lo]
    nrm = np.linalg.norm(tan, axis=1, keepdims=True)
    tan = np.where(nrm > 1e-9, tan / np.maximum(nrm, 1e-9), seg / np.maximum(np.linalg.norm(seg, axis=1,
                                                                                         keepdims=True), 1e-9))
    return p, tan


# ----------------------------------------------------------------------------- HHI
HHI_KINDS = ("approach_face", "follow", "greet", "avoid_blocker", "turn_to_face")


@dataclass(eq=False)
class HHIPair:
    """An ego clip and an invented partner, frame-aligned with the ego clip's T frames."""
    ego: int                    # clip index in the library
    partner: np.ndarray         # (T, 22, 3) float32 world joints
    kind: str                   # one of HHI_KINDS


class ClipCache:
    """Per-build cache of FK joints and path analysis (each clip is needed many times)."""

    def __init__(self, lib: ClipLibrary) -> None:
        self.lib = lib
        self._j: dict[int, np.ndarray] = {}
        self._p: dict[int, PathInfo] = {}

    def joints(self, i: int) -> np.ndarray:
        if not self._j:
            self._all_joints()
        return self._j[i]

    def _all_joints(self, chunk: int = 16384) -> None:
        """FK of every clip in a few large batches (per-clip calls are ~50x slower on small clips)."""
        lib = self.lib
        q = torch.from_numpy(np.ascontiguousarray(lib.rotations))
        p = torch.from_numpy(np.ascontiguousarray(lib.pelvis))
        parts = []
        with torch.no_grad():
            for a in range(0, len(q), chunk):
                parts.append(forward_kinematics(quat_to_matrix(q[a:a + chunk]), p[a:a + chunk])[0].numpy())
        allj = np.concatenate(parts).astype(np.float32) if parts else np.zeros((0, 22, 3), np.float32)
        for i in range(len(lib)):
            self._j[i] = allj[lib.offsets[i]:lib.offsets[i + 1]]

    def path(self, i: int) -> PathInfo:
        if i not in self._p:
            self._p[i] = analyse_path(self.joints(i))
        return self._p[i]


def _hhi_kinds(path: PathInfo, caption: str) -> list[str]:
    """Rules that fit a clip, its defining one first."""
    if path.turning:
        # approach_face first: on a turning walk the partner waits where the turn leads, the only
        # "turn towards someone" signal in the data (it has no in-place turns); avoid_blocker next
        return ["approach_face", "avoid_blocker", "follow"]
    if path.moving:
        return ["approach_face", "follow"]
    if is_gesture(caption) and path.travel < MOVING_DISTANCE:
        return ["greet"]
    return []


def _partner_pools(clips: ClipCache) -> tuple[list[int], list[int]]:
    """(standing clips, straight forward walks) of the whole library, partners' sources."""
    standing, walking = [], []
    for i in range(len(clips.lib)):
        if is_derived(clips.lib.names[i]):   # turned copies are not partners' sources
            continue
        p = clips.path(i)
        if p.standing:
            standing.append(i)
        elif p.moving and not p.turning and p.forwardness > 0.8 and 0.5 <= p.travel / max(
                clips.lib.frames(i) / FPS, 1e-6) <= 2.2:
            walking.append(i)
    return standing, walking


def _pick(rng: np.random.Generator, pool: list[int], ego: int) -> int | None:
    others = [i for i in pool if i != ego]
    if not others:
        return None
    return int(others[rng.integers(len(others))])


def _standing_source(clips: ClipCache, rng: np.random.Generator, pool: list[int], ego: int
                     ) -> tuple[np.ndarray, np.ndarray]:
    """(joints (Ts,22,3), frame indices to use) of a standing partner. Without a standing clip in the
    library, the quietest frame of another clip is held still (a body from a real clip, not moving)."""
    k = _pick(rng, pool, ego)
    if k is not None:
        return clips.joints(k), np.arange(clips.lib.frames(k))
    k = _pick(rng, list(range(len(clips.lib))), ego)
    k = ego if k is None else k
    j = clips.joints(k)
    speed = np.r_[0.0, np.linalg.norm(np.diff(j[:, 0, :2], axis=0), axis=1)]
    feet = np.abs(j[:, 10, 2] - j[:, 11, 2])
    f = int(np.argmin(speed + feet))
    return j[f:f + 1], np.zeros(1, np.int64)


def _standing_frames(src_frames: np.ndarray, t: int, shift: int) -> np.ndarray:
    """Source frames shown at ego frames 0..t-1 with a timing offset; short sources hold their ends."""
    return src_frames[np.clip(np.arange(t) + shift, 0, len(src_frames) - 1)]


def _hhi_one(kind: str, ego: int, clips: ClipCache, rng: np.random.Generator, standing: list[int],
             walking: list[int]) -> np.ndarray | None:
    ej, path = clips.joints(ego), clips.path(ego)
    t = len(ej)
    scale = float(rng.uniform(*SCALE_RANGE))
    shift = int(rng.integers(-MAX_SHIFT, MAX_SHIFT + 1))
    if kind == "follow":
        k = _pick(rng, walking, ego)
        src = clips.joints(k if k is not None else ego)
        src_path = clips.path(k if k is not None else ego)
        ahead = float(rng.uniform(1.3, 1.7))
        s_ego = np.concatenate(([0.0], np.cumsum(np.linalg.norm(np.diff(path.xy, axis=0), axis=1))))
        speed = max(path.travel / max((t - 1) / FPS, 1e-6), 0.3)
        # the leader is where the ego will be `lead` frames later (about `ahead` metres), walking the
        # ego's own path with the ego's own timing; past the clip's end it keeps the final pace
        lead = max(3, int(round(ahead / speed * FPS)) + shift)
        ft = np.arange(t) + lead
        q = s_ego[np.minimum(ft, t - 1)] + np.maximum(ft - (t - 1), 0) * path.end_speed / FPS
        q = np.maximum(q, s_ego + 1.0)   # never closer than 1 m along the path (e.g. while the ego stands)
        pts, s = _extended_path(path, float(q.max() - s_ego[-1]) + 0.5)
        xy, tan = _point_at(pts, s, q)
        frames = _loop_frames(t, len(src), int(rng.integers(0, max(1, len(src) // 3))), src)
        return place_on_path(src, src_path, frames, xy, tan, scale)
    src, src_frames = _standing_source(clips, rng, standing, ego)
    frames = _standing_frames(src_frames, t, shift)
    if kind == "approach_face":
        end = ej[-1, 0, :2].astype(np.float64)
        d = float(rng.uniform(0.9, 1.2)) + 0.3 * min(path.end_speed, 2.0)
        side = np.array([-path.h_end[1], path.h_end[0]])
        target = end + d * path.h_end + float(rng.uniform(-0.15, 0.15)) * side
        face = _unit(end - target)
        return place_standing(src, frames, int(frames[-1]), target, face, scale)
    if kind == "turn_to_face":
        end = ej[-1, 0, :2].astype(np.float64)
        face = _unit(path.facing[-3:].mean(0))
        side = np.array([-face[1], face[0]])
        target = end + float(rng.uniform(1.0, 2.4)) * face + float(rng.uniform(-0.15, 0.15)) * side
        return place_standing(src, frames, int(frames[-1]), target, -face, scale)
    if kind == "greet":
        mean_face = _unit(path.facing.mean(0))
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
    """Up to `per_clip` HHI pairs per clip of `clip_ids` (rules in the module docstring).

    Clips no rule fits (e.g. dance, jumps, side steps) give none. Deterministic for a seed; a clip's pairs
    do not depend on which other clips are in `clip_ids`. Every pair keeps the partner at least
    MIN_CLEARANCE from the ego at every frame (placements that do not are resampled, then skipped).
    """
    clips = ClipCache(lib)
    standing, walking = _partner_pools(clips)
    out: list[HHIPair] = []
    for ego in clip_ids:
        rng = np.random.default_rng([seed, int(ego)])
        # the only derived clips are turned copies (data/turns.py)
        rules = ["turn_to_face"] if is_derived(lib.names[ego]) else _hhi_kinds(clips.path(ego), lib.captions[ego])
        fits = [k for k in rules if k in kinds]
        if not fits or per_clip <= 0:
            continue
        order = fits[:1] + [fits[1:][i] for i in rng.permutation(len(fits) - 1)]
        for n in range(per_clip):
            kind = order[n % len(order)]
            for _ in range(8):
                partner = _hhi_one(kind, ego, clips, rng, standing, walking)
                if partner is not None and np.isfinite(partner).all() and \
                        min_clearance(clips.joints(ego), partner) >= MIN_CLEARANCE:
                    out.append(HHIPair(int(ego), partner.astype(np.float32), kind))
                    break
    return out


# ----------------------------------------------------------------------------- HSI
HSI_KINDS = ("block_turn", "beside_path", "corridor", "static", "detour")
GOAL_LEAD = 1.5           # s: a clip still walking at its end gets its goal this far ahead (at its final speed)
GOAL_LEAD_MAX = 2.5       # m
STOPPED_SPEED = 0.3       # m/s: a clip slower than this at its end has stopped there
_BOX_FACES = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                       [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]], np.int64)


@dataclass
class _Box:
    """An obstacle's footprint: centre (2,), unit axis u (2,) along its length, half sizes, height."""
    centre: np.ndarray
    u: np.ndarray
    hu: float
    hn: float
    height: float
    kind: str  # "box" | "wall" | "table" | "step"

    @property
    def n(self) -> np.ndarray:
        return np.array([-self.u[1], self.u[0]])

    def triangles(self) -> tuple[np.ndarray, np.ndarray]:
        """Closed boxes: one for a box, wall or step; a top and four legs for a table."""
        if self.kind != "table":
            return _cuboid(self.centre, self.u, self.hu, self.hn, 0.0, self.height)
        top = 0.05
        parts = [_cuboid(self.centre, self.u, self.hu, self.hn, self.height - top, self.height)]
        leg = 0.03
        for a in (-1, 1):
            for b in (-1, 1):
                c = self.centre + a * (self.hu - leg) * self.u + b * (self.hn - leg) * self.n
                parts.append(_cuboid(c, self.u, leg, leg, 0.0, self.height - top))
        return _merge(parts)


def _cuboid(c: np.ndarray, u: np.ndarray, hu: float, hn: float, z0: float, z1: float
            ) -> tuple[np.ndarray, np.ndarray]:
    n = np.array([-u[1], u[0]])
    v = np.array([[*(c + a * hu * u + b * hn * n), z] for a in (-1, 1) for b in (-1, 1) for z in (z0, z1)])
    return v, _BOX_FACES.copy()


def _merge(parts: list[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    vs, fs, off = [], [], 0
    for v, f in parts:
        vs.append(v)
        fs.append(f + off)
        off += len(v)
    return np.concatenate(vs).astype(np.float32), np.concatenate(fs).astype(np.int64)


@dataclass(eq=False)
class HSIScene:
    """An ego clip in an invented scene: obstacle triangles (world) and a goal from its own path."""
    ego: int
    vertices: np.ndarray        # (V, 3) float32 world
    faces: np.ndarray           # (M, 3) int64
    goal: np.ndarray            # (3,) world goal point on the floor (hsi_goal)
    kind: str                   # one of HSI_KINDS
    _grid: "OccupancyGrid | None" = field(default=None, init=False, repr=False, compare=False)

    def grid(self) -> "OccupancyGrid":
        """Voxelised obstacles (voxel_size 0.05, solid interiors), built once and cached."""
        if self._grid is None:
            from ..voxel import OccupancyGrid
            self._grid = OccupancyGrid.from_triangles(self.vertices, self.faces, voxel_size=VOXEL_SIZE)
        return self._grid


def _random_obstacle(rng: np.random.Generator, kinds: tuple[str, ...]) -> tuple[str, float, float, float]:
    """(kind, half length, half depth, height) of a random obstacle."""
    kind = str(kinds[rng.integers(len(kinds))])
    if kind == "wall":
        return kind, rng.uniform(0.75, 1.5), rng.uniform(0.05, 0.1), rng.uniform(1.2, 1.8)
    if kind == "table":
        return kind, rng.uniform(0.4, 0.7), rng.uniform(0.3, 0.45), rng.uniform(0.7, 0.8)
    if kind == "step":
        return kind, rng.uniform(0.3, 0.6), rng.uniform(0.15, 0.3), rng.uniform(0.1, 0.2)
    return "box", rng.uniform(0.15, 0.4), rng.uniform(0.15, 0.4), rng.uniform(0.3, 1.0)


def _push_out(joints: np.ndarray, start: np.ndarray, u: np.ndarray, hu: float, hn: float, height: float,
              push: np.ndarray, gap: float, kind: str) -> _Box | None:
    """Slide an obstacle from `start` along `push` (= u or +-n) until every ego joint that could touch
    it (same height band, within its cross-section plus BODY_MARGIN) is behind it, then `gap` more.
    None when that takes more than 3 m (the obstacle would no longer be near the path)."""
    n = np.array([-u[1], u[0]])
    along_push = abs(float(push @ u)) > 0.5
    half_push, half_side = (hu, hn) if along_push else (hn, hu)
    side = n if along_push else u
    p = joints.reshape(-1, 3)
    p = p[p[:, 2] < height + BODY_MARGIN]
    rel = p[:, :2] - start
    a, b = rel @ push, rel @ side
    hit = np.abs(b) < half_side + BODY_MARGIN
    reach = float(a[hit].max()) if hit.any() else -np.inf
    delta = max(0.0, reach + half_push + BODY_MARGIN) + gap
    if delta > 3.0:
        return None
    return _Box(start + delta * push, u, hu, hn, height, kind)


def _box_clear(box: _Box, joints: np.ndarray) -> bool:
    """Analytic check: no joint within BODY_MARGIN of the obstacle's bounding box."""
    p = joints.reshape(-1, 3)
    rel = p[:, :2] - box.centre
    inside = (np.abs(rel @ box.u) < box.hu + BODY_MARGIN) & (np.abs(rel @ box.n) < box.hn + BODY_MARGIN) & \
        (p[:, 2] < box.height + BODY_MARGIN)
    return not bool(inside.any())


def _path_heading(path: PathInfo, k: int, w: int = 5) -> np.ndarray:
    t = len(path.xy)
    d = path.xy[min(k + w, t - 1)] - path.xy[max(k - w, 0)]
    return _unit(d) if np.linalg.norm(d) > 1e-6 else path.facing[k]


def _beside(joints: np.ndarray, path: PathInfo, rng: np.random.Generator, k: int,
            kinds: tuple[str, ...] = ("box", "table", "step", "wall"), side: float | None = None) -> _Box | None:
    kind, hu, hn, h = _random_obstacle(rng, kinds)
    u = _path_heading(path, k)
    n = np.array([-u[1], u[0]])
    s = side if side is not None else (1.0 if rng.random() < 0.5 else -1.0)
    start = path.xy[k] + float(rng.uniform(-0.5, 0.5)) * u
    return _push_out(joints, start, u, hu, hn, h, s * n, float(rng.uniform(0.0, 0.4)), kind)


def _hsi_boxes(kind: str, joints: np.ndarray, path: PathInfo, rng: np.random.Generator) -> list[_Box] | None:
    t = len(joints)
    if kind == "block_turn":
        okind, hu, hn, h = _random_obstacle(rng, ("box", "wall", "table"))
        # facing the walker: its long side across the straight-ahead line
        u = np.array([-path.h_start[1], path.h_start[0]])
        if okind == "box":
            hn = hu = max(hu, 0.25)
        blocker = _push_out(joints, path.xy[path.onset], u, max(hu, 0.35), hn, h, path.h_start,
                            float(rng.uniform(0.0, 0.3)), okind)
        if blocker is None:
            return None
        boxes = [blocker]
        if rng.random() < 0.5:
            b = _beside(joints, path, rng, int(rng.integers(0, max(1, path.onset))))
            if b is not None:
                boxes.append(b)
        return boxes
    if kind == "beside_path":
        k0 = int(rng.integers(0, t))
        boxes = []
        for _ in range(int(rng.integers(1, 4))):
            k = int(np.clip(k0 + rng.integers(-20, 21), 0, t - 1))
            b = _beside(joints, path, rng, k)
            if b is not None:
                boxes.append(b)
        return boxes or None
    if kind == "corridor":
        k = int(rng.integers(0, t))
        boxes = [_beside(joints, path, rng, k, ("wall",), side=s) for s in (-1.0, 1.0)]
        return None if any(b is None for b in boxes) else boxes
    if kind == "detour":
        return _detour_box(joints, path, rng)
    if kind == "static":
        centre = joints[:, 0, :2].mean(0).astype(np.float64)
        boxes = []
        for _ in range(int(rng.integers(1, 3))):
            okind, hu, hn, h = _random_obstacle(rng, ("box", "table", "wall", "step"))
            a = float(rng.uniform(-np.pi, np.pi))
            d = np.array([np.cos(a), np.sin(a)])
            b = _push_out(joints, centre, np.array([-d[1], d[0]]), hu, hn, h, d, float(rng.uniform(0.0, 0.5)),
                          okind)
            if b is not None:
                boxes.append(b)
        return boxes or None
    raise ValueError(f"unknown HSI scene kind {kind!r}; use one of {', '.join(HSI_KINDS)}")


def _detour_box(joints: np.ndarray, path: PathInfo, rng: np.random.Generator) -> list[_Box] | None:
    """A box on the straight line from the copy's start to where it stops, beside the detour's widest point,
    as large as the detour leaves room for (its half width shrinks until the path clears it)."""
    chord = path.xy[-1] - path.xy[0]
    if np.linalg.norm(chord) < 1.0:
        return None
    u = _unit(chord)
    n = np.array([-u[1], u[0]])
    rel = path.xy - path.xy[0]
    apex = int(np.argmax(np.abs(rel @ n)))
    centre = path.xy[0] + (float(rel[apex] @ u) + float(rng.uniform(-0.3, 0.3))) * u + \
        float(rng.uniform(-0.1, 0.1)) * n
    kind = "table" if rng.random() < 0.2 else "box"
    hu, h = float(rng.uniform(0.2, 0.45)), float(rng.uniform(0.4, 1.0) if kind == "box" else rng.uniform(0.7, 0.8))
    for hn in np.arange(float(rng.uniform(0.3, 0.55)), 0.149, -0.05):
        box = _Box(centre, u, hu, float(hn), h, kind)
        if _box_clear(box, joints):
            return [box]
    return None


def hsi_goal(joints: np.ndarray, path: PathInfo, name: str) -> np.ndarray:
    """(3,) floor goal: where the clip stops, or, for a clip still walking at its end (captured walks end
    mid-stride), GOAL_LEAD seconds further along its final heading, so a goal under the ego always means
    "stop here" and a goal ahead "keep going" (data/detours.py makes the stops)."""
    end = joints[-1, 0, :2].astype(np.float64)
    stopped = derived_kind(name) in ("arrive", "detour")
    if not stopped and path.end_speed >= STOPPED_SPEED:
        end = end + min(GOAL_LEAD_MAX, GOAL_LEAD * path.end_speed) * path.h_end
    return np.array([end[0], end[1], 0.0], np.float32)


def _hsi_kinds(path: PathInfo, name: str = "") -> list[str]:
    if derived_kind(name) == "detour":
        return ["detour"]
    if path.turning:
        return ["block_turn", "beside_path", "corridor"]
    if path.travel >= MOVING_DISTANCE:
        return ["beside_path", "corridor"]
    return ["static"]


def scene_collisions(grid: "OccupancyGrid", joints: np.ndarray, height: float = SCENE_CHECK_HEIGHT) -> int:
    """Number of ego joints (any frame) below `height` that fall in an occupied voxel."""
    p = joints.reshape(-1, 3)
    p = p[p[:, 2] < height]
    return int(np.count_nonzero(grid.occupied(p))) if len(p) else 0


def build_hsi_scenes(lib: ClipLibrary, clip_ids: list[int], seed: int = 0, per_clip: int = 2) -> list[HSIScene]:
    """Up to `per_clip` procedural scenes per clip of `clip_ids` (rules in the module docstring).

    Deterministic for a seed; a clip's scenes do not depend on the other clips. Every returned scene's
    voxel grid (already built and cached) has no ego joint below 1.5 m inside an obstacle at any frame;
    placements that fail are resampled, then skipped.
    """
    from ..voxel import OccupancyGrid
    clips = ClipCache(lib)
    out: list[HSIScene] = []
    for ego in clip_ids:
        rng = np.random.default_rng([seed, int(ego), 1])
        joints, path = clips.joints(ego), clips.path(ego)
        kinds = _hsi_kinds(path, lib.names[ego])
        order = kinds[:1] + [kinds[1:][i] for i in rng.permutation(len(kinds) - 1)]
        goal = hsi_goal(joints, path, lib.names[ego])
        for n in range(max(per_clip, 0)):
            kind = order[n % len(order)]
            for _ in range(8):
                boxes = _hsi_boxes(kind, joints, path, rng)
                if not boxes or not all(_box_clear(b, joints) for b in boxes):
                    continue
                v, f = _merge([b.triangles() for b in boxes])
                grid = OccupancyGrid.from_triangles(v, f, voxel_size=VOXEL_SIZE)
                if scene_collisions(grid, joints):
                    continue
                scene = HSIScene(int(ego), v, f, goal.copy(), kind)
                scene._grid = grid
                out.append(scene)
                break
    return out
