"""Retargeting any humanoid's joint positions onto the SMPL-X 22-joint skeleton.

Position-based IK: per frame, each joint's global rotation turns its rest bone(s) onto the source's
bone directions. Joints with several children (pelvis: hips + spine; spine3: neck + collars) use the
best rotation for all children at once (Kabsch); single-child joints use the smallest swing from their
parent's orientation; end joints (head, wrists, feet) keep their parent's. Bone lengths stay SMPL-X's,
so the fit error reported is what the proportions differ by, after scaling the source so its legs
are as long as SMPL-X's.
"""
from __future__ import annotations

import numpy as np
import torch

from ..errors import InputError
from ..skeleton import (FOOT_JOINTS, JOINT_INDEX, JOINT_NAMES, NUM_JOINTS, PARENTS, SOLE_BELOW_FOOT_JOINT,
                        axis_angle_to_matrix, forward_kinematics, global_to_local, rest_joints, rest_offsets)
from .bone_maps import normalise_name

# Y-up source -> Blender Z-up: x' = x, y' = -z, z' = y
Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
CHILDREN = {j: [c for c in range(NUM_JOINTS) if PARENTS[c] == j] for j in range(NUM_JOINTS)}


def mapped_positions(positions: np.ndarray, ends: np.ndarray | None, names: list[str],
                     mapping: dict[str, str]) -> np.ndarray:
    """Source joints (T, J, 3) -> the 22 SMPL-X joint targets (T, 22, 3) through a bone map."""
    index = {normalise_name(n): i for i, n in enumerate(names)}

    def col(bone: str) -> int:
        k = index.get(normalise_name(bone))
        if k is None:
            raise InputError(f"bone map names '{bone}', which the source skeleton does not have; fix the map")
        return k

    out = np.zeros(positions.shape[:1] + (NUM_JOINTS, 3))
    for j, name in enumerate(JOINT_NAMES):
        spec = mapping[name]
        if spec.startswith("lerp:"):
            _, a, b, t = spec.split(":")
            out[:, j] = (1 - float(t)) * positions[:, col(a)] + float(t) * positions[:, col(b)]
        elif spec.startswith("end:"):
            k = col(spec[4:])
            if ends is None or np.isnan(ends[:, k]).any():
                raise InputError(f"bone '{spec[4:]}' has no end site to use for {name}; map {name} to a bone")
            out[:, j] = ends[:, k]
        else:
            out[:, j] = positions[:, col(spec)]
    return out


def _rotation_between(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """Smallest rotation (..., 3, 3) taking unit vectors a onto b."""
    axis = torch.cross(a, b, dim=-1)
    s = axis.norm(dim=-1, keepdim=True)
    c = (a * b).sum(-1, keepdim=True)
    angle = torch.atan2(s, c)
    axis = axis / s.clamp_min(1e-9)
    # antiparallel: any perpendicular axis
    perp = torch.cross(a, torch.tensor([1.0, 0.0, 0.0], dtype=a.dtype).expand_as(a), dim=-1)
    perp = torch.where(perp.norm(dim=-1, keepdim=True) < 1e-6,
                       torch.cross(a, torch.tensor([0.0, 1.0, 0.0], dtype=a.dtype).expand_as(a), dim=-1), perp)
    axis = torch.where(s < 1e-9, torch.nn.functional.normalize(perp, dim=-1), axis)
    return axis_angle_to_matrix(axis * angle)


def _kabsch(rest: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Rotation R (T,3,3) minimising sum |R rest_i - target_i|^2; rest (K,3), target (T,K,3)."""
    h = rest.T.unsqueeze(0) @ target          # (T, 3, 3) = sum rest_i target_i^T
    u, _, vt = torch.linalg.svd(h)
    d = torch.sign(torch.det(vt.transpose(-1, -2) @ u.transpose(-1, -2)))
    fix = torch.diag_embed(torch.stack((torch.ones_like(d), torch.ones_like(d), d), -1))
    return vt.transpose(-1, -2) @ fix @ u.transpose(-1, -2)


def solve_rotations(targets: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """targets (T, 22, 3) Z-up metres at SMPL-X scale -> (local rotations (T,22,3,3), pelvis (T,3))."""
    off = rest_offsets(targets.dtype)
    t = targets.shape[0]
    glob = torch.zeros(t, NUM_JOINTS, 3, 3, dtype=targets.dtype)
    for j in range(NUM_JOINTS):  # parents come before children in SMPL-X order
        kids = CHILDREN[j]
        parent = glob[:, PARENTS[j]] if PARENTS[j] >= 0 else torch.eye(3, dtype=targets.dtype).expand(t, 3, 3)
        if len(kids) >= 2:
            dirs = torch.nn.functional.normalize(targets[:, kids] - targets[:, j:j + 1], dim=-1)
            glob[:, j] = _kabsch(off[kids], dirs * off[kids].norm(dim=-1, keepdim=True))
        elif len(kids) == 1:
            c = kids[0]
            cur = torch.nn.functional.normalize((parent @ off[c]).reshape(t, 3), dim=-1)
            want = torch.nn.functional.normalize(targets[:, c] - targets[:, j], dim=-1)
            glob[:, j] = _rotation_between(cur, want) @ parent
        else:
            glob[:, j] = parent
    local = global_to_local(glob)
    # place the pelvis so the SMPL-X hips sit where the source's hips are on average
    rest = rest_joints(targets.dtype)
    hip_mid_rest = 0.5 * (rest[JOINT_INDEX["left_hip"]] + rest[JOINT_INDEX["right_hip"]])
    hip_mid = 0.5 * (targets[:, JOINT_INDEX["left_hip"]] + targets[:, JOINT_INDEX["right_hip"]])
    pelvis = hip_mid - (glob[:, 0] @ hip_mid_rest)
    return local, pelvis


def leg_length(joints: np.ndarray) -> float:
    """Mean hip-knee-ankle length of both legs over a clip (T, 22, 3)."""
    total = 0.0
    for side in ("left", "right"):
        h, k, a = (JOINT_INDEX[f"{side}_{n}"] for n in ("hip", "knee", "ankle"))
        total += np.linalg.norm(joints[:, h] - joints[:, k], axis=-1).mean()
        total += np.linalg.norm(joints[:, k] - joints[:, a], axis=-1).mean()
    return total / 2


def retarget(targets_src: np.ndarray, y_up: bool = True) -> tuple[torch.Tensor, torch.Tensor, dict]:
    """Mapped source joints (T, 22, 3) in metres -> SMPL-X (local rotations, pelvis, fit error in mm)."""
    if not np.isfinite(targets_src).all():
        raise InputError("source joints contain NaN or inf; check the file's channels")
    pts = targets_src @ Y_UP_TO_Z_UP.T if y_up else targets_src.copy()
    scale = leg_length(rest_joints().numpy()[None]) / max(leg_length(pts), 1e-6)
    pts = pts * scale
    targets = torch.as_tensor(pts, dtype=torch.float32)
    local, pelvis = solve_rotations(targets)
    joints, _ = forward_kinematics(local, pelvis)
    # soles on the floor: the lowest foot joint of the clip at the sole offset
    floor = float(joints[:, list(FOOT_JOINTS), 2].min()) - SOLE_BELOW_FOOT_JOINT
    pelvis = pelvis - torch.tensor([0.0, 0.0, floor])
    def hip_mid(x: torch.Tensor) -> torch.Tensor:
        return 0.5 * (x[:, JOINT_INDEX["left_hip"]] + x[:, JOINT_INDEX["right_hip"]]).unsqueeze(1)

    # aligned at the hips (rigs disagree on where the pelvis joint sits, not on where the hips are)
    err = (joints - hip_mid(joints)) - (targets - hip_mid(targets))
    err_mm = err.norm(dim=-1) * 1000.0
    return local, pelvis, {"mean": float(err_mm.mean()), "max": float(err_mm.max()), "scale": float(scale)}
