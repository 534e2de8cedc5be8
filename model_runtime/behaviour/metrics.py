"""Behaviour metrics: NumPy functions of (T, 22, 3) world joints (Z up, metres, 10 fps model frames).

Each metric is defined here once; the suite, the scenario tests and the real-clip references call these.
"""
from __future__ import annotations

from typing import Sequence

import numpy as np

from ..data.pairs import facing_xy as hip_facing  # noqa: F401  (one definition each, shared with evaluation)
from ..data.pairs import min_clearance as min_joint_clearance  # noqa: F401
from ..evaluation.metrics import FEET as TOES  # noqa: F401  (SMPL-X "foot" joints sit at the toe base)
from ..evaluation.metrics import facing_error_deg  # noqa: F401
from ..evaluation.metrics import grounded_foot_speeds

FPS = 10.0
SEAM_PERIOD = 8                 # model frames per segment: frame k * 8 (k >= 1) starts a new segment
PLANTED_HEIGHT = 0.02           # m: a toe whose sole is this close to the floor counts as planted
REACH_RADIUS = 0.5              # m: a goal counts as reached once the pelvis is this close (horizontally)
SETTLE_S = 2.0                  # s: "does it stop": distance to the goal this long after arrival


def goal_arrival(ego: np.ndarray, goal: Sequence[float], limit_frames: int,
                 radius: float = REACH_RADIUS, settle_s: float = SETTLE_S) -> tuple[bool, float, float]:
    """(reached, closest distance, distance settle_s after arrival) for the pelvis against a floor goal.

    Reached: within `radius` (horizontal) at some frame < limit_frames. The settle distance is NaN when not
    reached or when the episode ends before arrival + settle_s.
    """
    d = np.linalg.norm(np.asarray(ego, np.float64)[:, 0, :2] - np.asarray(goal, np.float64)[:2], axis=-1)
    inside = np.flatnonzero(d[:limit_frames] < radius)
    if inside.size == 0:
        return False, float(d.min()), float("nan")
    after = inside[0] + int(round(settle_s * FPS))
    return True, float(d.min()), float(d[after]) if after < len(d) else float("nan")


def frames_inside_boxes(joints: np.ndarray, boxes: Sequence) -> np.ndarray:
    """(T,) bool: any joint strictly inside any axis-aligned box (objects with .lo and .hi (3,) corners)."""
    j = np.asarray(joints, np.float64)
    hit = np.zeros(j.shape[0], bool)
    for b in boxes:
        lo, hi = np.asarray(b.lo, np.float64), np.asarray(b.hi, np.float64)
        hit |= ((j > lo) & (j < hi)).all(-1).any(-1)
    return hit


def joint_steps(joints: np.ndarray) -> np.ndarray:
    """(T-1,) mean over joints of the displacement from frame t-1 to frame t (m)."""
    j = np.asarray(joints, np.float64)
    return np.linalg.norm(np.diff(j, axis=0), axis=-1).mean(-1)


def seam_ratio(joints: np.ndarray, period: int = SEAM_PERIOD, offset: int = 0) -> float:
    """Mean joint step into a seam frame (t = offset + k * period, k >= 1) over the mean step into other frames.

    1.0 means seams are invisible; a pop at every segment boundary gives a large ratio. Seams are the frames
    where a new segment starts; the step into frame t is joints[t] - joints[t - 1].
    """
    steps = joint_steps(joints)                     # steps[t - 1] is the step into frame t
    t = np.arange(1, len(steps) + 1)
    seam = ((t - offset) % period == 0) & (t > offset)
    if not seam.any() or seam.all():
        return float("nan")
    other = steps[~seam].mean()
    return float(steps[seam].mean() / max(other, 1e-9))


def planted_toe_speed(joints: np.ndarray, floor: float = 0.0, height: float = PLANTED_HEIGHT) -> np.ndarray:
    """Horizontal toe speeds (m/s) over every frame step where that toe's sole is below `height` at both ends.

    Pooled over both toes; concatenate several sequences' outputs and take the mean.
    """
    # the evaluation's grounded-foot measure (cm per frame, same toe joints) with the tighter planted height
    return grounded_foot_speeds(joints, floor, contact=height) / 100.0 * FPS


def heading_deg(joints: np.ndarray) -> np.ndarray:
    """(T,) unwrapped hip heading in degrees (counter-clockwise about +Z)."""
    f = hip_facing(joints)
    return np.degrees(np.unwrap(np.arctan2(f[:, 1], f[:, 0])))


def net_yaw_deg(joints: np.ndarray, per_seconds: float = 20.0) -> float:
    """Net heading change from first to last frame, scaled to `per_seconds` of motion (signed degrees)."""
    h = heading_deg(joints)
    duration = (len(h) - 1) / FPS
    return float((h[-1] - h[0]) * per_seconds / max(duration, 1e-9))


def standing_drift_m(joints: np.ndarray, per_seconds: float = 60.0) -> float:
    """Horizontal pelvis distance from the first to the last frame, scaled to `per_seconds` (m)."""
    p = np.asarray(joints, np.float64)[:, 0, :2]
    duration = (len(p) - 1) / FPS
    return float(np.linalg.norm(p[-1] - p[0]) * per_seconds / max(duration, 1e-9))
