"""Small NumPy geometry shared by the motion readers, retargeting and the pair builders: unit vectors and
rotation matrices from Euler angles."""
from __future__ import annotations

import numpy as np

_PLANE = ((1, 2), (2, 0), (0, 1))   # the two axes each of x, y, z rotates


def normalized(v: np.ndarray) -> np.ndarray:
    """v scaled to length 1 along its last axis (a zero vector stays zero)."""
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)


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
