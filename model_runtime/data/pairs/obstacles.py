"""Procedural obstacles for the HSI scenes: boxes, walls, tables and low steps as closed triangle meshes,
slid out of the ego's swept volume so the real path stays free."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

BODY_MARGIN = 0.15        # m kept between obstacle faces and any ego joint (flesh, hands and feet)
_BOX_FACES = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                       [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]], np.int64)


@dataclass
class Box:
    """An obstacle's footprint: centre (2,), unit axis u (2,) along its length, half sizes, height."""
    centre: np.ndarray
    u: np.ndarray
    hu: float
    hn: float
    height: float
    kind: str  # "box" | "wall" | "table" | "step"

    @property
    def n(self) -> np.ndarray:
        return np.array([-self.u[1], self.u[0]])

    def triangles(self) -> tuple[np.ndarray, np.ndarray]:
        """Closed boxes: one for a box, wall or step; a top and four legs for a table."""
        if self.kind != "table":
            return _cuboid(self.centre, self.u, self.hu, self.hn, 0.0, self.height)
        top = 0.05
        parts = [_cuboid(self.centre, self.u, self.hu, self.hn, self.height - top, self.height)]
        leg = 0.03
        for a in (-1, 1):
            for b in (-1, 1):
                c = self.centre + a * (self.hu - leg) * self.u + b * (self.hn - leg) * self.n
                parts.append(_cuboid(c, self.u, leg, leg, 0.0, self.height - top))
        return merge_meshes(parts)


def _cuboid(c: np.ndarray, u: np.ndarray, hu: float, hn: float, z0: float, z1: float
            ) -> tuple[np.ndarray, np.ndarray]:
    n = np.array([-u[1], u[0]])
    v = np.array([[*(c + a * hu * u + b * hn * n), z] for a in (-1, 1) for b in (-1, 1) for z in (z0, z1)])
    return v, _BOX_FACES.copy()


def merge_meshes(parts: list[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, np.ndarray]:
    vs, fs, off = [], [], 0
    for v, f in parts:
        vs.append(v)
        fs.append(f + off)
        off += len(v)
    return np.concatenate(vs).astype(np.float32), np.concatenate(fs).astype(np.int64)


def random_obstacle(rng: np.random.Generator, kinds: tuple[str, ...]) -> tuple[str, float, float, float]:
    """(kind, half length, half depth, height) of a random obstacle."""
    kind = str(kinds[rng.integers(len(kinds))])
    if kind == "wall":
        return kind, rng.uniform(0.75, 1.5), rng.uniform(0.05, 0.1), rng.uniform(1.2, 1.8)
    if kind == "table":
        return kind, rng.uniform(0.4, 0.7), rng.uniform(0.3, 0.45), rng.uniform(0.7, 0.8)
    if kind == "step":
        return kind, rng.uniform(0.3, 0.6), rng.uniform(0.15, 0.3), rng.uniform(0.1, 0.2)
    return "box", rng.uniform(0.15, 0.4), rng.uniform(0.15, 0.4), rng.uniform(0.3, 1.0)


def push_out(joints: np.ndarray, start: np.ndarray, u: np.ndarray, hu: float, hn: float, height: float,
              push: np.ndarray, gap: float, kind: str) -> Box | None:
    """Slide an obstacle from `start` along `push` (= u or +-n) until every ego joint that could touch
    it (same height band, within its cross-section plus BODY_MARGIN) is behind it, then `gap` more.
    None when that takes more than 3 m (the obstacle would no longer be near the path)."""
    n = np.array([-u[1], u[0]])
    along_push = abs(float(push @ u)) > 0.5
    half_push, half_side = (hu, hn) if along_push else (hn, hu)
    side = n if along_push else u
    p = joints.reshape(-1, 3)
    p = p[p[:, 2] < height + BODY_MARGIN]
    rel = p[:, :2] - start
    a, b = rel @ push, rel @ side
    hit = np.abs(b) < half_side + BODY_MARGIN
    reach = float(a[hit].max()) if hit.any() else -np.inf
    delta = max(0.0, reach + half_push + BODY_MARGIN) + gap
    if delta > 3.0:
        return None
    return Box(start + delta * push, u, hu, hn, height, kind)


def box_clear(box: Box, joints: np.ndarray) -> bool:
    """Analytic check: no joint within BODY_MARGIN of the obstacle's bounding box."""
    p = joints.reshape(-1, 3)
    rel = p[:, :2] - box.centre
    inside = (np.abs(rel @ box.u) < box.hu + BODY_MARGIN) & (np.abs(rel @ box.n) < box.hn + BODY_MARGIN) & \
        (p[:, 2] < box.height + BODY_MARGIN)
    return not bool(inside.any())
