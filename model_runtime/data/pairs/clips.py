"""What the pair builders need to know about a clip: its joints, facing and pelvis path (travel, headings,
the turn), and a per-build cache of both."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from ...skeleton import LEFT_HIP, RIGHT_HIP, forward_kinematics, quat_to_matrix
from ..geometry import normalized
from ..library import ClipLibrary

FPS = 10
MOVING_DISTANCE = 1.0     # m of pelvis travel for a clip to count as locomotion
STANDING_RANGE = 0.5      # m: a clip whose pelvis stays within this (horizontal extent) is "standing"
TURN_ANGLE = np.radians(45.0)   # heading change that makes a walk a "walk-turn"
ONSET_ANGLE = np.radians(20.0)  # deviation from the initial heading that marks where the turn starts
GESTURE_WORDS = ("bow", "wave", "waving", "bye", "call", "guide", "respond", "raise", "greet", "salute",
                 "hello", "beckon")


def clip_joints(lib: ClipLibrary, i: int) -> np.ndarray:
    """(T, 22, 3) float32 world joints of clip i (FK of its pose)."""
    rot, pel = lib.pose(i)
    return forward_kinematics(rot, pel)[0].numpy().astype(np.float32)


def pose_joints(rotations: np.ndarray, pelvis: np.ndarray) -> np.ndarray:
    """(T, 22, 3) float64 world joints of a pose sequence that is not a library clip (rotations (T, 22, 4)
    w-first, pelvis (T, 3))."""
    rot = quat_to_matrix(torch.from_numpy(rotations.astype(np.float64)))
    return forward_kinematics(rot, torch.from_numpy(pelvis.astype(np.float64)))[0].numpy()


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
    h_start = normalized(xy[min(a + span, b)] - xy[a])
    h_end = normalized(xy[b] - xy[max(b - span, a)])
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


class ClipCache:
    """Per-build cache of FK joints and path analysis (each clip is needed many times)."""

    def __init__(self, lib: ClipLibrary, ids: list[int] | None = None) -> None:
        """`ids`: the clips the first batched FK covers (default all); any other clip is computed on its own
        when asked for."""
        self.lib = lib
        self._ids = list(range(len(lib))) if ids is None else sorted(set(ids))
        self._j: dict[int, np.ndarray] = {}
        self._p: dict[int, PathInfo] = {}
        self._batched = False

    def joints(self, i: int) -> np.ndarray:
        if not self._batched:
            self._all_joints()
            self._batched = True
        if i not in self._j:
            self._j[i] = clip_joints(self.lib, i)
        return self._j[i]

    def _all_joints(self, chunk: int = 16384) -> None:
        """FK of the cached clips in a few large batches (per-clip calls are ~50x slower on small clips)."""
        lib = self.lib
        if len(self._ids) == len(lib):
            q, p = lib.rotations, lib.pelvis
        else:
            rows = np.concatenate([np.arange(lib.offsets[i], lib.offsets[i + 1]) for i in self._ids] or
                                  [np.zeros(0, np.int64)])
            q, p = lib.rotations[rows], lib.pelvis[rows]
        q = torch.from_numpy(np.ascontiguousarray(q))
        p = torch.from_numpy(np.ascontiguousarray(p))
        parts = []
        with torch.no_grad():
            for a in range(0, len(q), chunk):
                parts.append(forward_kinematics(quat_to_matrix(q[a:a + chunk]), p[a:a + chunk])[0].numpy())
        allj = np.concatenate(parts).astype(np.float32) if parts else np.zeros((0, 22, 3), np.float32)
        at = 0
        for i in self._ids:
            n = lib.frames(i)
            self._j[i] = allj[at:at + n]
            at += n

    def path(self, i: int) -> PathInfo:
        if i not in self._p:
            self._p[i] = analyse_path(self.joints(i))
        return self._p[i]
