"""LINGO: SMPL-X motion segments in scanned rooms with their occupancy grids (see LAYOUT)."""
from __future__ import annotations

from pathlib import Path
from typing import Iterable

import numpy as np

from ...errors import InputError
from ...voxel import OccupancyGrid
from ..motion import Motion
from .common import YUP_TO_ZUP, load_npy, load_pickle, need_dir, params_to_motion
from .scenes import LINGO_VOXEL

LAYOUT = """LINGO (SMPL-X motion in scanned rooms + occupancy grids, Y-up, in mirrored form).
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
    grid as occupied; OccupancyGrid treats them as free."""

LINGO_FPS = 30.0   # not confirmed by a published source: see LAYOUT


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
    names. LINGO has no released test motions; the paper splits 70/10/20 itself. See LAYOUT.
    """
    root = Path(root)
    need_dir(root, "the LINGO dataset folder (human_pose.npy, human_orient.npy, transl_aligned.npy, Scene/)")
    orient = load_npy(root / "human_orient.npy", "LINGO's (N, 3) global_orient array human_orient.npy", True)
    pose = load_npy(root / "human_pose.npy", "LINGO's (N, 63) body_pose array human_pose.npy", True)
    transl = load_npy(root / "transl_aligned.npy", "LINGO's (N, 3) transl array transl_aligned.npy", True)
    if not (len(orient) == len(pose) == len(transl)):
        raise InputError(f"{root}: human_orient, human_pose and transl_aligned have {len(orient)}, {len(pose)} "
                         f"and {len(transl)} frames; they must match")
    starts = load_npy(root / "start_idx.npy", "LINGO's segment start frames start_idx.npy")
    ends = load_npy(root / "end_idx.npy", "LINGO's segment end frames end_idx.npy")
    starts = starts.reshape(len(starts), -1)[:, 0].astype(np.int64)
    ends = ends.reshape(len(ends), -1)[:, 0].astype(np.int64)
    texts = list(load_pickle(root / "text_aug.pkl", "LINGO's (M,) segment texts text_aug.pkl"))
    names = load_pickle(root / "scene_name.pkl", "LINGO's (N,) per-frame scene names scene_name.pkl")
    if not (len(starts) == len(ends) == len(texts)):
        raise InputError(f"{root}: start_idx, end_idx and text_aug have {len(starts)}, {len(ends)} and "
                         f"{len(texts)} segments; they must match")
    folder = need_dir(root / scene_dir, f"LINGO's {scene_dir}/ folder of <scene>.npy occupancy grids")
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
            arr = load_npy(folder / f"{scene}.npy", f"the occupancy grid of scene '{scene}'")
            grids[scene] = lingo_grid(arr, f"{scene_dir}/{scene}.npy")
        text = texts[i]
        if isinstance(text, (list, tuple, np.ndarray)):
            text = text[0] if len(text) else ""
        text = str(text)
        m = params_to_motion(orient[s:e], pose[s:e], transl[s:e], fps, rotation=YUP_TO_ZUP, caption=text,
                              source=f"lingo:{scene}:{i}")
        out.append((m, grids[scene], text))
    return out
