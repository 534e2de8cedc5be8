"""load_motion: a motion file -> 10 fps motion on the SMPL-X 22-joint skeleton (Z-up metres).

Readers give the source skeleton's world joints at the file's rate; retargeting solves SMPL-X
rotations at that rate; resampling to 10 fps then lerps the pelvis, slerps the rotations and runs FK,
so the joints always agree with the rotations.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from ..errors import InputError
from ..skeleton import forward_kinematics, matrix_to_quat, quat_slerp, quat_to_matrix
from .bone_maps import guess_bone_map, validate_bone_map
from .retarget import mapped_positions, retarget

MODEL_FPS = 10.0
AMC_DEFAULT_FPS = 120.0  # AMC files carry no frame rate; the CMU captures are 120 fps


@dataclass
class Motion:
    joints: np.ndarray            # (T, 22, 3) float32 world Z-up metres
    local_rotations: np.ndarray   # (T, 22, 4) float32 w-first; [:, 0] = global orientation
    root: np.ndarray              # (T, 4, 4) float32 pelvis world transforms
    fps: float
    caption: str | None = None
    source: str = ""
    fit_error_mm: dict | None = None   # retargeting report: mean, max, legs_mean (mm), dir_deg, scale, unit, up

    @classmethod
    def from_pose(cls, local_rot: torch.Tensor, pelvis: torch.Tensor, fps: float, **kw) -> "Motion":
        """Local rotation matrices (T, 22, 3, 3) + pelvis (T, 3) -> Motion (joints by FK)."""
        local_rot, pelvis = local_rot.float(), pelvis.float()
        joints, _ = forward_kinematics(local_rot, pelvis)
        root = torch.eye(4).repeat(local_rot.shape[0], 1, 1)
        root[:, :3, :3], root[:, :3, 3] = local_rot[:, 0], pelvis
        return cls(joints.numpy().astype(np.float32), matrix_to_quat(local_rot).numpy().astype(np.float32),
                   root.numpy().astype(np.float32), fps, **kw)


def _sample_times(n: int, fps: float, target: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Source frame pairs and weights for equal steps of 1/target seconds over a clip of n frames."""
    if fps <= 0 or not np.isfinite(fps):
        raise InputError(f"frame rate {fps} is not a positive number; pass fps=...")
    # headers round the frame time (0.0333333): allow 0.1 ms so a 1.000 s clip keeps its last frame
    src = np.minimum(np.arange(0.0, (n - 1) / fps + 1e-4, 1.0 / target) * fps, n - 1)
    i0 = np.clip(np.floor(src).astype(int), 0, n - 1)
    i1 = np.clip(i0 + 1, 0, n - 1)
    return i0, i1, src - i0


def resample_positions(x: np.ndarray, fps: float, target: float = MODEL_FPS) -> np.ndarray:
    """Linear resampling along axis 0 from fps to target fps."""
    i0, i1, w = _sample_times(x.shape[0], fps, target)
    w = w.reshape((-1,) + (1,) * (x.ndim - 1))
    return (1 - w) * x[i0] + w * x[i1]


def slerp_resample(local_rotations: np.ndarray, pelvis: np.ndarray, fps: float,
                   target: float = MODEL_FPS) -> tuple[torch.Tensor, torch.Tensor]:
    """Quaternions (T, 22, 4) by slerp and the pelvis (T, 3) by lerp to the target rate;
    returns rotation matrices (N, 22, 3, 3) and pelvis (N, 3)."""
    i0, i1, w = _sample_times(len(pelvis), fps, target)
    w = torch.as_tensor(w, dtype=torch.float32)
    q = torch.as_tensor(np.asarray(local_rotations), dtype=torch.float32)
    rot = quat_to_matrix(quat_slerp(q[i0], q[i1], w.view(-1, 1, 1)))
    p = torch.as_tensor(np.asarray(pelvis), dtype=torch.float32)
    return rot, (1 - w.view(-1, 1)) * p[i0] + w.view(-1, 1) * p[i1]


def load_motion(path: str | Path, fps: float | None = None, bone_map: dict[str, str] | None = None, *,
                caption: str | None = None, asf: str | Path | None = None,
                index: str | Path | None = None) -> Motion:
    """Read a .bvh, an Acclaim .amc (+ its .asf) or an AMASS-style .npz; retarget to the SMPL-X 22
    joints and resample to 10 fps.

    fps: the true frame rate, overriding the file's (headers lie: CMU amc2bvh files say 30 for 120).
    bone_map: SMPL-X joint -> source bone (see bone_maps); guessed from the bone names when None.
    caption: used as given; else looked up from labels (Bandai JSON, HDM05 names, `index`).
    asf: the skeleton for an .amc (default: '<subject>.asf' or the only .asf beside it).
    index: a dataset index CSV (e.g. CMU's index.csv) giving the true frame rate and the caption.
    """
    from .captions import caption_for, index_row
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".bvh", ".amc", ".npz"):
        raise InputError(f"{path.name}: unknown motion file type '{suffix}'; use .bvh, .amc (+ .asf) or "
                         "an AMASS .npz")
    if not path.exists():
        raise InputError(f"motion file {path} does not exist; check the path")
    # only a row naming this very file may set the rate (other variants of a trial differ: CC is 60 fps)
    row = index_row(path, index, exact_only=True) if index is not None else None
    if fps is None and row:
        fps = float(row.get("fps_true") or row.get("fps") or 0) or None
    if fps is not None and not (np.isfinite(fps) and fps > 0):
        raise InputError(f"fps={fps} is not a positive frame rate")
    if caption is None:
        caption = caption_for(path, index)
    if suffix == ".bvh":
        return _load_bvh(path, fps, bone_map, caption)
    if suffix == ".amc":
        return _load_amc(path, Path(asf) if asf else _find_asf(path), fps, bone_map, caption)
    from .amass import load_amass
    return load_amass(path, fps, caption)


def _find_asf(amc: Path) -> Path:
    """The skeleton beside an AMC file: '<subject>.asf' for '<subject>_<trial>.amc', else the only .asf."""
    subject = amc.parent / (amc.stem.split("_")[0] + ".asf")
    if subject.exists():
        return subject
    found = sorted(amc.parent.glob("*.asf"))
    if len(found) == 1:
        return found[0]
    raise InputError(f"no skeleton for {amc.name}: put its .asf beside it or pass load_motion(..., asf=PATH)")


def _load_bvh(path: Path, fps: float | None, bone_map: dict | None, caption: str | None) -> Motion:
    from .bvh import read_bvh
    m = read_bvh(path)
    drop = m.rest_lead_in()
    if drop:
        warnings.warn(f"{path.name}: frame 0 is an added rest pose (rotations ~0, then a jump); dropped "
                      f"{drop} leading frame{'s' if drop > 1 else ''}", stacklevel=3)
        m = m.drop_frames(drop)
    if fps is None and m.looks_like_amc2bvh():
        warnings.warn(f"{path.name}: header says {m.fps:g} fps, but amc2bvh output is usually 120 fps; "
                      "pass fps=120 (or index=) if this is a CMU capture", stacklevel=3)
    pos, ends = m.world_positions()
    names = [j.name for j in m.joints]
    with_ends = [j.name for j in m.joints if j.end_site is not None]
    return _retarget_positions(path, pos, ends, names, with_ends, float(fps or m.fps), bone_map, caption)


def _load_amc(path: Path, asf: Path, fps: float | None, bone_map: dict | None, caption: str | None) -> Motion:
    from .asf_amc import asf_amc_positions, read_amc, read_asf
    skel = read_asf(asf)
    starts, ends, names = asf_amc_positions(skel, read_amc(path, skel))
    if fps is None:
        warnings.warn(f"{path.name}: AMC files carry no frame rate; assuming {AMC_DEFAULT_FPS:g} fps (CMU). "
                      "Pass fps=... for other sources", stacklevel=3)
    return _retarget_positions(path, starts, ends, names, names, float(fps or AMC_DEFAULT_FPS), bone_map,
                               caption, unit_hint=skel.metres_per_unit)


def _retarget_positions(path: Path, pos: np.ndarray, ends: np.ndarray, names: list[str], with_ends: list[str],
                        src_fps: float, bone_map: dict | None, caption: str | None,
                        unit_hint: float | None = None) -> Motion:
    """Source joint positions (any axes, any unit) -> SMPL-X motion at 10 fps."""
    src = mapped_source(pos, ends, names, with_ends, bone_map, path.name)
    return motion_from_source(src, src_fps, path, caption, unit_hint=unit_hint)


def mapped_source(pos: np.ndarray, ends: np.ndarray, names: list[str], with_ends: list[str],
                  bone_map: dict | None, rig: str) -> np.ndarray:
    """A rig's joint positions (T, J, 3) -> the 22 SMPL-X joint targets (T, 22, 3) through its bone map
    (guessed from the bone names when None)."""
    if bone_map is None:
        bone_map = guess_bone_map(names, end_sites=with_ends).mapping
    validate_bone_map(bone_map, names, rig=rig)
    return mapped_positions(pos, ends, names, bone_map)


def motion_from_source(src: np.ndarray, src_fps: float, path: Path, caption: str | None, **retarget_kw) -> Motion:
    """Mapped source joints (T, 22, 3) at src_fps -> SMPL-X motion at 10 fps (retarget_kw: see `retarget`)."""
    r = retarget(src, **retarget_kw)
    quats = matrix_to_quat(r.local_rot).numpy()
    rot, pelvis = slerp_resample(quats, r.pelvis.numpy(), src_fps)
    if rot.shape[0] < 2:
        raise InputError(f"{path.name} is shorter than two frames at 10 fps ({len(src)} frames at {src_fps:g} fps)")
    return Motion.from_pose(rot, pelvis, MODEL_FPS, caption=caption, source=str(path), fit_error_mm=r.fit_error_mm)
