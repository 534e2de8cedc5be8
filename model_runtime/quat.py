"""NumPy quaternion maths (w, x, y, z) and unit vectors, no torch.

The per-frame output path and the Blender extension handle one pose at a time, where a NumPy op costs
about 1 us and a torch op 5-10 us of dispatch. The batched torch versions live in ``skeleton.py``;
tests check that both agree and check both against SciPy.
"""
from __future__ import annotations

import numpy as np


def unit_vectors(v: np.ndarray) -> np.ndarray:
    """Vectors along the last axis scaled to length 1 (a zero vector stays zero)."""
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)


def qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product, broadcasting over leading axes."""
    aw, ax, ay, az = np.moveaxis(a, -1, 0)
    bw, bx, by, bz = np.moveaxis(b, -1, 0)
    return np.stack((aw * bw - ax * bx - ay * by - az * bz,
                     aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw), axis=-1)


def qconj(q: np.ndarray) -> np.ndarray:
    """Conjugate (the inverse of a unit quaternion)."""
    return q * np.array([1.0, -1.0, -1.0, -1.0], dtype=q.dtype)


def qslerp(q0: np.ndarray, q1: np.ndarray, t: float | np.ndarray) -> np.ndarray:
    """Shortest-arc spherical interpolation of (..., 4) unit quaternions."""
    dot = np.sum(q0 * q1, axis=-1, keepdims=True)
    q1 = np.where(dot < 0.0, -q1, q1)
    dot = np.clip(np.abs(dot), 0.0, 1.0)
    theta = np.arccos(dot)
    s = np.sin(theta)
    near = s < 1e-6
    safe = np.where(near, 1.0, s)
    w0 = np.where(near, 1.0 - t, np.sin((1.0 - t) * theta) / safe)
    w1 = np.where(near, t, np.sin(t * theta) / safe)
    q = w0 * q0 + w1 * q1
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def matrix_to_quat_np(m: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices -> (..., 4) w-first unit quaternions with w >= 0."""
    m00, m11, m22 = m[..., 0, 0], m[..., 1, 1], m[..., 2, 2]
    r21, r12, r02, r20, r10, r01 = m[..., 2, 1], m[..., 1, 2], m[..., 0, 2], m[..., 2, 0], m[..., 1, 0], m[..., 0, 1]
    # the four standard candidates (each scaled by 4|component|), stacked; keep the best-conditioned one
    cand = np.stack((
        np.stack((1 + m00 + m11 + m22, r21 - r12, r02 - r20, r10 - r01), -1),
        np.stack((r21 - r12, 1 + m00 - m11 - m22, r01 + r10, r02 + r20), -1),
        np.stack((r02 - r20, r01 + r10, 1 - m00 + m11 - m22, r12 + r21), -1),
        np.stack((r10 - r01, r02 + r20, r12 + r21, 1 - m00 - m11 + m22), -1),
    ), -2)
    diag = np.stack((cand[..., 0, 0], cand[..., 1, 1], cand[..., 2, 2], cand[..., 3, 3]), -1)
    q = np.take_along_axis(cand, diag.argmax(-1)[..., None, None], -2)[..., 0, :]
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0, -q, q)


def rigid_rotation(m4: np.ndarray) -> np.ndarray:
    """The rotation part of a 4x4 transform with its (positive) per-axis scale divided out."""
    r = np.asarray(m4, dtype=np.float64)[:3, :3]
    return r / np.linalg.norm(r, axis=0, keepdims=True)


def continuous_quaternions(q: np.ndarray) -> np.ndarray:
    """(T, B, 4) -> the same rotations, signs flipped so no bone jumps to its antipode between frames.

    q and -q are one rotation, but keys are interpolated per component: a sign jump between two keys
    would swing the bone through a wrong pose at sub-frames (motion blur, retiming).
    """
    dots = np.sum(q[1:] * q[:-1], axis=-1)
    flips = np.concatenate((np.ones((1,) + q.shape[1:-1]), np.cumprod(np.where(dots < 0.0, -1.0, 1.0), axis=0)))
    out = q * flips[..., None]
    return out * np.where(out[:1, :, :1] < 0.0, -1.0, 1.0)   # start in the w >= 0 hemisphere
