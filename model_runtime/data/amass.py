"""AMASS-layout SMPL-X / SMPL-H .npz: poses (T,165|156), trans (T,3), mocap_frame_rate.

AMASS worlds are Z-up while the body model's rest pose is Y-up. Our rest skeleton is the same body
converted with C (x' = x, y' = -z, z' = y), so rotations are conjugated: the global orientation becomes
R C^T and body joints C R_j C^T; the pelvis is trans + the Y-up rest pelvis (SMPL-X rotates about it).
Betas are ignored (the ego uses betas = 0, as in the paper).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from ..errors import InputError
from ..skeleton import REST_JOINTS_ZUP, axis_angle_to_matrix
from .motion import MODEL_FPS, Motion, slerp_resample
from ..skeleton import matrix_to_quat

C = torch.tensor([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
# rest pelvis in SMPL-X's own Y-up frame: invert the Z-up conversion of the constant
_PZ = REST_JOINTS_ZUP[0]
REST_PELVIS_YUP = torch.tensor([_PZ[0], _PZ[2], -_PZ[1]])


def load_amass(path: Path, fps: float | None = None, caption: str | None = None) -> Motion:
    try:
        with np.load(path, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except (OSError, ValueError) as exc:
        raise InputError(f"{path.name} is not a readable .npz ({exc})") from None
    for key in ("poses", "trans"):
        if key not in data:
            raise InputError(f"{path.name} has no '{key}' array; expected the AMASS layout (poses, trans, "
                             "mocap_frame_rate)")
    poses, trans = np.asarray(data["poses"], np.float32), np.asarray(data["trans"], np.float32)
    if poses.ndim != 2 or poses.shape[1] < 66 or trans.shape != (poses.shape[0], 3):
        raise InputError(f"{path.name}: poses must be (T, >=66) and trans (T, 3), got {poses.shape} and {trans.shape}")
    if not (np.isfinite(poses).all() and np.isfinite(trans).all()):
        raise InputError(f"{path.name}: poses or trans contain NaN or inf")
    rate = fps or float(data.get("mocap_frame_rate", data.get("mocap_framerate", 0)) or 0)
    if rate <= 0:
        raise InputError(f"{path.name} has no mocap_frame_rate; pass fps=...")
    r = axis_angle_to_matrix(torch.from_numpy(poses[:, :66]).reshape(-1, 22, 3))
    local = C @ r @ C.T
    local[:, 0] = r[:, 0] @ C.T
    pelvis = torch.from_numpy(trans) + REST_PELVIS_YUP
    rot, pel = slerp_resample(matrix_to_quat(local).numpy(), pelvis.numpy(), rate)
    return Motion.from_pose(rot, pel, MODEL_FPS, caption=caption, source=str(path))
