"""Loaders for the research datasets the paper trains on, in their published layouts.

A user who has HumanML3D (+ AMASS), Inter-X, LINGO or EgoBody on disk can turn each into our types:
`Motion` (10 fps, SMPL-X 22 joints, world Z-up metres, betas = 0 for the ego), partner joints (T, 22, 3)
in the same world frame, and `OccupancyGrid` scenes. Nothing here downloads anything; the tests run on
tiny synthetic fixtures written in the same layouts (no licensed data in the repository).

Every SMPL-X/H parameter set goes through `amass.load_amass` (the one place that maps the body model's
Y-up rest onto our Z-up skeleton and resamples to 10 fps by slerp); this module only moves parameters
into a Z-up world first (Inter-X and LINGO are Y-up, EgoBody is in Kinect camera coordinates) and cuts
clips. Body shape is never used: the ego has betas = 0 as in the paper, and so does the partner here (the
paper keeps the partner's betas, which needs the SMPL-X model this runtime does not ship). Moving a body
rigidly uses the betas = 0 rest pelvis as the rotation centre; for a real subject the centre differs by a
few centimetres, which shifts that body by at most that much.

`DATASETS` describes each layout, what was confirmed and from where, and what was assumed.
"""
from __future__ import annotations

import csv
import io
import json
import pickle
import warnings
import zipfile
from dataclasses import replace
from pathlib import Path
from typing import Iterable, Mapping

import numpy as np
import torch

from ..errors import InputError
from ..skeleton import SOLE_BELOW_FOOT_JOINT, axis_angle_to_matrix, matrix_to_axis_angle, quat_to_matrix
from ..voxel import OccupancyGrid
from .amass import REST_PELVIS_YUP, load_amass
from .motion import Motion

__all__ = ["DATASETS", "LINGO_BOUNDS", "LINGO_VOXEL", "load_humanml3d", "load_interx_pairs", "load_lingo",
           "load_egobody", "lingo_grid", "read_obj"]

DATASETS: dict[str, str] = {
    "humanml3d": """HumanML3D (texts + cut list) over AMASS SMPL+H G parameters.
    HumanML3D/                     root: the released dataset folder
        train.txt val.txt test.txt (also train_val.txt, all.txt): one clip id per line; ids 'M<id>' are
                                   the left/right mirror of '<id>' (loaded by mirroring, mirrored=True)
        texts/<id>.txt             (or texts.zip, read in place) one caption per line:
                                   'caption#word/POS word/POS ...#from#to'; from/to in seconds, 0#0 (or nan)
                                   = the whole clip, otherwise a sub-span cut at 20 fps (int(s * 20))
    index.csv                      in root or its parent (the HumanML3D repository root; or index_csv=):
                                   source_path,start_frame,end_frame,new_name, e.g.
                                   ./pose_data/CMU/80/80_63_poses.npy,516,716,000004.npy
    amass_root/<Dataset>/.../<name>_poses.npz   AMASS SMPL+H G: poses (T,156), trans, mocap_framerate
    Frames in index.csv count the 20 fps stream poses[::int(fps / 20)] after HumanML3D's per-dataset trims
    (Eyes_Japan_Dataset and MPI_HDM05 drop 3 s, TotalCapture and MPI_Limits 1 s, Transitions_mocap 0.5 s);
    the cut is mapped back to source frames and resampled from the true frame rate. humanact12 rows are not
    AMASS parameters and are skipped. Each clip is grounded (lowest joint of frame 0 on z = 0, sole offset
    included), as the paper does for HumanML3D.
    Confirmed: index.csv columns and rows, the trims, the stride, the text line format and the 20 fps span
    cut, M-prefixed ids in the split files (EricGuo5513/HumanML3D: index.csv, raw_pose_processing.py,
    legacy/HumanML3D/train.txt; t2m dataset loaders); AMASS folder renames (HDM05 -> MPI_HDM05, BMLrub ->
    BioMotionLab_NTroje, ...) from the same repository's README, used as fallbacks here.
    Assumed: SMPL-X N '_stageii.npz' files as a last fallback (HumanML3D was built from SMPL+H G).""",

    "interx": """Inter-X (two-person SMPL-X at 120 fps, Y-up world).
    Inter-X_Dataset/               root
        splits/train.txt val.txt test.txt all.txt   one id per line, GgggTtttAaaaRrrr
        motions/<id>/P1.npz, P2.npz (motions.zip unzipped) root_orient (T,3), pose_body (T,21,3) or
                                   (T,63), pose_lhand, pose_rhand, trans (T,3), betas (1,10), gender
        texts/<id>.txt             (texts.zip unzipped) several whole-interaction descriptions, one a line
        annots/interaction_order.pkl  actor/reactor order (not needed: both persons are used as ego)
    Each pair is returned twice (P1 as ego with P2 as partner, then the reverse: the paper's augmentation),
    with the first description as text unless role_texts gives role-specific ones (the paper writes those
    with an LLM). Y-up is turned Z-up by (x, y, z) -> (x, -z, y); each person is grounded on its frame 0.
    Confirmed: layout, keys, 120 fps, split files (liangxuy/Inter-X README and preprocess/1_prepare_data.py,
    which grounds on the y axis, i.e. Y-up; visualize/smplx_viewer_tool plays at 120 fps).
    Assumed: texts/<id>.txt is plain text without HumanML3D-style '#' fields (anything after '#' is cut).""",

    "lingo": """LINGO (SMPL-X motion in scanned rooms + occupancy grids, Y-up, in mirrored form).
    dataset/                       root
        human_orient.npy (N,3) global_orient, human_pose.npy (N,63) body_pose, transl_aligned.npy (N,3)
                                   transl: all motion segments concatenated, in the scene's frame
        start_idx.npy, end_idx.npy (M,) segment [start, end) frame indices (a 2-D array: column 0 is used)
        text_aug.pkl               (M,) texts; an entry may be a list of variants (the first is used)
        scene_name.pkl             (N,) scene name of every frame
        Scene/<scene>.npy          bool occupancy, Y-up index order [x, y(up), z]: (300, 100, 400) over
                                   x [-3, 3], y [0, 2], z [-4, 4] at 0.02 m; Scene_vis/ holds (400, 100, 600)
                                   grids over x [-4, 4], z [-6, 6] (scene_dir='Scene_vis')
    Grids become Z-up (x, -z, y): x [-3, 3], y [-4, 4], z [0, 2] at 0.02 m, 300 x 400 x 100 cells (the
    paper's numbers); motion stays in the scene's world coordinates (not grounded, not re-centred).
    Confirmed: file names and shapes (mileret/lingo-release readme.md), the grid bounds, index order and
    voxel lookup (code/datasets/lingo.py: scene_grid [-3, 0, -4, 3, 2, 4, 300, 100, 400], y-up joints).
    Not confirmed: the capture frame rate (30 fps assumed: the official loader samples windows of 48
    frames with step 3; pass fps= otherwise); whether start/end_idx are (M,) or (M, 3) (the readme says
    M x 3); the exact element type of text_aug.pkl entries. LINGO's own lookup treats points outside the
    grid as occupied; OccupancyGrid treats them as free.""",

    "egobody": """EgoBody (camera wearer + interactee SMPL-X at 30 fps in scanned scenes).
    egobody_release/               root
        data_info_release.csv      recording_name, body_idx_0, body_idx_1, body_idx_fpv ('<idx> <gender>' of
                                   the interactee; the camera wearer is the other index), start_frame,
                                   end_frame (inclusive), scene_name
        data_splits.csv            columns train, val, test listing recording names
        smplx_camera_wearer_<split>/<rec>/body_idx_<i>/results/frame_<%05d>/000.pkl
        smplx_interactee_<split>/<rec>/body_idx_<j>/results/frame_<%05d>/000.pkl
                                   per-frame dicts: global_orient (1,3), body_pose (1,63), transl (1,3),
                                   betas, hand poses, ... in the master Kinect colour camera frame
        calibrations/<rec>/cal_trans/kinect12_to_world/<scene>.json   {"trans": 4x4 camera -> scene}
                                   (calibrations/<rec>/kinect12_to_world/ also accepted)
        scene_mesh/<scene>/<scene>.obj   the scanned scene mesh
    The scene mesh is normalised as in the paper (bounding-box XY centre to (0, 0), lowest vertex to z = 0),
    the bodies get the same translation, and the mesh is voxelised with the LINGO configuration (Z-up
    x [-3, 3], y [-4, 4], z [0, 2] at 0.02 m). Each recording yields both roles as ego (paper), split into
    runs where both bodies have parameters. Frames are read at equal intervals (every 3rd at 30 fps).
    Confirmed: csv columns and their parsing, split dirs, per-frame pkl paths and keys, calibration path and
    direction, mesh path, inclusive frame range (sanweiliti/EgoBody release_renderer_kinect.py and
    release_vis_kinect_scene.py, README); 30 fps (the Kinect rate; third-party EgoBody loaders use 30).
    Not confirmed: that the scene mesh frame is Z-up (the paper's 'lowest Z' normalisation implies it);
    'XY centre' read as the bounding-box centre. The paper's texts come from Motion-X, not EgoBody: pass
    captions={recording_name: text} to attach them.""",
}

# LINGO's occupancy configuration in our Z-up frame (the paper's numbers).
LINGO_VOXEL = 0.02
LINGO_BOUNDS = ((-3.0, 3.0), (-4.0, 4.0), (0.0, 2.0))

HUMANML3D_FPS = 20.0
_HUMANML3D_TRIM_S = (("Eyes_Japan_Dataset", 3.0), ("MPI_HDM05", 3.0), ("TotalCapture", 1.0),
                     ("MPI_Limits", 1.0), ("Transitions_mocap", 0.5))
# HumanML3D's folder names (index.csv) -> names AMASS downloads unzip to today (HumanML3D README).
_AMASS_ALIASES = {"MPI_HDM05": "HDM05", "TCD_handMocap": "TCDHands", "MPI_mosh": "MoSh",
                  "Transitions_mocap": "Transitions", "MPI_Limits": "PosePrior", "SSM_synced": "SSM",
                  "DFaust_67": "DFaust", "BioMotionLab_NTroje": "BMLrub", "ACCAD": "ACCD"}

# Y-up world -> Z-up world: (x, y, z) -> (x, -z, y).
_YUP_TO_ZUP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
_J0 = REST_PELVIS_YUP.numpy().astype(np.float64)      # betas = 0 rest pelvis: SMPL-X rotates about it
_LEFT = (1, 4, 7, 10, 13, 16, 18, 20)
_RIGHT = (2, 5, 8, 11, 14, 17, 19, 21)
_MIRROR_PERM = list(range(22))
for _l, _r in zip(_LEFT, _RIGHT):
    _MIRROR_PERM[_l], _MIRROR_PERM[_r] = _r, _l
del _l, _r


# ====================================================================== shared helpers
class _NamedBuffer(io.BytesIO):
    """An in-memory .npz that load_amass can read like a path (it only uses .name in messages)."""

    def __init__(self, name: str) -> None:
        super().__init__()
        self.name = name

    def __str__(self) -> str:
        return self.name


def _params_to_motion(root_orient, body_pose, trans, fps: float, *, rotation: np.ndarray | None = None,
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


def _grounded(m: Motion) -> Motion:
    """Shift vertically so the lowest point of frame 0 (lowest joint less the sole) is on z = 0."""
    dz = float(m.joints[0, :, 2].min()) - SOLE_BELOW_FOOT_JOINT
    joints, root = m.joints.copy(), m.root.copy()
    joints[..., 2] -= dz
    root[:, 2, 3] -= dz
    return replace(m, joints=joints, root=root)


def _mirrored(m: Motion) -> Motion:
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


def _load_pickle(path: Path, what: str):
    try:
        with open(path, "rb") as fh:
            return _SafeUnpickler(fh).load()
    except FileNotFoundError:
        raise InputError(f"{path} not found; expected {what}") from None
    except Exception as exc:  # noqa: BLE001 - any unpickling failure is a bad file
        raise InputError(f"{path} is not a readable {what} ({exc})") from None


def _need_dir(path: Path, what: str) -> Path:
    if not path.is_dir():
        raise InputError(f"{path} is not a folder; expected {what}")
    return path


def _need_file(path: Path, what: str) -> Path:
    if not path.is_file():
        raise InputError(f"{path} not found; expected {what}")
    return path


def _read_lines(path: Path) -> list[str]:
    return [s.strip() for s in path.read_text(encoding="utf-8", errors="replace").splitlines() if s.strip()]


def _load_npy(path: Path, what: str, mmap: bool = False) -> np.ndarray:
    _need_file(path, what)
    try:
        return np.load(path, allow_pickle=False, mmap_mode="r" if mmap else None)
    except (OSError, ValueError) as exc:
        raise InputError(f"{path} is not a readable .npy ({exc}); expected {what}") from None


def _npz_arrays(path: Path, keys: Iterable[str], what: str) -> dict[str, np.ndarray]:
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


def read_obj(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """Plain-text Wavefront OBJ -> vertices (N, 3) float64, triangles (M, 3) int64 (polygons fanned)."""
    path = Path(path)
    verts: list[list[str]] = []
    faces: list[tuple[int, int, int]] = []
    try:
        with open(path, "r", encoding="utf-8", errors="replace") as fh:
            for line in fh:
                if line.startswith("v "):
                    verts.append(line.split()[1:4])
                elif line.startswith("f "):
                    n = len(verts)
                    idx = [int(tok.split("/")[0]) for tok in line.split()[1:]]
                    idx = [i - 1 if i > 0 else n + i for i in idx]
                    faces.extend((idx[0], idx[k], idx[k + 1]) for k in range(1, len(idx) - 1))
    except FileNotFoundError:
        raise InputError(f"{path} not found; expected a scene mesh (.obj)") from None
    except ValueError as exc:
        raise InputError(f"{path} is not a readable OBJ ({exc})") from None
    try:
        v = np.asarray(verts, dtype=np.float64).reshape(-1, 3)
    except ValueError as exc:
        raise InputError(f"{path}: a vertex line is not three numbers ({exc})") from None
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if len(f) == 0:
        raise InputError(f"{path} has no faces; expected a triangle mesh")
    if f.min() < 0 or f.max() >= len(v):
        raise InputError(f"{path}: a face refers to a vertex that does not exist")
    return v, f


def _grid_in_bounds(vertices: np.ndarray, faces: np.ndarray, bounds=LINGO_BOUNDS, voxel: float = LINGO_VOXEL,
                    fill_interior: bool = True) -> OccupancyGrid:
    """Voxelise triangles into the fixed grid `bounds` (cells aligned to its lower corner).

    OccupancyGrid.from_triangles puts its origin at the lowest vertex; a one-vertex anchor triangle on the
    target lattice, at least a cell below the mesh on every axis, makes that origin lattice-aligned. The
    anchor's own cell holds no geometry and is cleared. Faces wholly more than 1 m outside the bounds are
    dropped so huge scans stay within memory.
    """
    lo_b = np.array([b[0] for b in bounds], np.float64)
    hi_b = np.array([b[1] for b in bounds], np.float64)
    shape = tuple(int(round(x)) for x in (hi_b - lo_b) / voxel)
    occ = np.zeros(shape, dtype=bool)
    tri = vertices[faces]
    keep = np.all(tri.max(axis=1) >= lo_b - 1.0, axis=1) & np.all(tri.min(axis=1) <= hi_b + 1.0, axis=1)
    faces = faces[keep]
    if len(faces):
        used = vertices[np.unique(faces)]
        k = np.floor((used.min(axis=0) - lo_b) / voxel) - 1.0
        anchor = lo_b + k * voxel
        v = np.concatenate([vertices, anchor[None]])
        a = len(vertices)
        f = np.concatenate([faces, [[a, a, a]]])
        src = OccupancyGrid.from_triangles(v, f, voxel_size=voxel, padding=0.0, fill_interior=fill_interior)
        s = np.array(src.occupancy)                   # a writable copy
        s[0, 0, 0] = False                            # the anchor
        o = np.rint((src.origin - lo_b) / voxel).astype(int)
        f0 = np.maximum(o, 0)
        f1 = np.minimum(np.array(shape), o + np.array(s.shape))
        if np.all(f1 > f0):
            occ[f0[0]:f1[0], f0[1]:f1[1], f0[2]:f1[2]] = s[f0[0] - o[0]:f1[0] - o[0], f0[1] - o[1]:f1[1] - o[1],
                                                            f0[2] - o[2]:f1[2] - o[2]]
    return OccupancyGrid(lo_b, voxel, occ, num_triangles=int(len(faces)))


# ====================================================================== HumanML3D
def _humanml3d_texts(root: Path):
    """id -> list of text lines, from texts/ or texts.zip."""
    folder = root / "texts"
    if folder.is_dir():
        def get(cid: str) -> list[str] | None:
            p = folder / f"{cid}.txt"
            return _read_lines(p) if p.is_file() else None
        return get
    zpath = root / "texts.zip"
    if zpath.is_file():
        try:
            with zipfile.ZipFile(zpath) as zf:
                table = {Path(n).stem: [s.strip() for s in zf.read(n).decode("utf-8", "replace").splitlines()
                                        if s.strip()] for n in zf.namelist() if n.endswith(".txt")}
        except (OSError, zipfile.BadZipFile) as exc:
            raise InputError(f"{zpath} is not a readable zip ({exc}); expected HumanML3D's texts") from None
        return table.get
    raise InputError(f"{folder} not found; expected HumanML3D's texts/ folder (or texts.zip) with <id>.txt captions")


def _parse_humanml3d_line(line: str) -> tuple[str, float, float] | None:
    parts = line.split("#")
    caption = parts[0].strip()
    if not caption:
        return None
    try:
        f = float(parts[2]) if len(parts) > 2 else 0.0
        t = float(parts[3]) if len(parts) > 3 else 0.0
    except ValueError:
        f = t = 0.0
    return caption, (0.0 if np.isnan(f) else f), (0.0 if np.isnan(t) else t)


def _amass_candidates(amass_root: Path, source_path: str) -> list[Path]:
    rel = Path(source_path.replace("\\", "/"))
    parts = [p for p in rel.parts if p not in (".", "")]
    if parts and parts[0] == "pose_data":
        parts = parts[1:]
    if not parts:
        return []
    stem = Path(parts[-1]).stem
    base = [amass_root.joinpath(*parts[:-1], stem + ".npz")]
    if parts[0] in _AMASS_ALIASES:
        base.append(amass_root.joinpath(_AMASS_ALIASES[parts[0]], *parts[1:-1], stem + ".npz"))
    if stem.endswith("_poses"):
        base += [p.with_name(stem[:-len("_poses")] + "_stageii.npz") for p in list(base)]
    return base


def _amass_arrays(path: Path) -> tuple[np.ndarray, np.ndarray, float]:
    """poses, trans and frame rate of an AMASS .npz (other keys, e.g. a pickled gender, are not read)."""
    what = "an AMASS .npz (poses, trans, mocap_framerate)"
    d = _npz_arrays(path, ("poses", "trans"), what)
    with np.load(path, allow_pickle=False) as z:
        rate = next((float(z[k]) for k in ("mocap_framerate", "mocap_frame_rate") if k in z.files), 0.0)
    if rate <= 0:
        raise InputError(f"{path} has no mocap_framerate; expected {what}")
    if d["poses"].ndim != 2 or d["poses"].shape[1] < 66 or d["trans"].shape != (len(d["poses"]), 3):
        raise InputError(f"{path}: poses must be (T, >=66) and trans (T, 3), got {d['poses'].shape} and "
                         f"{d['trans'].shape}")
    return d["poses"], d["trans"], rate


def load_humanml3d(root: str | Path, amass_root: str | Path, split: str = "train", mirrored: bool = True,
                   index_csv: str | Path | None = None, all_captions: bool = False) -> list[Motion]:
    """HumanML3D clips of one official split, cut from AMASS and resampled to 10 fps.

    One Motion per clip and caption span: the whole clip with its first whole-clip caption, plus one per
    sub-span caption. all_captions=True returns one Motion per caption instead (they share arrays).
    Ids 'M<id>' are mirrored copies (skipped with mirrored=False). See DATASETS['humanml3d'].
    """
    root, amass_root = Path(root), Path(amass_root)
    _need_dir(root, "the HumanML3D dataset folder (texts/, train.txt, val.txt, test.txt)")
    _need_dir(amass_root, "the AMASS folder with <Dataset>/.../<name>_poses.npz (SMPL+H G) files")
    split_file = _need_file(root / f"{split}.txt", f"HumanML3D's split file {split}.txt (one clip id a line)")
    if index_csv is None:
        found = [p for p in (root / "index.csv", root.parent / "index.csv") if p.is_file()]
        if not found:
            raise InputError(f"index.csv not found in {root} or {root.parent}; copy it from the HumanML3D "
                             "repository or pass index_csv=")
        index_csv = found[0]
    index_csv = _need_file(Path(index_csv), "HumanML3D's index.csv (source_path,start_frame,end_frame,new_name)")
    index: dict[str, tuple[str, int, int]] = {}
    with open(index_csv, newline="", encoding="utf-8") as fh:
        reader = csv.DictReader(fh)
        need = {"source_path", "start_frame", "end_frame", "new_name"}
        if not need <= set(reader.fieldnames or ()):
            raise InputError(f"{index_csv} must have the columns source_path,start_frame,end_frame,new_name")
        for row in reader:
            index[Path(row["new_name"]).stem] = (row["source_path"], int(row["start_frame"]), int(row["end_frame"]))
    texts = _humanml3d_texts(root)

    cache: dict[Path, tuple[np.ndarray, np.ndarray, float]] = {}
    missing_files: list[str] = []
    skipped = {"humanact12": 0, "no text": 0, "not in index.csv": 0}
    out: list[Motion] = []
    for cid in _read_lines(split_file):
        is_mirror = cid.startswith("M")
        if is_mirror and not mirrored:
            continue
        base = cid[1:] if is_mirror else cid
        if base not in index:
            skipped["not in index.csv"] += 1
            continue
        source_path, start, end = index[base]
        if "humanact12" in source_path:
            skipped["humanact12"] += 1
            continue
        lines = texts(cid)
        if not lines:
            skipped["no text"] += 1
            continue
        cands = _amass_candidates(amass_root, source_path)
        path = next((p for p in cands if p.is_file()), None)
        if path is None:
            missing_files.append(str(cands[0]) if cands else source_path)
            continue
        if path not in cache:
            if len(cache) > 16:
                cache.clear()
            cache[path] = _amass_arrays(path)
        poses, trans, rate = cache[path]
        stride = max(int(rate / HUMANML3D_FPS), 1)
        n20 = (len(poses) + stride - 1) // stride
        trim = next((int(s * HUMANML3D_FPS) for key, s in _HUMANML3D_TRIM_S if key in source_path), 0)
        a = trim + start
        b = min(n20 + end if end < 0 else trim + end, n20)

        spans: dict[tuple[int, int], list[str]] = {}
        for line in lines:
            parsed = _parse_humanml3d_line(line)
            if parsed is None:
                continue
            caption, f, t = parsed
            key = (a, b) if (f == 0.0 and t == 0.0) else (a + int(f * HUMANML3D_FPS),
                                                           min(a + int(t * HUMANML3D_FPS), b))
            spans.setdefault(key, []).append(caption)
        for (s0, s1), captions in spans.items():
            if s1 - s0 < 2:
                continue
            src = slice(s0 * stride, (s1 - 1) * stride + 1)
            name = f"humanml3d:{cid}" + ("" if (s0, s1) == (a, b) else f"@{s0 - a}-{s1 - a}")
            m = _params_to_motion(poses[src, :3], poses[src, 3:66], trans[src], rate, source=name)
            if len(m.joints) < 2:
                continue
            m = _grounded(_mirrored(m) if is_mirror else m)
            for c in (captions if all_captions else captions[:1]):
                out.append(replace(m, caption=c))
    if missing_files and not out:
        raise InputError(f"none of the {len(missing_files)} AMASS files of split '{split}' were found, e.g. "
                         f"{missing_files[0]}; expected SMPL+H G npz files under {amass_root}")
    notes = [f"{v} {k}" for k, v in skipped.items() if v]
    if missing_files:
        notes.append(f"{len(missing_files)} missing AMASS files (e.g. {missing_files[0]})")
    if notes:
        warnings.warn(f"HumanML3D {split}: skipped " + ", ".join(notes), stacklevel=2)
    return out


# ====================================================================== Inter-X
INTERX_FPS = 120.0


def load_interx_pairs(root: str | Path, split: str = "train", fps: float = INTERX_FPS,
                      role_texts: Mapping[str, tuple[str, str]] | None = None
                      ) -> list[tuple[Motion, np.ndarray, str]]:
    """Inter-X pairs of one official split, each twice: (ego Motion, partner joints (T, 22, 3), text).

    The first tuple of a pair has P1 as ego, the second P2 (the paper's both-ego augmentation).
    role_texts maps an id to (text with P1 as ego, text with P2 as ego). See DATASETS['interx'].
    """
    root = Path(root)
    _need_dir(root, "the Inter-X dataset folder (motions/, texts/, splits/)")
    split_file = _need_file(root / "splits" / f"{split}.txt", f"Inter-X's split file splits/{split}.txt")
    motions = root / "motions"
    if not motions.is_dir():
        hint = " (unzip motions.zip there)" if (root / "motions.zip").is_file() else ""
        raise InputError(f"{motions} is not a folder; expected motions/<id>/P1.npz and P2.npz{hint}")
    texts = root / "texts"
    if not texts.is_dir() and role_texts is None:
        hint = " (unzip texts.zip there)" if (root / "texts.zip").is_file() else ""
        raise InputError(f"{texts} is not a folder; expected texts/<id>.txt descriptions{hint}")
    keys = ("root_orient", "pose_body", "trans")
    what = "an Inter-X SMPL-X .npz (root_orient, pose_body, trans)"
    out: list[tuple[Motion, np.ndarray, str]] = []
    for cid in _read_lines(split_file):
        folder = motions / cid
        people = []
        for p in ("P1", "P2"):
            d = _npz_arrays(_need_file(folder / f"{p}.npz", f"motions/{cid}/{p}.npz"), keys, what)
            people.append(d)
        n = min(len(people[0]["trans"]), len(people[1]["trans"]))
        if role_texts is not None and cid in role_texts:
            text1, text2 = role_texts[cid]
        else:
            tp = _need_file(texts / f"{cid}.txt", f"texts/{cid}.txt with the descriptions of {cid}")
            lines = [s.split("#")[0].strip() for s in _read_lines(tp)]
            text1 = text2 = next((s for s in lines if s), "")
        ms = []
        for p, d in zip(("P1", "P2"), people):
            m = _params_to_motion(d["root_orient"][:n], np.asarray(d["pose_body"]).reshape(len(d["pose_body"]), -1)[:n],
                                  d["trans"][:n], fps, rotation=_YUP_TO_ZUP, source=f"interx:{cid}:{p}")
            ms.append(_grounded(m))
        out.append((replace(ms[0], caption=text1), ms[1].joints.copy(), text1))
        out.append((replace(ms[1], caption=text2), ms[0].joints.copy(), text2))
    return out


# ====================================================================== LINGO
LINGO_FPS = 30.0   # not confirmed by a published source: see DATASETS['lingo']


def lingo_grid(occupancy_yup: np.ndarray, name: str = "scene") -> OccupancyGrid:
    """A LINGO Scene/*.npy array (Y-up index order [x, y(up), z], 0.02 m, centred in x and z, y from 0) ->
    an OccupancyGrid in our Z-up world: (x, y, z)_Z-up = (x, -z, y)_Y-up."""
    occ = np.asarray(occupancy_yup)
    if occ.ndim != 3:
        raise InputError(f"{name}: a LINGO scene must be a 3-D occupancy array [x, y(up), z], got shape {occ.shape}")
    nx, _, nz = occ.shape
    zup = np.ascontiguousarray(occ.astype(bool, copy=False).transpose(0, 2, 1)[:, ::-1, :])
    origin = (-nx * LINGO_VOXEL / 2, -nz * LINGO_VOXEL / 2, 0.0)
    return OccupancyGrid(origin, LINGO_VOXEL, zup)


def load_lingo(root: str | Path, scene_dir: str = "Scene", fps: float = LINGO_FPS,
               scenes: Iterable[str] | None = None) -> list[tuple[Motion, OccupancyGrid, str]]:
    """LINGO motion segments with their scene grid and text: (Motion in scene world coords, grid, text).

    Grids are shared between the segments of one scene (about 12 MB each). scenes= keeps only those scene
    names. LINGO has no released test motions; the paper splits 70/10/20 itself. See DATASETS['lingo'].
    """
    root = Path(root)
    _need_dir(root, "the LINGO dataset folder (human_pose.npy, human_orient.npy, transl_aligned.npy, Scene/)")
    orient = _load_npy(root / "human_orient.npy", "LINGO's (N, 3) global_orient array human_orient.npy", True)
    pose = _load_npy(root / "human_pose.npy", "LINGO's (N, 63) body_pose array human_pose.npy", True)
    transl = _load_npy(root / "transl_aligned.npy", "LINGO's (N, 3) transl array transl_aligned.npy", True)
    if not (len(orient) == len(pose) == len(transl)):
        raise InputError(f"{root}: human_orient, human_pose and transl_aligned have {len(orient)}, {len(pose)} "
                         f"and {len(transl)} frames; they must match")
    starts = _load_npy(root / "start_idx.npy", "LINGO's segment start frames start_idx.npy")
    ends = _load_npy(root / "end_idx.npy", "LINGO's segment end frames end_idx.npy")
    starts = starts.reshape(len(starts), -1)[:, 0].astype(np.int64)
    ends = ends.reshape(len(ends), -1)[:, 0].astype(np.int64)
    texts = list(_load_pickle(root / "text_aug.pkl", "LINGO's (M,) segment texts text_aug.pkl"))
    names = _load_pickle(root / "scene_name.pkl", "LINGO's (N,) per-frame scene names scene_name.pkl")
    if not (len(starts) == len(ends) == len(texts)):
        raise InputError(f"{root}: start_idx, end_idx and text_aug have {len(starts)}, {len(ends)} and "
                         f"{len(texts)} segments; they must match")
    folder = _need_dir(root / scene_dir, f"LINGO's {scene_dir}/ folder of <scene>.npy occupancy grids")
    wanted = None if scenes is None else {str(s) for s in scenes}
    grids: dict[str, OccupancyGrid] = {}
    out: list[tuple[Motion, OccupancyGrid, str]] = []
    for i, (s, e) in enumerate(zip(starts, ends)):
        s, e = int(s), int(min(e, len(transl)))
        if e - s < 2:
            continue
        scene = str(names[s])
        if wanted is not None and scene not in wanted:
            continue
        if scene not in grids:
            arr = _load_npy(folder / f"{scene}.npy", f"the occupancy grid of scene '{scene}'")
            grids[scene] = lingo_grid(arr, f"{scene_dir}/{scene}.npy")
        text = texts[i]
        if isinstance(text, (list, tuple, np.ndarray)):
            text = text[0] if len(text) else ""
        text = str(text)
        m = _params_to_motion(orient[s:e], pose[s:e], transl[s:e], fps, rotation=_YUP_TO_ZUP, caption=text,
                              source=f"lingo:{scene}:{i}")
        out.append((m, grids[scene], text))
    return out


# ====================================================================== EgoBody
EGOBODY_FPS = 30.0


def _egobody_split(root: Path, split: str) -> list[str]:
    path = _need_file(root / "data_splits.csv", "EgoBody's data_splits.csv (columns train, val, test)")
    with open(path, newline="", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    cols = ("train", "val", "test") if split == "all" else (split,)
    if rows and any(c not in rows[0] for c in cols):
        raise InputError(f"{path} has no '{split}' column; expected columns train, val, test")
    return [r[c].strip() for c in cols for r in rows if (r.get(c) or "").strip() not in ("", "nan", "NaN")]


def _egobody_frame(folder: Path, frame: int) -> dict | None:
    p = folder / "results" / f"frame_{frame:05d}" / "000.pkl"
    if not p.is_file():
        return None
    d = _load_pickle(p, "an EgoBody SMPL-X frame (global_orient, body_pose, transl)")
    if not isinstance(d, dict) or any(k not in d for k in ("global_orient", "body_pose", "transl")):
        raise InputError(f"{p} lacks global_orient, body_pose or transl; expected an EgoBody SMPL-X frame")
    return d


def load_egobody(root: str | Path, split: str = "train", both_ego: bool = True, fps: float = EGOBODY_FPS,
                 fill_interior: bool = True, captions: Mapping[str, str] | None = None
                 ) -> list[tuple[Motion, np.ndarray, OccupancyGrid]]:
    """EgoBody recordings of a split ('train', 'val', 'test' or 'all'): (ego Motion, partner joints
    (T, 22, 3), scene grid), camera wearer as ego first, then (both_ego) the interactee as ego.

    Scenes are normalised and voxelised as in the paper (see DATASETS['egobody']); grids are shared by
    recordings of one scene. captions maps recording names to texts (e.g. Motion-X's).
    """
    root = Path(root)
    _need_dir(root, "the EgoBody release folder (data_info_release.csv, smplx_*_<split>/, scene_mesh/)")
    info_path = _need_file(root / "data_info_release.csv", "EgoBody's data_info_release.csv")
    with open(info_path, newline="", encoding="utf-8") as fh:
        info = {r["recording_name"]: r for r in csv.DictReader(fh)}
    splits = ("train", "val", "test") if split == "all" else (split,)
    step = max(int(round(fps / 10.0)), 1)
    scene_cache: dict[str, tuple[OccupancyGrid, np.ndarray]] = {}
    out: list[tuple[Motion, np.ndarray, OccupancyGrid]] = []
    for rec in _egobody_split(root, split):
        if rec not in info:
            raise InputError(f"{rec} is in data_splits.csv but not in data_info_release.csv")
        row = info[rec]
        try:
            inter_idx = int(str(row["body_idx_fpv"]).split()[0])
            first, last = int(row["start_frame"]), int(row["end_frame"])
            scene = str(row["scene_name"]).strip()
        except (KeyError, ValueError, IndexError):
            raise InputError(f"{info_path}: row {rec} needs body_idx_fpv ('<idx> <gender>'), start_frame, "
                             "end_frame and scene_name") from None
        wearer_idx = 1 - inter_idx
        rec_split = next((s for s in splits if (root / f"smplx_camera_wearer_{s}" / rec).is_dir()), None)
        if rec_split is None:
            raise InputError(f"{root / f'smplx_camera_wearer_{splits[0]}' / rec} not found; expected the camera "
                             "wearer's per-frame SMPL-X fits of this recording")
        wearer_dir = root / f"smplx_camera_wearer_{rec_split}" / rec / f"body_idx_{wearer_idx}"
        inter_dir = _need_dir(root / f"smplx_interactee_{rec_split}" / rec / f"body_idx_{inter_idx}",
                              "the interactee's per-frame SMPL-X fits of this recording")
        _need_dir(wearer_dir, "the camera wearer's per-frame SMPL-X fits (body_idx_<i>/results/frame_<n>/000.pkl)")
        calib = next((p for p in (root / "calibrations" / rec / "cal_trans" / "kinect12_to_world" / f"{scene}.json",
                                  root / "calibrations" / rec / "kinect12_to_world" / f"{scene}.json") if p.is_file()),
                     None)
        if calib is None:
            raise InputError(f"{root / 'calibrations' / rec / 'cal_trans' / 'kinect12_to_world' / (scene + '.json')}"
                             " not found; expected the master Kinect -> scene transform {'trans': 4x4}")
        try:
            cam_to_world = np.asarray(json.loads(calib.read_text())["trans"], np.float64)
        except (KeyError, ValueError) as exc:
            raise InputError(f"{calib} is not a {{'trans': 4x4}} calibration ({exc})") from None
        if cam_to_world.shape != (4, 4):
            raise InputError(f"{calib}: 'trans' must be 4x4, got shape {cam_to_world.shape}")
        if scene not in scene_cache:
            mesh = root / "scene_mesh" / scene / f"{scene}.obj"
            v, f = read_obj(_need_file(mesh, f"the scene mesh scene_mesh/{scene}/{scene}.obj"))
            lo, hi = v[np.unique(f)].min(axis=0), v[np.unique(f)].max(axis=0)
            shift = np.array([-(lo[0] + hi[0]) / 2, -(lo[1] + hi[1]) / 2, -lo[2]])
            scene_cache[scene] = (_grid_in_bounds(v + shift, f, fill_interior=fill_interior), shift)
        grid, shift = scene_cache[scene]
        rot, off = cam_to_world[:3, :3], cam_to_world[:3, 3] + shift

        frames: list[tuple[int, dict, dict]] = []
        for fr in range(first, last + 1, step):
            a, b = _egobody_frame(wearer_dir, fr), _egobody_frame(inter_dir, fr)
            if a is not None and b is not None:
                frames.append((fr, a, b))
        runs: list[list[tuple[int, dict, dict]]] = []
        for item in frames:                         # split where a frame of either body is missing
            if runs and item[0] - runs[-1][-1][0] == step:
                runs[-1].append(item)
            else:
                runs.append([item])
        caption = None if captions is None else captions.get(rec)
        for r, run in enumerate(runs):
            if len(run) < 2:
                continue
            bodies = []
            for who, k in (("wearer", 1), ("interactee", 2)):
                def stack(key: str, k=k) -> np.ndarray:
                    return np.stack([np.asarray(item[k][key], np.float64).reshape(-1) for item in run])
                bodies.append(_params_to_motion(stack("global_orient"), stack("body_pose"), stack("transl"),
                                                fps / step, rotation=rot, offset=off, caption=caption,
                                                source=f"egobody:{rec}:{who}:{run[0][0]}"))
            wearer, interactee = bodies
            out.append((wearer, interactee.joints.copy(), grid))
            if both_ego:
                out.append((interactee, wearer.joints.copy(), grid))
    return out
