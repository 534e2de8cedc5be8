"""Small NumPy geometry shared by the motion readers, retargeting and the pair builders: unit vectors,
rotation matrices from Euler angles, between directions and from orthonormal frames."""
from __future__ import annotations

import numpy as np

from ..quat import unit_vectors as normalized  # noqa: F401  (the one unit-vector helper)

_PLANE = ((1, 2), (2, 0), (0, 1))   # the two axes each of x, y, z rotates


def axis_rotation(axis: int, ang: np.ndarray) -> np.ndarray:
    """Rotations (..., 3, 3) by angles (radians) about the x (0), y (1) or z (2) axis."""
    c, s = np.cos(ang), np.sin(ang)
    m = np.zeros(np.shape(ang) + (3, 3))
    a, b = _PLANE[axis]
    m[..., axis, axis] = 1.0
    m[..., a, a], m[..., a, b], m[..., b, a], m[..., b, b] = c, -s, s, c
    return m


def euler_matrix(angles_deg: np.ndarray, order: str) -> np.ndarray:
    """(..., n) angles in degrees about the n axes named by `order` ("ZXY", case-insensitive) ->
    (..., 3, 3) R = R_order[0] @ R_order[1] @ ... : the axes compose in the order listed, as BVH channels do."""
    a = np.radians(np.asarray(angles_deg, np.float64))
    m = np.broadcast_to(np.eye(3), a.shape[:-1] + (3, 3)).copy()
    for k, ax in enumerate(order.upper()):
        m = m @ axis_rotation("XYZ".index(ax), a[..., k])
    return m


def rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Smallest rotations (T, 3, 3) taking directions a onto b (T, 3)."""
    a, b = normalized(a), normalized(b)
    axis = np.cross(a, b)
    s = np.linalg.norm(axis, axis=-1)
    c = (a * b).sum(-1)
    # antiparallel: turn half way round any axis perpendicular to a
    perp = np.cross(a, np.array([1.0, 0.0, 0.0]))
    perp = np.where(np.linalg.norm(perp, axis=-1, keepdims=True) < 1e-6, np.cross(a, [0.0, 1.0, 0.0]), perp)
    axis = np.where((s < 1e-9)[:, None], normalized(perp), axis / np.maximum(s, 1e-12)[:, None])
    angle = np.arctan2(s, c)
    return axis_angle_rotation(axis, angle)


def axis_angle_rotation(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rotations (T, 3, 3) by angles (T,) (radians) about unit axes (T, 3)."""
    x, y, z = axis[:, 0], axis[:, 1], axis[:, 2]
    c, s = np.cos(angle), np.sin(angle)
    t = 1 - c
    return np.stack([np.stack([t * x * x + c, t * x * y - s * z, t * x * z + s * y], -1),
                     np.stack([t * x * y + s * z, t * y * y + c, t * y * z - s * x], -1),
                     np.stack([t * x * z - s * y, t * y * z + s * x, t * z * z + c], -1)], -2)


def frame_of(primary: np.ndarray, secondary: np.ndarray) -> np.ndarray:
    """Orthonormal frames (T, 3, 3) whose first column is `primary` and second is `secondary`'s part
    perpendicular to it."""
    a = normalized(primary)
    b = normalized(secondary - (secondary * a).sum(-1, keepdims=True) * a)
    return np.stack([a, b, np.cross(a, b)], -1)


def two_vector_rotation(rest_a: np.ndarray, rest_b: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Rotation taking rest direction rest_a exactly onto a, and rest_b as near as possible to b."""
    f0 = frame_of(np.broadcast_to(rest_a, a.shape), np.broadcast_to(rest_b, b.shape))
    return frame_of(a, b) @ np.swapaxes(f0, -1, -2)


def perpendicular_part(v: np.ndarray, axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Part of v perpendicular to the unit axis, and its length relative to |v| (0 = parallel)."""
    p = v - (v * axis).sum(-1, keepdims=True) * axis
    return p, np.linalg.norm(p, axis=-1) / np.maximum(np.linalg.norm(v, axis=-1), 1e-12)
