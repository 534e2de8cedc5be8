"""Signed distance to the obstacles of an OccupancyGrid, built once per grid, sampled differentiably.

Test-time control needs how far a joint is from the nearest obstacle, and which way is out, as a smooth
function it can take gradients of. An occupancy grid gives neither; its distance field does: positive outside
(metres to the nearest occupied cell centre), negative inside (metres to the nearest free cell centre),
sampled trilinearly with torch's grid_sample so gradients flow to the query points.

The transform is the separable squared-distance form (one 1-D pass per axis, each a minimum over shifts),
exact up to `reach` metres and clamped beyond: the costs only look a few decimetres out. It is written here
in NumPy because the runtime does not depend on SciPy (Blender's Python does not ship it); its
`distance_transform_edt` agrees within float error (tests/test_control.py checks it).
"""
from __future__ import annotations

import numpy as np
import torch

DEFAULT_REACH = 0.5   # m: distances beyond this are clamped (the costs' margins are well inside it)


def _squared_distance_to(mask: np.ndarray, radius: int) -> np.ndarray:
    """Squared distance in cells from every cell to the nearest True cell, exact up to `radius` cells."""
    big = float((radius + 1) ** 2 * 3)
    d = np.where(mask, 0.0, big).astype(np.float32)
    for axis in range(3):
        n = d.shape[axis]
        best = d.copy()
        for s in range(1, min(radius, n - 1) + 1):
            shifted_fwd = np.full_like(d, big)
            shifted_bwd = np.full_like(d, big)
            src = [slice(None)] * 3
            dst = [slice(None)] * 3
            src[axis], dst[axis] = slice(0, n - s), slice(s, n)
            shifted_fwd[tuple(dst)] = d[tuple(src)]
            shifted_bwd[tuple(src)] = d[tuple(dst)]
            np.minimum(best, shifted_fwd + s * s, out=best)
            np.minimum(best, shifted_bwd + s * s, out=best)
        d = best
    return np.minimum(d, big)


def signed_distance(occupancy: np.ndarray, voxel_size: float, reach: float = DEFAULT_REACH) -> np.ndarray:
    """(nx, ny, nz) bool -> float32 signed distance in metres at cell centres, clamped to +-reach."""
    occ = np.asarray(occupancy, bool)
    radius = max(1, int(np.ceil(reach / voxel_size)))
    outside = np.sqrt(_squared_distance_to(occ, radius)) * voxel_size
    inside = np.sqrt(_squared_distance_to(~occ, radius)) * voxel_size
    return np.clip(np.where(occ, -inside, outside), -reach, reach).astype(np.float32)


class DistanceField:
    """The signed distance field of one OccupancyGrid, as a differentiable function of world points."""

    def __init__(self, grid, reach: float = DEFAULT_REACH) -> None:
        self.reach = float(reach)
        self.voxel_size = float(grid.voxel_size)
        # a free border `reach` wide: beyond the padded grid every point really is at least `reach` away
        border = int(np.ceil(self.reach / self.voxel_size))
        occ = np.pad(np.asarray(grid.occupancy, bool), border)
        self.origin = torch.as_tensor(np.asarray(grid.origin, np.float32) - border * self.voxel_size)
        self.empty = not occ.any()
        sdf = np.full(occ.shape, self.reach, np.float32) if self.empty else signed_distance(occ, grid.voxel_size,
                                                                                             reach)
        # grid_sample reads (N, C, D, H, W) and takes points as (W, H, D): store [x, y, z] and flip the points
        self._volume = torch.from_numpy(sdf)[None, None]
        self._volume_np, self._origin_np = sdf, np.asarray(self.origin, np.float64)   # control_grad.py reads these
        self._size = torch.tensor(occ.shape[::-1], dtype=torch.float32)

    def __call__(self, points: torch.Tensor) -> torch.Tensor:
        """(..., 3) world points -> (...) signed distance in metres (the clamp value far from the grid)."""
        if self.empty:
            return torch.full(points.shape[:-1], self.reach, dtype=points.dtype)
        centre_index = (points - self.origin) / self.voxel_size - 0.5     # cell centres at integer indices
        xyz_to_whd = centre_index.flip(-1)
        unit = 2.0 * xyz_to_whd / (self._size - 1.0).clamp_min(1.0) - 1.0
        flat = unit.reshape(1, -1, 1, 1, 3)
        vals = torch.nn.functional.grid_sample(self._volume, flat, mode="bilinear", padding_mode="border",
                                               align_corners=True).reshape(points.shape[:-1])
        # beyond the grid there is nothing: far, with no gradient along the grid's outer faces
        inside = ((unit > -1.0) & (unit < 1.0)).all(-1)
        return torch.where(inside, vals, torch.full_like(vals, self.reach))
