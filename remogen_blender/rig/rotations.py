"""Batched rotation matrices for retargeting: quaternion <-> matrix, axis-angle, the rotation between two
directions. Everything broadcasts over leading axes (frames, bones); quaternions are w first."""
from __future__ import annotations

import numpy as np

_TINY = 1e-12


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """(..., 4) unit quaternions -> (..., 3, 3) rotation matrices."""
    q = np.asarray(q, dtype=np.float64)
    q = q / np.maximum(np.sqrt(np.sum(q * q, axis=-1, keepdims=True)), _TINY)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    out = np.empty(q.shape[:-1] + (3, 3))
    out[..., 0, 0] = 1 - 2 * (y * y + z * z)
    out[..., 0, 1] = 2 * (x * y - w * z)
    out[..., 0, 2] = 2 * (x * z + w * y)
    out[..., 1, 0] = 2 * (x * y + w * z)
    out[..., 1, 1] = 1 - 2 * (x * x + z * z)
    out[..., 1, 2] = 2 * (y * z - w * x)
    out[..., 2, 0] = 2 * (x * z - w * y)
    out[..., 2, 1] = 2 * (y * z + w * x)
    out[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return out


def norm(v: np.ndarray) -> np.ndarray:
    """Lengths along the last axis (np.linalg.norm costs more for the small arrays of one live frame)."""
    return np.sqrt(np.sum(v * v, axis=-1))


def unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(norm(v), _TINY)[..., None]


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product along the last axis, broadcasting (np.cross costs more for one live frame)."""
    a, b = np.broadcast_arrays(a, b)
    out = np.empty(a.shape)
    out[..., 0] = a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1]
    out[..., 1] = a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2]
    out[..., 2] = a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]
    return out


def axis_angle(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """(..., 3) unit axes and (...) angles -> (..., 3, 3) rotations (Rodrigues)."""
    x, y, z = axis[..., 0], axis[..., 1], axis[..., 2]
    s, c = np.sin(angle), np.cos(angle)
    t = 1.0 - c
    out = np.empty(axis.shape[:-1] + (3, 3))
    out[..., 0, 0] = t * x * x + c
    out[..., 0, 1] = t * x * y - s * z
    out[..., 0, 2] = t * x * z + s * y
    out[..., 1, 0] = t * x * y + s * z
    out[..., 1, 1] = t * y * y + c
    out[..., 1, 2] = t * y * z - s * x
    out[..., 2, 0] = t * x * z - s * y
    out[..., 2, 1] = t * y * z + s * x
    out[..., 2, 2] = t * z * z + c
    return out


def solve3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """x with a @ x = b for (..., 3, 3) a and (..., 3) b, by the adjugate (no LAPACK call per live frame)."""
    c0, c1, c2 = a[..., :, 0], a[..., :, 1], a[..., :, 2]
    r0, r1, r2 = cross(c1, c2), cross(c2, c0), cross(c0, c1)     # rows of the adjugate
    det = np.sum(c0 * r0, axis=-1)
    return np.stack((np.sum(r0 * b, -1), np.sum(r1 * b, -1), np.sum(r2 * b, -1)), -1) / det[..., None]


def rotation_between(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(..., 3, 3): the smallest rotation taking direction u to direction v (half a turn when opposite)."""
    u, v = unit(np.asarray(u, np.float64)), unit(np.asarray(v, np.float64))
    axis = cross(u, v)
    s = norm(axis)
    c = np.clip(np.sum(u * v, axis=-1), -1.0, 1.0)
    # opposite directions: any axis perpendicular to u
    ref = np.where(np.abs(u[..., :1]) < 0.9, np.array((1.0, 0.0, 0.0)), np.array((0.0, 1.0, 0.0)))
    perp = unit(cross(u, ref))
    axis = np.where((s < 1e-9)[..., None], perp, axis / np.maximum(s, _TINY)[..., None])
    return axis_angle(axis, np.arctan2(s, c))


def yaw_matrix(yaw: float) -> np.ndarray:
    """Rotation by `yaw` radians about +Z."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array(((c, -s, 0.0), (s, c, 0.0), (0.0, 0.0, 1.0)))


def facing_yaw(left: np.ndarray) -> float:
    """The yaw (0 faces -Y) of a body whose left side points along `left` (world): forward = left x up."""
    fwd = cross(left, np.array((0.0, 0.0, 1.0)))
    if np.hypot(fwd[0], fwd[1]) < 1e-9:
        return 0.0
    return float(np.arctan2(fwd[0], -fwd[1]))
