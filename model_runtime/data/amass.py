"""AMASS-layout SMPL-X / SMPL-H .npz: poses (T, 165 | 156), trans (T, 3), mocap_frame_rate (or
mocap_framerate), optional betas and gender.

The first 66 pose values (global orientation + 21 body joints, axis-angle) drive our 22-joint
skeleton directly. AMASS worlds are Z-up while the body model's rest pose is Y-up; our rest skeleton
is that body turned Z-up by C (x' = x, y' = -z, z' = y), i.e. J' = C J. The body model places joint
j at R0 (J_j - J_p) + J_p + trans (it turns about the pelvis J_p), our FK at R0' (J'_j - J'_p) + pelvis.
Equal for every pose when
    R0' = R0 C^T,  R_j' = C R_j C^T (j >= 1),  pelvis = trans + J_p   (J_p in Y-up numbers),
because the C^T C pairs cancel along every chain. So AMASS's zero pose is the Y-up body as it is, lying
along +Y in the Z-up world; real AMASS clips stand it up with a root orientation of about +90 degrees
about X. Betas and gender are ignored (the ego uses betas = 0, as in the paper).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from ..errors import InputError
from ..skeleton import REST_JOINTS_ZUP, axis_angle_to_matrix, matrix_to_quat
from .motion import MODEL_FPS, Motion, slerp_resample

C = torch.tensor([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
# rest pelvis in SMPL-X's own Y-up frame (reference rest_yup[0]): invert the Z-up conversion
_PZ = REST_JOINTS_ZUP[0]
REST_PELVIS_YUP = torch.tensor([_PZ[0], _PZ[2], -_PZ[1]])
# SMPL-H's rest pelvis sits ~11 cm higher in its template (the root offset public AMASS loaders quote)
REST_PELVIS_YUP_SMPLH = torch.tensor([-0.00217366, -0.24078917, 0.02858375])


def amass_to_local(poses: torch.Tensor) -> torch.Tensor:
    """(T, >=66) axis-angle poses in AMASS's layout -> (T, 22, 3, 3) local rotations for our skeleton."""
    r = axis_angle_to_matrix(poses[:, :66].reshape(-1, 22, 3))
    local = C @ r @ C.T
    local[:, 0] = r[:, 0] @ C.T
    return local


def load_amass(path, fps: float | None = None, caption: str | None = None) -> Motion:
    """Read an AMASS-layout .npz (a path, or a file object with .name) -> Motion at 10 fps."""
    name = Path(getattr(path, "name", str(path))).name
    try:
        with np.load(path, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except (OSError, ValueError, EOFError) as exc:
        raise InputError(f"{name} is not a readable .npz ({exc}); expected the AMASS layout") from None
    for key in ("poses", "trans"):
        if key not in data:
            raise InputError(f"{name} has no '{key}' array; expected the AMASS layout (poses, trans, "
                             "mocap_frame_rate)")
    poses, trans = np.asarray(data["poses"], np.float32), np.asarray(data["trans"], np.float32)
    if poses.ndim != 2 or poses.shape[1] < 66 or trans.shape != (poses.shape[0], 3):
        raise InputError(f"{name}: poses must be (T, >=66) and trans (T, 3), got {poses.shape} and {trans.shape}")
    if not (np.isfinite(poses).all() and np.isfinite(trans).all()):
        raise InputError(f"{name}: poses or trans contain NaN or inf; fix or trim the file")
    rate = fps
    if rate is None:
        stored = data.get("mocap_frame_rate", data.get("mocap_framerate"))
        rate = float(np.asarray(stored).reshape(-1)[0]) if stored is not None else 0.0
    if not rate or rate <= 0:
        raise InputError(f"{name} has no mocap_frame_rate; pass fps=...")
    local = amass_to_local(torch.from_numpy(poses))
    rest_pelvis = REST_PELVIS_YUP_SMPLH if poses.shape[1] == 156 else REST_PELVIS_YUP
    pelvis = torch.from_numpy(trans) + rest_pelvis
    rot, pel = slerp_resample(matrix_to_quat(local).numpy(), pelvis.numpy(), rate)
    if rot.shape[0] < 1:
        raise InputError(f"{name} has no frames")
    return Motion.from_pose(rot, pel, MODEL_FPS, caption=caption, source=str(getattr(path, "name", path)))
