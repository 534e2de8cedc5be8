"""EgoBody: camera wearer and interactee SMPL-X fits in scanned scenes, either as ego (see LAYOUT)."""
from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Mapping

import numpy as np

from ...errors import InputError
from ...voxel import OccupancyGrid
from ..motion import Motion
from .common import load_pickle, need_dir, need_file, params_to_motion
from .scenes import grid_in_bounds, read_obj

LAYOUT = """EgoBody (camera wearer + interactee SMPL-X at 30 fps in scanned scenes).
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
    captions={recording_name: text} to attach them."""

EGOBODY_FPS = 30.0


def _egobody_split(root: Path, split: str) -> list[str]:
    path = need_file(root / "data_splits.csv", "EgoBody's data_splits.csv (columns train, val, test)")
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
    d = load_pickle(p, "an EgoBody SMPL-X frame (global_orient, body_pose, transl)")
    if not isinstance(d, dict) or any(k not in d for k in ("global_orient", "body_pose", "transl")):
        raise InputError(f"{p} lacks global_orient, body_pose or transl; expected an EgoBody SMPL-X frame")
    return d


def load_egobody(root: str | Path, split: str = "train", both_ego: bool = True, fps: float = EGOBODY_FPS,
                 fill_interior: bool = True, captions: Mapping[str, str] | None = None
                 ) -> list[tuple[Motion, np.ndarray, OccupancyGrid]]:
    """EgoBody recordings of a split ('train', 'val', 'test' or 'all'): (ego Motion, partner joints
    (T, 22, 3), scene grid), camera wearer as ego first, then (both_ego) the interactee as ego.

    Scenes are normalised and voxelised as in the paper (see LAYOUT); grids are shared by
    recordings of one scene. captions maps recording names to texts (e.g. Motion-X's).
    """
    root = Path(root)
    need_dir(root, "the EgoBody release folder (data_info_release.csv, smplx_*_<split>/, scene_mesh/)")
    info_path = need_file(root / "data_info_release.csv", "EgoBody's data_info_release.csv")
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
        inter_dir = need_dir(root / f"smplx_interactee_{rec_split}" / rec / f"body_idx_{inter_idx}",
                              "the interactee's per-frame SMPL-X fits of this recording")
        need_dir(wearer_dir, "the camera wearer's per-frame SMPL-X fits (body_idx_<i>/results/frame_<n>/000.pkl)")
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
            v, f = read_obj(need_file(mesh, f"the scene mesh scene_mesh/{scene}/{scene}.obj"))
            lo, hi = v[np.unique(f)].min(axis=0), v[np.unique(f)].max(axis=0)
            shift = np.array([-(lo[0] + hi[0]) / 2, -(lo[1] + hi[1]) / 2, -lo[2]])
            scene_cache[scene] = (grid_in_bounds(v + shift, f, fill_interior=fill_interior), shift)
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
                bodies.append(params_to_motion(stack("global_orient"), stack("body_pose"), stack("transl"),
                                                fps / step, rotation=rot, offset=off, caption=caption,
                                                source=f"egobody:{rec}:{who}:{run[0][0]}"))
            wearer, interactee = bodies
            out.append((wearer, interactee.joints.copy(), grid))
            if both_ego:
                out.append((interactee, wearer.joints.copy(), grid))
    return out
