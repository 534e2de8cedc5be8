"""Motion-quality and interaction metrics on joint arrays (NumPy; unit-tested on analytic motion)."""
from __future__ import annotations

from typing import Any

import numpy as np

from ..data.pairs import facing_xy as hip_facing
from ..data.pairs import min_clearance as min_body_clearance
from ..skeleton import JOINT_INDEX, SOLE_BELOW_FOOT_JOINT

__all__ = ["joint_error_mm", "constant_velocity", "grounded_foot_speeds", "foot_skating_cm", "peak_jerk",
           "facing_error_deg", "min_body_clearance", "collision_frames", "collision_percent"]

FPS = 10
FEET = (JOINT_INDEX["left_foot"], JOINT_INDEX["right_foot"])
GROUND_CONTACT = 0.05     # m: a sole this close to the floor counts as grounded
COLLISION_HEIGHT = 1.5    # m: ego joints above this are ignored for scene collisions (arms raised over a box)


def joint_error_mm(pred: np.ndarray, gt: np.ndarray) -> float:
    """Mean Euclidean joint position error in millimetres over all leading axes: (..., 22, 3) each."""
    return float(np.linalg.norm(np.asarray(pred, np.float64) - np.asarray(gt, np.float64), axis=-1).mean() * 1000)


def constant_velocity(history: np.ndarray, frames: int) -> np.ndarray:
    """Extrapolate each joint with its last history velocity: (..., H >= 2, J, 3) -> (..., frames, J, 3)."""
    h = np.asarray(history, np.float64)
    if h.shape[-3] < 2:
        raise ValueError("constant_velocity needs at least 2 history frames")
    last, vel = h[..., -1:, :, :], h[..., -1:, :, :] - h[..., -2:-1, :, :]
    k = np.arange(1, frames + 1, dtype=np.float64).reshape((frames, 1, 1))
    return last + k * vel


def grounded_foot_speeds(joints: np.ndarray, floor: float = 0.0, contact: float = GROUND_CONTACT) -> np.ndarray:
    """Horizontal foot-joint displacement (cm per frame) over every frame step where that foot's sole is
    within `contact` of the floor at both ends. joints (T, 22, 3), Z up; the sole is SOLE_BELOW_FOOT_JOINT
    below the foot joint. Pooled over feet; concatenate sequences' outputs to average several."""
    j = np.asarray(joints, np.float64)[:, list(FEET), :]
    sole = j[..., 2] - SOLE_BELOW_FOOT_JOINT - floor
    down = sole < contact
    both = down[1:] & down[:-1]
    step = np.linalg.norm(j[1:, :, :2] - j[:-1, :, :2], axis=-1) * 100.0
    return step[both]


def foot_skating_cm(joints: np.ndarray, floor: float = 0.0, contact: float = GROUND_CONTACT) -> float:
    """Mean grounded foot speed, cm/frame (NaN when no foot is ever grounded). A still foot scores 0."""
    s = grounded_foot_speeds(joints, floor, contact)
    return float(s.mean()) if s.size else float("nan")


def peak_jerk(joints: np.ndarray, fps: float = FPS) -> float:
    """Max over joints and time of the third finite difference of positions, in m/s^3. (T >= 4, J, 3)."""
    j = np.asarray(joints, np.float64)
    if j.shape[0] < 4:
        return float("nan")
    d3 = j[3:] - 3 * j[2:-1] + 3 * j[1:-2] - j[:-3]
    return float(np.linalg.norm(d3, axis=-1).max() * fps ** 3)


def facing_error_deg(ego: np.ndarray, target_xy: np.ndarray) -> np.ndarray | float:
    """Angle (degrees, 0..180) between the ego's hip facing and the horizontal direction from its pelvis
    to target_xy. ego (..., 22, 3), target_xy (..., 2) or (..., 3)."""
    e = np.asarray(ego, np.float64)
    to = np.asarray(target_xy, np.float64)[..., :2] - e[..., 0, :2]
    f = hip_facing(e)   # +Z x (right hip - left hip): the rest body faces -Y
    cross = f[..., 0] * to[..., 1] - f[..., 1] * to[..., 0]
    ang = np.degrees(np.abs(np.arctan2(cross, (f * to).sum(-1))))
    return float(ang) if np.ndim(ang) == 0 else ang


def collision_frames(joints: np.ndarray, grid: Any, height: float = COLLISION_HEIGHT) -> np.ndarray:
    """(T,) bool: any ego joint below `height` inside an occupied voxel of `grid` (an OccupancyGrid)."""
    j = np.asarray(joints, np.float64)
    hit = np.asarray(grid.occupied(j), bool) & (j[..., 2] < height)
    return hit.any(axis=-1)


def collision_percent(joints: np.ndarray, grid: Any, height: float = COLLISION_HEIGHT) -> float:
    """Percent of frames in collision (see collision_frames)."""
    c = collision_frames(joints, grid, height)
    return float(100.0 * c.mean()) if c.size else float("nan")
