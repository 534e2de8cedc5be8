"""HSI scenes (stand-in for LINGO), `build_hsi_scenes`: a real ego clip among procedural obstacles (boxes,
walls, tables, low steps) with a goal from its own path (goals.hsi_goal), one of five rules per scene:
    block_turn     a turning clip: an obstacle on the straight-ahead continuation of the pre-turn path,
                   just beyond the turn, so the captured turn avoids it (plus maybe one beside the path).
    beside_path    a moving clip: 1-3 obstacles beside the swept volume of a stretch of the path.
    corridor       a moving clip: two walls along a stretch of the path, one on each side.
    static         an in-place clip (gestures, dance): 1-2 obstacles around the swept volume.
    detour         a detour-and-stop copy of a straight walk (`<name>#detour<k>`, data/detours.py: like the
                   turned copies, an exception to the real-ego rule, since no clip walks around anything or
                   stops at a target): a box or table on the walk's original straight line beside the
                   detour's widest point, as wide as the detour leaves room for; the goal is where it stops.
A turn-then-walk arrival (`<name>#turnarrive<k>`, data/turn_arrivals.py) takes beside_path or corridor, its goal
where it stops.
Every obstacle is pushed out of the ego's swept volume (all joints, plus a body margin) along one axis,
so the real path stays free; the voxelised scene is then checked joint by joint.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..geometry import normalized
from ..library import ClipLibrary, derived_kind
from .clips import MOVING_DISTANCE, ClipCache, PathInfo
from .goals import hsi_goal
from .obstacles import Box, box_clear, merge_meshes, push_out, random_obstacle

if TYPE_CHECKING:  # voxel.py is NumPy-only and imported lazily (see HSIScene.grid)
    from ...voxel import OccupancyGrid

HSI_KINDS = ("block_turn", "beside_path", "corridor", "static", "detour")
SCENE_CHECK_HEIGHT = 1.5  # m: ego joints below this must never be inside an obstacle
VOXEL_SIZE = 0.05


@dataclass(eq=False)
class HSIScene:
    """An ego clip in an invented scene: obstacle triangles (world) and a goal from its own path."""
    ego: int
    vertices: np.ndarray        # (V, 3) float32 world
    faces: np.ndarray           # (M, 3) int64
    goal: np.ndarray            # (3,) world goal point on the floor (hsi_goal)
    kind: str                   # one of HSI_KINDS
    _grid: "OccupancyGrid | None" = field(default=None, init=False, repr=False, compare=False)

    def grid(self) -> "OccupancyGrid":
        """Voxelised obstacles (voxel_size 0.05, solid interiors), built once and cached."""
        if self._grid is None:
            from ...voxel import OccupancyGrid
            self._grid = OccupancyGrid.from_triangles(self.vertices, self.faces, voxel_size=VOXEL_SIZE)
        return self._grid


def _path_heading(path: PathInfo, k: int, w: int = 5) -> np.ndarray:
    t = len(path.xy)
    d = path.xy[min(k + w, t - 1)] - path.xy[max(k - w, 0)]
    return normalized(d) if np.linalg.norm(d) > 1e-6 else path.facing[k]


def _beside(joints: np.ndarray, path: PathInfo, rng: np.random.Generator, k: int,
            kinds: tuple[str, ...] = ("box", "table", "step", "wall"), side: float | None = None) -> Box | None:
    kind, hu, hn, h = random_obstacle(rng, kinds)
    u = _path_heading(path, k)
    n = np.array([-u[1], u[0]])
    s = side if side is not None else (1.0 if rng.random() < 0.5 else -1.0)
    start = path.xy[k] + float(rng.uniform(-0.5, 0.5)) * u
    return push_out(joints, start, u, hu, hn, h, s * n, float(rng.uniform(0.0, 0.4)), kind)


def _hsi_boxes(kind: str, joints: np.ndarray, path: PathInfo, rng: np.random.Generator) -> list[Box] | None:
    t = len(joints)
    if kind == "block_turn":
        okind, hu, hn, h = random_obstacle(rng, ("box", "wall", "table"))
        # facing the walker: its long side across the straight-ahead line
        u = np.array([-path.h_start[1], path.h_start[0]])
        if okind == "box":
            hn = hu = max(hu, 0.25)
        blocker = push_out(joints, path.xy[path.onset], u, max(hu, 0.35), hn, h, path.h_start,
                            float(rng.uniform(0.0, 0.3)), okind)
        if blocker is None:
            return None
        boxes = [blocker]
        if rng.random() < 0.5:
            b = _beside(joints, path, rng, int(rng.integers(0, max(1, path.onset))))
            if b is not None:
                boxes.append(b)
        return boxes
    if kind == "beside_path":
        k0 = int(rng.integers(0, t))
        boxes = []
        for _ in range(int(rng.integers(1, 4))):
            k = int(np.clip(k0 + rng.integers(-20, 21), 0, t - 1))
            b = _beside(joints, path, rng, k)
            if b is not None:
                boxes.append(b)
        return boxes or None
    if kind == "corridor":
        k = int(rng.integers(0, t))
        boxes = [_beside(joints, path, rng, k, ("wall",), side=s) for s in (-1.0, 1.0)]
        return None if any(b is None for b in boxes) else boxes
    if kind == "detour":
        return _detour_box(joints, path, rng)
    if kind == "static":
        centre = joints[:, 0, :2].mean(0).astype(np.float64)
        boxes = []
        for _ in range(int(rng.integers(1, 3))):
            okind, hu, hn, h = random_obstacle(rng, ("box", "table", "wall", "step"))
            a = float(rng.uniform(-np.pi, np.pi))
            d = np.array([np.cos(a), np.sin(a)])
            b = push_out(joints, centre, np.array([-d[1], d[0]]), hu, hn, h, d, float(rng.uniform(0.0, 0.5)),
                          okind)
            if b is not None:
                boxes.append(b)
        return boxes or None
    raise ValueError(f"unknown HSI scene kind {kind!r}; use one of {', '.join(HSI_KINDS)}")


def _detour_box(joints: np.ndarray, path: PathInfo, rng: np.random.Generator) -> list[Box] | None:
    """A box on the straight line from the copy's start to where it stops, beside the detour's widest point,
    as large as the detour leaves room for (its half width shrinks until the path clears it)."""
    chord = path.xy[-1] - path.xy[0]
    if np.linalg.norm(chord) < 1.0:
        return None
    u = normalized(chord)
    n = np.array([-u[1], u[0]])
    rel = path.xy - path.xy[0]
    apex = int(np.argmax(np.abs(rel @ n)))
    centre = path.xy[0] + (float(rel[apex] @ u) + float(rng.uniform(-0.3, 0.3))) * u + \
        float(rng.uniform(-0.1, 0.1)) * n
    kind = "table" if rng.random() < 0.2 else "box"
    hu, h = float(rng.uniform(0.2, 0.45)), float(rng.uniform(0.4, 1.0) if kind == "box" else rng.uniform(0.7, 0.8))
    for hn in np.arange(float(rng.uniform(0.3, 0.55)), 0.149, -0.05):
        box = Box(centre, u, hu, float(hn), h, kind)
        if box_clear(box, joints):
            return [box]
    return None


def _hsi_kinds(path: PathInfo, name: str = "") -> list[str]:
    if derived_kind(name) == "detour":
        return ["detour"]
    if derived_kind(name) == "turnarrive":    # its turn is on the spot: no pre-turn path for block_turn to block
        return ["beside_path", "corridor"]
    if path.turning:
        return ["block_turn", "beside_path", "corridor"]
    if path.travel >= MOVING_DISTANCE:
        return ["beside_path", "corridor"]
    return ["static"]


def scene_collisions(grid: "OccupancyGrid", joints: np.ndarray, height: float = SCENE_CHECK_HEIGHT) -> int:
    """Number of ego joints (any frame) below `height` that fall in an occupied voxel."""
    p = joints.reshape(-1, 3)
    p = p[p[:, 2] < height]
    return int(np.count_nonzero(grid.occupied(p))) if len(p) else 0


def build_hsi_scenes(lib: ClipLibrary, clip_ids: list[int], seed: int = 0, per_clip: int = 2) -> list[HSIScene]:
    """Up to `per_clip` procedural scenes per clip of `clip_ids` (rules in the module docstring).

    Deterministic for a seed; a clip's scenes do not depend on the other clips. Every returned scene's
    voxel grid (already built and cached) has no ego joint below 1.5 m inside an obstacle at any frame;
    placements that fail are resampled, then skipped.
    """
    from ...voxel import OccupancyGrid
    clips = ClipCache(lib)
    out: list[HSIScene] = []
    for ego in clip_ids:
        rng = np.random.default_rng([seed, int(ego), 1])
        joints, path = clips.joints(ego), clips.path(ego)
        kinds = _hsi_kinds(path, lib.names[ego])
        order = kinds[:1] + [kinds[1:][i] for i in rng.permutation(len(kinds) - 1)]
        goal = hsi_goal(joints, path, lib.names[ego])
        for n in range(max(per_clip, 0)):
            kind = order[n % len(order)]
            for _ in range(8):
                boxes = _hsi_boxes(kind, joints, path, rng)
                if not boxes or not all(box_clear(b, joints) for b in boxes):
                    continue
                v, f = merge_meshes([b.triangles() for b in boxes])
                grid = OccupancyGrid.from_triangles(v, f, voxel_size=VOXEL_SIZE)
                if scene_collisions(grid, joints):
                    continue
                scene = HSIScene(int(ego), v, f, goal.copy(), kind)
                scene._grid = grid
                out.append(scene)
                break
    return out
