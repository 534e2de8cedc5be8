"""The 22-joint SMPL-X body skeleton, forward kinematics and rotation maths (all torch, batched).

The body's names, parents and rest positions live in ``joints.py`` (no torch); NumPy quaternion
maths in ``quat.py``.

Conventions used everywhere in the package:
- quaternions are (w, x, y, z);
- the 6D rotation form is the first two *columns* of the matrix, concatenated (c0, c1);
- a pose is 22 local rotation matrices (index 0 = global orientation) plus the pelvis world position.
"""
from __future__ import annotations

import numpy as np
import torch

from .joints import (FOOT_JOINTS, JOINT_INDEX, JOINT_NAMES, LEFT_HIP, NUM_JOINTS, PARENTS,  # noqa: F401
                     REST_JOINTS_ZUP, RIGHT_HIP, SOLE_BELOW_FOOT_JOINT, standing_pelvis_height)
from .quat import unit_vectors


def rest_joints(dtype: torch.dtype = torch.float32) -> torch.Tensor:
    """(22, 3) rest joints with the pelvis at the origin."""
    j = torch.tensor(REST_JOINTS_ZUP, dtype=dtype)
    return j - j[0]


def rest_offsets(dtype: torch.dtype = torch.float32) -> torch.Tensor:
    """(22, 3) bone vectors joint - parent in the rest pose (row 0 is zero)."""
    j = torch.tensor(REST_JOINTS_ZUP, dtype=dtype)
    off = torch.zeros_like(j)
    for i, p in enumerate(PARENTS):
        if p >= 0:
            off[i] = j[i] - j[p]
    return off


_OFFSETS = rest_offsets()


def _levels() -> list[list[int]]:
    """Joints grouped by depth in the tree, so FK runs one batched step per level (8) not per joint (21)."""
    depth = [0] * NUM_JOINTS
    for i in range(1, NUM_JOINTS):
        depth[i] = depth[PARENTS[i]] + 1
    return [[i for i in range(NUM_JOINTS) if depth[i] == d] for d in range(1, max(depth) + 1)]


_LEVELS = [(torch.tensor(lv), torch.tensor([PARENTS[i] for i in lv])) for lv in _levels()]


def forward_kinematics(local_rot: torch.Tensor, pelvis: torch.Tensor,
                       offsets: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
    """Batched FK.

    local_rot: (..., 22, 3, 3) local rotations (index 0 = global orientation);
    pelvis: (..., 3) world pelvis position; offsets: (22, 3) or (..., 22, 3) bone vectors.
    Returns (joints (..., 22, 3), global rotations (..., 22, 3, 3)).
    """
    off = (_OFFSETS if offsets is None else offsets).to(local_rot)
    glob = torch.empty_like(local_rot)
    pos = torch.empty(local_rot.shape[:-2] + (3,), dtype=local_rot.dtype, device=local_rot.device)
    glob[..., 0, :, :] = local_rot[..., 0, :, :]
    pos[..., 0, :] = pelvis
    for idx, par in _LEVELS:
        gp = glob[..., par, :, :]
        glob[..., idx, :, :] = gp @ local_rot[..., idx, :, :]
        pos[..., idx, :] = pos[..., par, :] + (gp @ off[..., idx, :].unsqueeze(-1)).squeeze(-1)
    return pos, glob


def global_to_local(global_rot: torch.Tensor) -> torch.Tensor:
    """(..., 22, 3, 3) global rotations -> local rotations."""
    loc = [global_rot[..., 0, :, :]]
    for i in range(1, NUM_JOINTS):
        loc.append(global_rot[..., PARENTS[i], :, :].transpose(-1, -2) @ global_rot[..., i, :, :])
    return torch.stack(loc, dim=-3)


# ----------------------------------------------------------------------------- rotation maths

def rot6d_to_matrix(d6: torch.Tensor) -> torch.Tensor:
    """(..., 6) -> (..., 3, 3) by Gram-Schmidt; the 6D form holds the first two columns."""
    a1, a2 = d6[..., :3], d6[..., 3:]
    b1 = torch.nn.functional.normalize(a1, dim=-1)
    b2 = torch.nn.functional.normalize(a2 - (b1 * a2).sum(-1, keepdim=True) * b1, dim=-1)
    b3 = torch.cross(b1, b2, dim=-1)
    return torch.stack((b1, b2, b3), dim=-1)


def matrix_to_rot6d(m: torch.Tensor) -> torch.Tensor:
    """(..., 3, 3) -> (..., 6): first column then second column."""
    return torch.cat((m[..., :, 0], m[..., :, 1]), dim=-1)


def quat_to_matrix(q: torch.Tensor) -> torch.Tensor:
    """(..., 4) w-first quaternion (normalised here) -> (..., 3, 3)."""
    q = torch.nn.functional.normalize(q, dim=-1)
    w, x, y, z = q.unbind(-1)
    m = torch.stack((
        1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
        2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
        2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
    ), dim=-1)
    return m.reshape(q.shape[:-1] + (3, 3))


def matrix_to_quat(m: torch.Tensor) -> torch.Tensor:
    """(..., 3, 3) -> (..., 4) w-first unit quaternion with w >= 0 (numerically stable branch pick)."""
    m00, m11, m22 = m[..., 0, 0], m[..., 1, 1], m[..., 2, 2]
    cands = torch.stack((
        1 + m00 + m11 + m22, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22,
    ), dim=-1)
    best = cands.argmax(dim=-1, keepdim=True)
    s = torch.sqrt(cands.clamp_min(1e-12))  # s = 4 * |component| / 2
    r21, r12 = m[..., 2, 1], m[..., 1, 2]
    r02, r20 = m[..., 0, 2], m[..., 2, 0]
    r10, r01 = m[..., 1, 0], m[..., 0, 1]
    q_w = torch.stack((s[..., 0], (r21 - r12) / s[..., 0], (r02 - r20) / s[..., 0], (r10 - r01) / s[..., 0]), -1)
    q_x = torch.stack(((r21 - r12) / s[..., 1], s[..., 1], (r01 + r10) / s[..., 1], (r02 + r20) / s[..., 1]), -1)
    q_y = torch.stack(((r02 - r20) / s[..., 2], (r01 + r10) / s[..., 2], s[..., 2], (r12 + r21) / s[..., 2]), -1)
    q_z = torch.stack(((r10 - r01) / s[..., 3], (r02 + r20) / s[..., 3], (r12 + r21) / s[..., 3], s[..., 3]), -1)
    allq = torch.stack((q_w, q_x, q_y, q_z), dim=-2) * 0.5
    q = torch.gather(allq, -2, best.unsqueeze(-1).expand(best.shape[:-1] + (1, 4))).squeeze(-2)
    q = torch.nn.functional.normalize(q, dim=-1)
    return torch.where(q[..., :1] < 0, -q, q)


def axis_angle_to_matrix(aa: torch.Tensor) -> torch.Tensor:
    """(..., 3) rotation vector -> (..., 3, 3) (Rodrigues)."""
    angle = aa.norm(dim=-1, keepdim=True)
    half = 0.5 * angle
    small = angle < 1e-8
    scale = torch.where(small, 0.5 - angle * angle / 48.0, torch.sin(half) / angle.clamp_min(1e-12))
    q = torch.cat((torch.cos(half), aa * scale), dim=-1)
    return quat_to_matrix(q)


def matrix_to_axis_angle(m: torch.Tensor) -> torch.Tensor:
    """(..., 3, 3) -> (..., 3) rotation vector."""
    q = matrix_to_quat(m)
    xyz = q[..., 1:]
    sin_half = xyz.norm(dim=-1, keepdim=True)
    angle = 2 * torch.atan2(sin_half, q[..., :1])
    return xyz * torch.where(sin_half < 1e-8, 2.0 + 0 * angle, angle / sin_half.clamp_min(1e-12))


def yaw_matrix(yaw: torch.Tensor) -> torch.Tensor:
    """(...,) angle about +Z (radians, counter-clockwise seen from above) -> (..., 3, 3)."""
    c, s = torch.cos(yaw), torch.sin(yaw)
    z, o = torch.zeros_like(yaw), torch.ones_like(yaw)
    return torch.stack((c, -s, z, s, c, z, z, z, o), dim=-1).reshape(yaw.shape + (3, 3))


def quat_slerp(q0: torch.Tensor, q1: torch.Tensor, t: torch.Tensor | float) -> torch.Tensor:
    """Spherical interpolation of w-first quaternions (..., 4), shortest arc."""
    t = torch.as_tensor(t, dtype=q0.dtype)
    dot = (q0 * q1).sum(-1, keepdim=True)
    q1 = torch.where(dot < 0, -q1, q1)
    dot = dot.abs().clamp(max=1.0)
    theta = torch.acos(dot)
    sin_t = torch.sin(theta)
    near = sin_t < 1e-6
    w0 = torch.where(near, 1 - t, torch.sin((1 - t) * theta) / sin_t.clamp_min(1e-12))
    w1 = torch.where(near, t, torch.sin(t * theta) / sin_t.clamp_min(1e-12))
    return torch.nn.functional.normalize(w0 * q0 + w1 * q1, dim=-1)


# ----------------------------------------------------------------------------- NumPy, single poses
# The per-frame output path handles one pose at a time, where each torch op costs ~5-10 us of dispatch
# and a NumPy op ~1 us; these mirror the torch functions above (tests check they agree).
_OFFSETS_NP = rest_offsets().numpy()
_LEVELS_NP = [(idx.numpy(), par.numpy()) for idx, par in _LEVELS]


def rot6d_to_matrix_np(d6: np.ndarray) -> np.ndarray:
    a1, a2 = d6[..., :3], d6[..., 3:]
    b1 = unit_vectors(a1)
    b2 = unit_vectors(a2 - (b1 * a2).sum(-1, keepdims=True) * b1)
    return np.stack((b1, b2, np.cross(b1, b2)), axis=-1)


def forward_kinematics_np(local_rot: np.ndarray, pelvis: np.ndarray, world_rotations: bool = False):
    """(..., 22, 3, 3) local rotations, (..., 3) pelvis -> (..., 22, 3) joints, and their (..., 22, 3, 3) world
    rotations when `world_rotations` (the planted-foot IK needs both, and FK computes both anyway)."""
    glob = np.empty_like(local_rot)
    pos = np.empty(local_rot.shape[:-2] + (3,), dtype=local_rot.dtype)
    glob[..., 0, :, :], pos[..., 0, :] = local_rot[..., 0, :, :], pelvis
    for idx, par in _LEVELS_NP:
        gp = glob[..., par, :, :]
        glob[..., idx, :, :] = gp @ local_rot[..., idx, :, :]
        pos[..., idx, :] = pos[..., par, :] + (gp @ _OFFSETS_NP[idx][..., None])[..., 0]
    return (pos, glob) if world_rotations else pos
