"""load_motion: a motion file -> 10 fps motion on the SMPL-X 22-joint skeleton (Z-up metres)."""
from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from ..errors import InputError
from ..skeleton import forward_kinematics, matrix_to_quat, quat_to_matrix
from .bone_maps import guess_bone_map, validate_bone_map
from .bvh import drop_first_frame, leading_rest_frame, read_bvh
from .retarget import mapped_positions, retarget

MODEL_FPS = 10.0


@dataclass
class Motion:
    joints: np.ndarray            # (T, 22, 3) float32 world Z-up metres
    local_rotations: np.ndarray   # (T, 22, 4) float32 w-first; [:, 0] = global orientation
    root: np.ndarray              # (T, 4, 4) float32 pelvis transforms
    fps: float
    caption: str | None = None
    source: str = ""
    fit_error_mm: dict | None = None

    @classmethod
    def from_pose(cls, local_rot: torch.Tensor, pelvis: torch.Tensor, fps: float, **kw) -> "Motion":
        joints, _ = forward_kinematics(local_rot, pelvis)
        root = torch.eye(4).repeat(local_rot.shape[0], 1, 1)
        root[:, :3, :3], root[:, :3, 3] = local_rot[:, 0], pelvis
        return cls(joints.numpy().astype(np.float32), matrix_to_quat(local_rot).numpy().astype(np.float32),
                   root.numpy().astype(np.float32), fps, **kw)


def resample_positions(x: np.ndarray, fps: float, target: float = MODEL_FPS) -> np.ndarray:
    """Linear resampling along axis 0 from fps to target fps (equal-interval sample times)."""
    n = x.shape[0]
    dur = (n - 1) / fps
    times = np.arange(0.0, dur + 1e-9, 1.0 / target)
    src = times * fps
    i0 = np.clip(np.floor(src).astype(int), 0, n - 1)
    i1 = np.clip(i0 + 1, 0, n - 1)
    w = (src - i0).reshape((-1,) + (1,) * (x.ndim - 1))
    return (1 - w) * x[i0] + w * x[i1]


def _units_to_metres(hip_height: float) -> float:
    """Guess the file's unit from the standing hip height: metres, centimetres, or ASF units / inches."""
    if 0.5 < hip_height < 1.5:
        return 1.0
    if 50 < hip_height < 150:
        return 0.01
    if 10 < hip_height < 30:       # CMU ASF units (1/0.45 inch) ~ 17.8 at the hip
        return 0.05644
    if 25 <= hip_height < 50:      # inches
        return 0.0254
    raise InputError(f"cannot tell the unit of a skeleton whose hips are {hip_height:.2f} units high; "
                     "pass a bone map and check the file")


AMC_DEFAULT_FPS = 120.0  # AMC files carry no frame rate; the CMU captures are 120 fps


def load_motion(path: str | Path, fps: float | None = None, bone_map: dict[str, str] | None = None,
                caption: str | None = None, asf: str | Path | None = None) -> Motion:
    """Read a .bvh, an Acclaim .amc (+ its .asf) or an AMASS-style .npz, retarget to the SMPL-X 22 joints
    and resample to 10 fps.

    fps overrides the file's frame rate (some headers are wrong, e.g. CMU amc2bvh files say 30 for 120).
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".bvh":
        return _load_bvh(path, fps, bone_map, caption)
    if suffix == ".amc":
        return _load_amc(path, Path(asf) if asf else _find_asf(path), fps, bone_map, caption)
    if suffix == ".npz":
        from .amass import load_amass
        return load_amass(path, fps, caption)
    raise InputError(f"{path.name}: unknown motion file type '{suffix}'; use .bvh, .amc (+ .asf) or an AMASS .npz")


def _find_asf(amc: Path) -> Path:
    """The skeleton beside an AMC file: '<subject>.asf' for '<subject>_<trial>.amc', else the only .asf."""
    subject = amc.parent / (amc.stem.split("_")[0] + ".asf")
    if subject.exists():
        return subject
    found = sorted(amc.parent.glob("*.asf"))
    if len(found) == 1:
        return found[0]
    raise InputError(f"no skeleton for {amc.name}: put its .asf beside it or pass load_motion(..., asf=PATH)")


def _load_amc(path: Path, asf: Path, fps: float | None, bone_map: dict | None, caption: str | None) -> Motion:
    from .asf_amc import asf_amc_positions, read_amc, read_asf
    skel = read_asf(asf)
    starts, ends, names = asf_amc_positions(skel, read_amc(path, skel))
    return _retarget_positions(path, starts, ends, names, fps or AMC_DEFAULT_FPS, bone_map, caption)


def _load_bvh(path: Path, fps: float | None, bone_map: dict | None, caption: str | None) -> Motion:
    m = read_bvh(path)
    if leading_rest_frame(m):
        warnings.warn(f"{path.name}: frame 0 is an added rest pose; dropped it", stacklevel=3)
        m = drop_first_frame(m)
    pos, ends = m.world_positions()
    return _retarget_positions(path, pos, ends, [j.name for j in m.joints], float(fps) if fps else m.fps,
                               bone_map, caption)


def _retarget_positions(path: Path, pos: np.ndarray, ends: np.ndarray, names: list[str], src_fps: float,
                        bone_map: dict | None, caption: str | None) -> Motion:
    """Source joint positions (Y-up, any unit) -> SMPL-X motion at 10 fps."""
    if bone_map is None:
        bone_map = guess_bone_map(names).mapping
    validate_bone_map(bone_map, names, rig=path.name)
    raw = mapped_positions(pos, ends, names, bone_map)
    hips = 0.5 * (raw[:, 1] + raw[:, 2])
    feet = raw[:, [7, 8, 10, 11]]
    unit = _units_to_metres(float(np.median(hips[:, 1] - feet[..., 1].min(axis=1))))
    targets = resample_positions(raw * unit, src_fps)
    if targets.shape[0] < 2:
        raise InputError(f"{path.name} is shorter than two frames at 10 fps")
    local, pelvis, err = retarget(targets, y_up=True)
    return Motion.from_pose(local, pelvis, MODEL_FPS, caption=caption, source=str(path), fit_error_mm=err)


def slerp_resample(local_rotations: np.ndarray, pelvis: np.ndarray, fps: float) -> tuple[torch.Tensor, torch.Tensor]:
    """Resample rotations (T,22,4 quats) by slerp and the pelvis by lerp to 10 fps."""
    from ..skeleton import quat_slerp
    n = local_rotations.shape[0]
    times = np.arange(0.0, (n - 1) / fps + 1e-9, 1.0 / MODEL_FPS) * fps
    i0 = np.clip(np.floor(times).astype(int), 0, n - 1)
    i1 = np.clip(i0 + 1, 0, n - 1)
    w = torch.as_tensor(times - i0, dtype=torch.float32)
    q = torch.as_tensor(local_rotations, dtype=torch.float32)
    rot = quat_to_matrix(quat_slerp(q[i0], q[i1], w.view(-1, 1, 1)))
    p = torch.as_tensor(pelvis, dtype=torch.float32)
    return rot, (1 - w.view(-1, 1)) * p[i0] + w.view(-1, 1) * p[i1]
