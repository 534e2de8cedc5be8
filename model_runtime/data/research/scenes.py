"""Scene geometry of the research datasets: OBJ meshes and voxel grids on LINGO's fixed lattice."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ...errors import InputError
from ...voxel import OccupancyGrid

# LINGO's occupancy configuration in our Z-up frame (the paper's numbers).
LINGO_VOXEL = 0.02
LINGO_BOUNDS = ((-3.0, 3.0), (-4.0, 4.0), (0.0, 2.0))


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


def grid_in_bounds(vertices: np.ndarray, faces: np.ndarray, bounds=LINGO_BOUNDS, voxel: float = LINGO_VOXEL,
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
