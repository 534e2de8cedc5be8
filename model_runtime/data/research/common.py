"""What every research-dataset loader shares: SMPL-X/H parameters -> Motion (moved rigidly into a Z-up world
first), grounding and mirroring, and careful readers for the files datasets ship (pickles without code, .npy,
.npz, text lines) whose errors name the file and what was expected."""
from __future__ import annotations

import io
import pickle
import zipfile
from dataclasses import replace
from pathlib import Path
from typing import Iterable

import numpy as np
import torch

from ...errors import InputError
from ...skeleton import SOLE_BELOW_FOOT_JOINT, axis_angle_to_matrix, matrix_to_axis_angle, quat_to_matrix
from ..amass import REST_PELVIS_YUP, load_amass
from ..motion import Motion

# Y-up world -> Z-up world: (x, y, z) -> (x, -z, y).
YUP_TO_ZUP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
_J0 = REST_PELVIS_YUP.numpy().astype(np.float64)      # betas = 0 rest pelvis: SMPL-X rotates about it
_LEFT = (1, 4, 7, 10, 13, 16, 18, 20)
_RIGHT = (2, 5, 8, 11, 14, 17, 19, 21)
_MIRROR_PERM = list(range(22))
for _l, _r in zip(_LEFT, _RIGHT):
    _MIRROR_PERM[_l], _MIRROR_PERM[_r] = _r, _l
del _l, _r


class _NamedBuffer(io.BytesIO):
    """An in-memory .npz that load_amass can read like a path (it only uses .name in messages)."""

    def __init__(self, name: str) -> None:
        super().__init__()
        self.name = name

    def __str__(self) -> str:
        return self.name


def params_to_motion(root_orient, body_pose, trans, fps: float, *, rotation: np.ndarray | None = None,
                      offset: np.ndarray | None = None, caption: str | None = None, source: str = "") -> Motion:
    """SMPL-X/H parameters -> Motion, after moving the body rigidly by world x -> rotation @ x + offset.

    root_orient (T, 3), body_pose (T, 63) (or (T, 21, 3)), trans (T, 3) in a Z-up world once moved.
    """
    tr = np.asarray(trans, np.float64).reshape(-1, 3)
    n = len(tr)
    ro = np.asarray(root_orient, np.float64).reshape(n, 3)
    bp = np.asarray(body_pose, np.float64).reshape(n, -1)
    if bp.shape[1] < 63:
        raise InputError(f"{source}: body pose has {bp.shape[1]} values per frame, expected 63 (21 joints x 3)")
    if rotation is not None or offset is not None:
        rot = np.eye(3) if rotation is None else np.asarray(rotation, np.float64)
        off = np.zeros(3) if offset is None else np.asarray(offset, np.float64)
        g = axis_angle_to_matrix(torch.from_numpy(ro)).numpy()
        ro = matrix_to_axis_angle(torch.from_numpy(rot @ g)).numpy()
        tr = (tr + _J0) @ rot.T + off - _J0
    buf = _NamedBuffer(source or "parameters")
    np.savez(buf, poses=np.concatenate([ro, bp[:, :63]], axis=1).astype(np.float32),
             trans=tr.astype(np.float32), mocap_frame_rate=np.float64(fps))
    buf.seek(0)
    m = load_amass(buf, None, caption)
    m.source = source
    return m


def grounded(m: Motion) -> Motion:
    """Shift vertically so the lowest point of frame 0 (lowest joint less the sole) is on z = 0."""
    dz = float(m.joints[0, :, 2].min()) - SOLE_BELOW_FOOT_JOINT
    joints, root = m.joints.copy(), m.root.copy()
    joints[..., 2] -= dz
    root[:, 2, 3] -= dz
    return replace(m, joints=joints, root=root)


def mirror_left_right(m: Motion) -> Motion:
    """Left/right mirror x -> -x with the left and right joints swapped (HumanML3D's 'M' clips)."""
    rot = quat_to_matrix(torch.from_numpy(m.local_rotations))[:, _MIRROR_PERM]
    flip = torch.diag(torch.tensor([-1.0, 1.0, 1.0]))
    pelvis = torch.from_numpy(m.root[:, :3, 3].copy()) * torch.tensor([-1.0, 1.0, 1.0])
    return Motion.from_pose(flip @ rot @ flip, pelvis, m.fps, caption=m.caption, source=m.source)


class _SafeUnpickler(pickle.Unpickler):
    """Datasets ship .pkl files; allow only plain containers and NumPy arrays, never arbitrary code."""

    _ALLOWED = {("numpy", "ndarray"), ("numpy", "dtype"), ("collections", "OrderedDict"), ("_codecs", "encode"),
                ("numpy.core.multiarray", "_reconstruct"), ("numpy._core.multiarray", "_reconstruct"),
                ("numpy.core.multiarray", "scalar"), ("numpy._core.multiarray", "scalar"),
                ("numpy.core.numeric", "_frombuffer"), ("numpy._core.numeric", "_frombuffer")}

    def find_class(self, module: str, name: str):
        if (module, name) in self._ALLOWED:
            return super().find_class(module, name)
        raise pickle.UnpicklingError(f"refusing to load {module}.{name}")


def load_pickle(path: Path, what: str):
    try:
        with open(path, "rb") as fh:
            return _SafeUnpickler(fh).load()
    except FileNotFoundError:
        raise InputError(f"{path} not found; expected {what}") from None
    except Exception as exc:  # noqa: BLE001 - any unpickling failure is a bad file
        raise InputError(f"{path} is not a readable {what} ({exc})") from None


def need_dir(path: Path, what: str) -> Path:
    if not path.is_dir():
        raise InputError(f"{path} is not a folder; expected {what}")
    return path


def need_file(path: Path, what: str) -> Path:
    if not path.is_file():
        raise InputError(f"{path} not found; expected {what}")
    return path


def read_lines(path: Path) -> list[str]:
    return [s.strip() for s in path.read_text(encoding="utf-8", errors="replace").splitlines() if s.strip()]


def load_npy(path: Path, what: str, mmap: bool = False) -> np.ndarray:
    need_file(path, what)
    try:
        return np.load(path, allow_pickle=False, mmap_mode="r" if mmap else None)
    except (OSError, ValueError) as exc:
        raise InputError(f"{path} is not a readable .npy ({exc}); expected {what}") from None


def npz_arrays(path: Path, keys: Iterable[str], what: str) -> dict[str, np.ndarray]:
    """Read only the named arrays (datasets also store object arrays such as gender that need pickle)."""
    try:
        with np.load(path, allow_pickle=False) as z:
            missing = [k for k in keys if k not in z.files]
            if missing:
                raise InputError(f"{path} has no {', '.join(missing)}; expected {what}")
            return {k: np.asarray(z[k]) for k in keys}
    except FileNotFoundError:
        raise InputError(f"{path} not found; expected {what}") from None
    except (OSError, ValueError, zipfile.BadZipFile) as exc:
        raise InputError(f"{path} is not a readable .npz ({exc}); expected {what}") from None
