"""Walking distance to a floor goal around the obstacles of an OccupancyGrid, sampled differentiably.

The goal cost of test-time control asks each segment to get closer to its goal. Measured as a straight line,
"closer" points into a box or a wall standing between the ego and the goal: the scene cost pushes back and the
ego stops in front of the obstacle or squeezes through it. Measured as the walking distance around obstacles,
closer points around them and through doorways.

The field is the solution of the eikonal equation |grad u| = cost on a floor map (0.1 m cells) with u = 0 at
the goal: cost 1 on free floor, `blocked_cost` on floor within `clearance` of an obstacle between `band` heights
(so every cell has a finite value, an enclosed goal still has a field, and inside an obstacle the field still
points out). It is solved by vectorised Jacobi sweeps of the first-order upwind update, which, unlike a graph
search over 8 neighbours, has no preferred directions: a walk in the open heads straight at the goal.
Beyond the map, the distance to the map's edge is added, so the field is continuous everywhere. Written in
NumPy because the runtime does not depend on SciPy (Blender's Python does not ship it).
"""
from __future__ import annotations

import numpy as np
import torch

from .distance_field import _squared_distance_to

NAV_CELL = 0.1           # m: floor map resolution
NAV_CLEARANCE = 0.3      # m: floor this close to an obstacle is slow to cross (a body's half width and some room)
NAV_BAND = (0.05, 1.9)   # m: obstacles between these heights block walking (not a rug, not a high shelf)
NAV_MARGIN = 1.5         # m: free floor kept around the obstacles and the goal
BLOCKED_COST = 10.0      # walking-distance units per metre through blocked floor
MAX_SWEEPS = 2000        # a bound only: sweeps stop when nothing changes (about the map's diameter in cells)


def blocked_floor(grid, cell: float = NAV_CELL, clearance: float = NAV_CLEARANCE,
                  band: tuple[float, float] = NAV_BAND) -> tuple[np.ndarray, np.ndarray]:
    """(origin xy of the grid's floor footprint, (nx, ny) bool at `cell` resolution: floor within `clearance`
    of an obstacle between the `band` heights)."""
    occ = np.asarray(grid.occupancy, bool)
    vs = float(grid.voxel_size)
    z0 = float(grid.origin[2])
    k = np.arange(occ.shape[2])
    centres = z0 + (k + 0.5) * vs
    in_band = (centres >= band[0]) & (centres <= band[1])
    column = occ[:, :, in_band].any(-1) if in_band.any() else np.zeros(occ.shape[:2], bool)
    # inflate at the voxel resolution, then take the floor cells' centres
    radius = max(1, int(np.ceil(clearance / vs)))
    pad = radius
    padded = np.pad(column, pad)
    near = _squared_distance_to(padded[:, :, None], radius)[:, :, 0] * vs * vs <= clearance * clearance
    origin = np.asarray(grid.origin[:2], np.float64) - pad * vs
    size = np.asarray(near.shape, np.float64) * vs
    n = np.maximum(1, np.ceil(size / cell).astype(int))
    centres_x = origin[0] + (np.arange(n[0]) + 0.5) * cell
    centres_y = origin[1] + (np.arange(n[1]) + 0.5) * cell
    ix = np.clip(((centres_x - origin[0]) / vs).astype(int), 0, near.shape[0] - 1)
    iy = np.clip(((centres_y - origin[1]) / vs).astype(int), 0, near.shape[1] - 1)
    return origin, near[np.ix_(ix, iy)]


SEED_RADIUS = 3          # cells around the goal given their exact distance (the scheme is least exact near a point)


def solve_eikonal(cost: np.ndarray, source: tuple[float, float], cell: float) -> np.ndarray:
    """(nx, ny) travel cost per metre -> the least travel cost from each cell centre to `source`, a point in
    cell units (cell (i, j) has its centre at (i + 0.5, j + 0.5)). First-order upwind update, Jacobi sweeps
    until nothing changes; the cells within SEED_RADIUS of the source start from their exact cost."""
    i, j = np.meshgrid(np.arange(cost.shape[0]) + 0.5, np.arange(cost.shape[1]) + 0.5, indexing="ij")
    exact = np.hypot(i - source[0], j - source[1]) * cell * cost
    seeds = np.hypot(i - source[0], j - source[1]) <= SEED_RADIUS
    u = np.where(seeds, exact, np.inf)
    h = cost * cell
    for _ in range(MAX_SWEEPS):
        p = np.pad(u, 1, constant_values=np.inf)
        a = np.minimum(p[:-2, 1:-1], p[2:, 1:-1])
        b = np.minimum(p[1:-1, :-2], p[1:-1, 2:])
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        with np.errstate(invalid="ignore"):
            # both neighbours count when they are within one step of each other, else the nearer one alone
            both = (lo + hi + np.sqrt(np.maximum(2.0 * h * h - (hi - lo) ** 2, 0.0))) / 2.0
            new = np.where(hi - lo < h, both, lo + h)
        new = np.minimum(u, np.where(np.isfinite(new), new, np.inf))
        if np.array_equal(new, u):
            break
        u = new
    return u


class FloorMap:
    """Where one grid's obstacles block walking (`blocked_floor`): it depends on the grid alone, so it is built
    once per grid and shared by every goal and every ego."""

    def __init__(self, grid, cell: float = NAV_CELL, clearance: float = NAV_CLEARANCE) -> None:
        self.cell = float(cell)
        self.origin, self.blocked = blocked_floor(grid, cell, clearance)
        self.blocks = bool(self.blocked.any())  # False: nothing in the way, the straight line is the way


class NavigationField:
    """The walking distance to one floor goal around one floor map's obstacles, as a differentiable function of
    world floor points (..., 2) -> (...) metres (straight-line metres where nothing is in the way)."""

    def __init__(self, floor: FloorMap, goal_xy, blocked_cost: float = BLOCKED_COST,
                 margin: float = NAV_MARGIN) -> None:
        goal = np.asarray(goal_xy, np.float64)[:2]
        self.goal = goal
        self.floor = floor
        self.cell = cell = floor.cell
        grid_origin, blocked = floor.origin, floor.blocked
        lo = np.minimum(grid_origin, goal) - margin
        hi = np.maximum(grid_origin + np.asarray(blocked.shape) * cell, goal) + margin
        n = np.ceil((hi - lo) / cell).astype(int)
        self.origin = lo
        # the footprint's blocked cells placed into the larger map
        cost = np.ones(n)
        off = np.round((grid_origin - lo) / cell).astype(int)
        cost[off[0]:off[0] + blocked.shape[0], off[1]:off[1] + blocked.shape[1]][blocked] = blocked_cost
        u = solve_eikonal(cost, tuple((goal - lo) / cell), cell)
        self._u = u
        # each cell's unit direction of steepest descent, for walking along the field (waypoint) in a few us a step
        gx, gy = np.gradient(u, cell)
        norm = np.hypot(gx, gy)
        self._down = -np.stack((gx, gy), -1) / np.maximum(norm, 1e-9)[..., None]
        self._map = torch.from_numpy(u.astype(np.float32))[None, None]      # (1, 1, nx, ny)
        self._lo = torch.tensor(lo + 0.5 * cell, dtype=torch.float32)             # first cell centre
        self._hi = torch.tensor(lo + (n - 0.5) * cell, dtype=torch.float32)       # last cell centre

    @property
    def blocks(self) -> bool:
        """Whether anything stands in the way on its floor map (else the straight line is the way)."""
        return self.floor.blocks

    def __call__(self, xy: torch.Tensor) -> torch.Tensor:
        inside = torch.minimum(torch.maximum(xy, self._lo), self._hi)
        beyond = torch.linalg.vector_norm(xy - inside, dim=-1)
        # grid_sample reads (N, C, H, W) with points as (W, H): the map is [x, y], so the point is (y, x)
        unit = 2.0 * (inside - self._lo) / (self._hi - self._lo).clamp_min(1e-6) - 1.0
        flat = unit.flip(-1).reshape(1, -1, 1, 2)
        vals = torch.nn.functional.grid_sample(self._map, flat, mode="bilinear", padding_mode="border",
                                               align_corners=True)
        return vals.reshape(xy.shape[:-1]) + beyond

    def _sample(self, xy: np.ndarray) -> float:
        """The field at a world floor point, in NumPy (the same bilinear sampling as __call__)."""
        c = (np.asarray(xy, np.float64) - self.origin) / self.cell - 0.5          # cell-centre index units
        n = np.asarray(self._u.shape)
        inside = np.clip(c, 0.0, n - 1.0)
        beyond = float(np.hypot(*(c - inside))) * self.cell
        i0 = np.minimum(np.floor(inside).astype(int), n - 2).clip(0)
        t = inside - i0
        u = self._u
        i1 = np.minimum(i0 + 1, n - 1)
        v = ((1 - t[0]) * (1 - t[1]) * u[i0[0], i0[1]] + t[0] * (1 - t[1]) * u[i1[0], i0[1]]
             + (1 - t[0]) * t[1] * u[i0[0], i1[1]] + t[0] * t[1] * u[i1[0], i1[1]])
        return float(v) + beyond

    def heading(self, xy: np.ndarray) -> np.ndarray:
        """The unit floor direction (2,) of steepest walking-distance descent at world point xy (2,)."""
        p = np.asarray(xy, np.float64)[:2]
        e = self.cell * 0.5
        g = np.array([self._sample(p + (e, 0.0)) - self._sample(p - (e, 0.0)),
                      self._sample(p + (0.0, e)) - self._sample(p - (0.0, e))])
        n = float(np.hypot(g[0], g[1]))
        if n < 1e-9:
            d = self.goal - p
            n = float(np.hypot(d[0], d[1]))
            return d / n if n > 1e-9 else np.zeros(2)
        return -g / n

    def waypoint(self, xy: np.ndarray, distance: float) -> np.ndarray:
        """The world floor point (2,) reached by walking `distance` metres down the field from xy (2,), or the
        goal if it is nearer: where to face while walking there."""
        p = np.asarray(xy, np.float64)[:2].copy()
        step = self.cell
        n = self._u.shape
        for _ in range(max(1, int(np.ceil(distance / step)))):
            if float(np.hypot(*(self.goal - p))) <= step:
                return self.goal.copy()
            i, j = ((p - self.origin) / step).astype(int)
            inside = 0 <= i < n[0] and 0 <= j < n[1]
            p = p + step * (self._down[i, j] if inside else self.heading(p))
        return p
