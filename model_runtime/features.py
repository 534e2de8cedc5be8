"""The 276-D per-frame motion features (DART layout), canonicalisation and normalisation.

Layout of one frame (all in the segment's canonical frame; ARCHITECTURE.md describes the frames):

| slice        | size   | what                                             |
|--------------|--------|--------------------------------------------------|
| ROOT_T       | 3      | pelvis position                                  |
| ROT6D        | 22 x 6 | global orientation + 21 local rotations, 6D      |
| ROOT_T_DELTA | 3      | pelvis translation to the next frame             |
| ROOT_R_DELTA | 6      | R_next @ R_this^T of the global orientation, 6D  |
| JOINTS       | 22 x 3 | joint positions                                  |
| JOINT_DELTA  | 22 x 3 | joint displacement to the next frame             |

A rigid change of frame (yaw about +Z plus a translation) acts on the slices in closed form
(`rigid_transform`), so history can be moved from one segment's canonical frame to the next exactly.
"""
from __future__ import annotations

import torch

from .config import FEATURE_DIM
from .skeleton import (LEFT_HIP, NUM_JOINTS, RIGHT_HIP, forward_kinematics, matrix_to_rot6d,
                       rot6d_to_matrix)

ROOT_T = slice(0, 3)
ROT6D = slice(3, 135)
ROOT_T_DELTA = slice(135, 138)
ROOT_R_DELTA = slice(138, 144)
JOINTS = slice(144, 210)
JOINT_DELTA = slice(210, 276)


def features_from_pose(local_rot: torch.Tensor, pelvis: torch.Tensor,
                       joints: torch.Tensor | None = None) -> torch.Tensor:
    """Frames (..., T+1) of a pose sequence -> features (..., T, 276).

    local_rot (..., T+1, 22, 3, 3), pelvis (..., T+1, 3). The extra last frame only supplies the deltas.
    """
    if joints is None:
        joints, _ = forward_kinematics(local_rot, pelvis)
    cur, nxt = slice(None, -1), slice(1, None)
    go = local_rot[..., :, 0, :, :]
    rot_delta = go[..., nxt, :, :] @ go[..., cur, :, :].transpose(-1, -2)
    lead = local_rot.shape[:-4]
    t = local_rot.shape[-4] - 1
    return torch.cat((
        pelvis[..., cur, :],
        matrix_to_rot6d(local_rot[..., cur, :, :, :]).reshape(lead + (t, NUM_JOINTS * 6)),
        pelvis[..., nxt, :] - pelvis[..., cur, :],
        matrix_to_rot6d(rot_delta),
        joints[..., cur, :, :].reshape(lead + (t, NUM_JOINTS * 3)),
        (joints[..., nxt, :, :] - joints[..., cur, :, :]).reshape(lead + (t, NUM_JOINTS * 3)),
    ), dim=-1)


def features_to_pose(feat: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """(..., 276) -> (local rotations (..., 22, 3, 3), pelvis (..., 3)). Joints come from FK of these."""
    rot = rot6d_to_matrix(feat[..., ROT6D].reshape(feat.shape[:-1] + (NUM_JOINTS, 6)))
    return rot, feat[..., ROOT_T]


def self_consistent(frames: torch.Tensor) -> torch.Tensor:
    """Generated frames (T, 276) made consistent the way real frames are: joints from the kinematics of their
    rotations and pelvis, and each frame's deltas to the next from the two poses. The last frame's deltas (to a
    frame not made yet) stay as they were.

    A decoder predicts the joint channels beside the rotations, and they disagree (measured in rollouts: 1.5 cm
    and 2 degrees of facing standing, 4.6 cm and 7 degrees walking up to a partner). Fed back as history, the
    joints set the next segment's canonical frame while the rotations are what is shown, and the model,
    trained on real frames where both agree, turned the body at every segment start by about that much.
    """
    rot, pelvis = features_to_pose(frames)
    joints, _ = forward_kinematics(rot, pelvis)
    out = frames.clone()
    out[..., JOINTS] = joints.reshape(joints.shape[:-2] + (-1,))
    if frames.shape[0] >= 2:
        out[:-1] = features_from_pose(rot, pelvis, joints)
    return out


def feature_joints(feat: torch.Tensor) -> torch.Tensor:
    """(..., 276) -> the joint-position slice as (..., 22, 3)."""
    return feat[..., JOINTS].reshape(feat.shape[:-1] + (NUM_JOINTS, 3))


# The 276 channels are 92 three-vectors. Which of them a rigid change of frame moves:
_VEC3 = FEATURE_DIM // 3
_POINT_ROWS = torch.tensor([0] + list(range(JOINTS.start // 3, JOINTS.stop // 3)))        # + translation
_FIXED_ROWS = torch.arange(ROT6D.start // 3 + 2, ROT6D.stop // 3)    # local rotations of joints 1..21
_RDELTA_ROWS = (ROOT_R_DELTA.start // 3, ROOT_R_DELTA.start // 3 + 1)


def rigid_transform(feat: torch.Tensor, rot: torch.Tensor, trans: torch.Tensor) -> torch.Tensor:
    """Express features in another frame: x' = rot @ x + trans for points, rot @ v for vectors.

    rot (..., 3, 3) must be a rotation about +Z (canonical frames only differ by yaw); trans (..., 3).
    Both broadcast over the frame axis of feat (..., T, 276). Local joint rotations do not change; the
    global orientation's 6D columns rotate with rot, and its delta D becomes rot D rot^T, whose first two
    columns only need D's first two because rot^T keeps the z axis.
    """
    v = feat.reshape(feat.shape[:-1] + (_VEC3, 3))
    r = rot.unsqueeze(-3)
    out = v @ r.transpose(-1, -2)                        # every 3-vector rotated
    out[..., _FIXED_ROWS, :] = v[..., _FIXED_ROWS, :]    # ... except local rotations
    out[..., _POINT_ROWS, :] += trans.unsqueeze(-2).unsqueeze(-2)
    a = rot[..., :2, :2].transpose(-1, -2).unsqueeze(-3)  # (rot^T)[:2, :2]
    c0, c1 = out[..., _RDELTA_ROWS[0], :].clone(), out[..., _RDELTA_ROWS[1], :].clone()
    out[..., _RDELTA_ROWS[0], :] = a[..., 0, 0:1] * c0 + a[..., 1, 0:1] * c1
    out[..., _RDELTA_ROWS[1], :] = a[..., 0, 1:2] * c0 + a[..., 1, 1:2] * c1
    return out.reshape(feat.shape)


def canonical_frame(joints: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Canonical frame of one pose: joints (..., 22, 3) in world.

    Returns (rot, trans) mapping canonical -> world: x_world = rot @ x_can + trans. Origin: the pelvis
    projected on the floor (z = 0); +X from the left hip to the right hip (horizontal); +Z up; +Y = forward.
    """
    across = joints[..., RIGHT_HIP, :] - joints[..., LEFT_HIP, :]
    x = torch.stack((across[..., 0], across[..., 1], torch.zeros_like(across[..., 0])), dim=-1)
    x = torch.nn.functional.normalize(x, dim=-1, eps=1e-8)
    z = torch.zeros_like(x)
    z[..., 2] = 1.0
    y = torch.cross(z, x, dim=-1)
    rot = torch.stack((x, y, z), dim=-1)
    trans = joints[..., 0, :].clone()
    trans[..., 2] = 0.0
    return rot, trans


def to_canonical(feat_world: torch.Tensor, rot: torch.Tensor, trans: torch.Tensor) -> torch.Tensor:
    """World-frame features -> features in the frame (rot, trans) (canonical -> world)."""
    rt = rot.transpose(-1, -2)
    return rigid_transform(feat_world, rt, -(rt @ trans.unsqueeze(-1)).squeeze(-1))


def to_world(feat_can: torch.Tensor, rot: torch.Tensor, trans: torch.Tensor) -> torch.Tensor:
    """Canonical features -> world-frame features."""
    return rigid_transform(feat_can, rot, trans)


def canonicalize(feat_world: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Canonicalise a segment (..., T, 276) on its first frame. Returns (features, rot, trans)."""
    rot, trans = canonical_frame(feature_joints(feat_world[..., 0, :]))
    return to_canonical(feat_world, rot, trans), rot, trans


def world_points_to_canonical(points: torch.Tensor, rot: torch.Tensor, trans: torch.Tensor) -> torch.Tensor:
    """(..., N, 3) world points -> canonical frame (rot/trans broadcast over N)."""
    return (points - trans.unsqueeze(-2)) @ rot


class FeatureStats(torch.nn.Module):
    """Per-channel mean/std, computed once on the prior's training data and stored in the checkpoint."""

    def __init__(self, dim: int = FEATURE_DIM) -> None:
        super().__init__()
        self.register_buffer("mean", torch.zeros(dim))
        self.register_buffer("std", torch.ones(dim))

    @torch.no_grad()
    def fit(self, feats: torch.Tensor, min_std: float = 1e-2) -> None:
        """feats (N, D): set mean/std; tiny stds are floored so constant channels do not explode."""
        flat = feats.reshape(-1, feats.shape[-1]).double()
        self.mean.copy_(flat.mean(0).float())
        self.std.copy_(flat.std(0).clamp_min(min_std).float())

    def normalize(self, x: torch.Tensor) -> torch.Tensor:
        return (x - self.mean) / self.std

    def denormalize(self, x: torch.Tensor) -> torch.Tensor:
        return x * self.std + self.mean
