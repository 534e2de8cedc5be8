"""Seeded scenario generators for the behaviour suite, one per family.

Every episode starts the ego standing at the origin facing yaw 0 (-Y). Partners are a real CMU walk
(trial 05_01, retargeted to the SMPL-X body and shipped in data/clips), rotated to any direction and
retimed: the gait phase follows the distance walked, so retiming to 0.8-1.6 m/s or easing to a stop keeps
the partner's feet planted. Obstacles are axis-aligned boxes (box, wall with a doorway, table with legs).
Different splits draw from different generator seeds; within a split, family f's episode i is fixed.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

FPS = 10.0
SPLIT_SEEDS = {"val": 1001, "test": 2002}
FAMILIES = ("crossing", "approach", "goal", "obstacles", "text", "walk_forward", "stand")
EPISODES_PER_FAMILY = 48
GOAL_LIMIT_FRAMES = 120                  # 12 s to reach a goal
GOAL_EPISODE_FRAMES = 140                # plus 2 s to see whether it stops
STAND_TEXT = "a person stands"
WALK_TEXT = "a person walks forward"
GOAL_TEXT = "a person walks"
TEXT_EPISODE_FRAMES = 100              # 10 s per text prompt
CROSS_TIME = 2.5                       # s: a crossing partner passes where the ego should be then
CROSS_FRAMES = 50                      # 5 s crossing episodes
CROSS_MISS = 0.3                       # m: the partner's line passes that point within this
EGO_WALK_SPEED = 1.0                   # m/s: where a walking ego is expected at CROSS_TIME
APPROACH_AFTER = 3.0                   # s an approach episode goes on after the partner's rough arrival
from .. import WALK_CLIP
from .text_targets import TEXT_PROMPTS  # prompt -> kind -> statistic and target


@dataclass(frozen=True)
class Box:
    """An axis-aligned obstacle, world Z-up metres."""
    lo: tuple[float, float, float]
    hi: tuple[float, float, float]


@dataclass
class Episode:
    family: str
    index: int
    seed: int                                # the session's noise seed
    text: str
    frames: int
    partner: np.ndarray | None = None        # (frames, 22, 3) world joints
    goal: tuple[float, float, float] | None = None
    boxes: list[Box] = field(default_factory=list)
    params: dict = field(default_factory=dict)


# ----------------------------------------------------------------------------- the real walk
@lru_cache(maxsize=1)
def walk_clip() -> tuple[np.ndarray, float]:
    """(T, 22, 3) joints of the walk, pelvis starting at the origin, walking along +X; and its speed (m/s).

    The 5 s capture is extended by repeating its best-matching gait cycle, so partners can walk any distance.
    """
    import torch

    from ..skeleton import forward_kinematics, quat_to_matrix
    d = np.load(WALK_CLIP)
    rot = quat_to_matrix(torch.as_tensor(d["local_rotations"], dtype=torch.float32))
    joints = forward_kinematics(rot, torch.as_tensor(d["pelvis"], dtype=torch.float32))[0].numpy().astype(np.float64)
    joints[..., 2] -= joints[..., 2].min()     # soles on the floor
    travel = joints[-1, 0, :2] - joints[0, 0, :2]
    ang = math.atan2(travel[1], travel[0])
    c, s = math.cos(-ang), math.sin(-ang)
    xy = joints[..., :2] - joints[0, 0, :2]
    joints[..., 0], joints[..., 1] = c * xy[..., 0] - s * xy[..., 1], s * xy[..., 0] + c * xy[..., 1]
    speed = float(joints[-1, 0, 0] / ((len(joints) - 1) / float(d["fps"])))
    return _loop_gait(joints, repeats=12), speed


def _loop_gait(joints: np.ndarray, repeats: int) -> np.ndarray:
    """The clip followed by `repeats` copies of its gait cycle, each moved on by one cycle's displacement."""
    rel = joints - joints[:, :1]
    best = min(((np.abs(rel[a] - rel[a + p]).max(), a, p) for a in range(5, 21) for p in range(10, 41)
                if a + p < len(joints)))
    _, a, p = best
    cycle = joints[a:a + p]
    shift = joints[a + p] - joints[a]
    shift[..., 2] = 0.0
    parts = [joints[:a + p]] + [cycle + shift * (k + 1) for k in range(repeats)]
    return np.concatenate(parts, 0)


def _pose_at_distance(s: np.ndarray) -> np.ndarray:
    """Walk poses at distances s (m) along the clip: the gait phase follows the distance walked."""
    joints, _ = walk_clip()
    progress = np.maximum.accumulate(joints[:, 0, 0])     # pelvis distance along the walk, made monotonic
    t = np.interp(np.asarray(s, np.float64), progress, np.arange(len(joints), dtype=np.float64))
    i = np.minimum(np.floor(t).astype(int), len(joints) - 2)
    a = (t - i)[:, None, None]
    return (1.0 - a) * joints[i] + a * joints[i + 1]


def walk_track(start_xy, heading: float, distances: np.ndarray) -> np.ndarray:
    """(T, 22, 3) the walk placed at start_xy, heading `heading` (rad, CCW from +X), at distances (T,)."""
    pose = _pose_at_distance(distances)
    c, s = math.cos(heading), math.sin(heading)
    out = pose.copy()
    out[..., 0] = c * pose[..., 0] - s * pose[..., 1] + start_xy[0]
    out[..., 1] = s * pose[..., 0] + c * pose[..., 1] + start_xy[1]
    return out


def cruise_then_stop(total: float, speed: float, frames: int, brake: float = 0.75) -> np.ndarray:
    """Distance walked per frame: constant speed, then a linear slow-down over the last `brake` m, then still."""
    t = np.arange(frames) / FPS
    cruise = max(total - brake, 0.0) / speed
    brake_t = 2.0 * min(brake, total) / speed
    s = np.minimum(speed * t, total - min(brake, total))
    tb = np.clip(t - cruise, 0.0, brake_t)
    s = s + speed * tb - 0.5 * (speed / brake_t) * tb ** 2
    return np.minimum(s, total)


def _facing_dir(yaw: float) -> np.ndarray:
    """World xy of the direction a body with this yaw faces (yaw 0 faces -Y)."""
    return np.array([math.sin(yaw), -math.cos(yaw)])


def _rotate(v: np.ndarray, ang: float) -> np.ndarray:
    c, s = math.cos(ang), math.sin(ang)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]])


def crossing_point(walks: bool, heading: float, offset: float) -> np.ndarray:
    """World xy a crossing partner's pelvis passes at CROSS_TIME: where the ego will be then (standing at the
    origin, or EGO_WALK_SPEED straight ahead), moved `offset` m to the left of the partner's heading (rad)."""
    meet = _facing_dir(0.0) * (EGO_WALK_SPEED * CROSS_TIME if walks else 0.0)
    direction = np.array([math.cos(heading), math.sin(heading)])
    return meet + np.array([-direction[1], direction[0]]) * offset


# ----------------------------------------------------------------------------- families
def _crossing(rng: np.random.Generator, i: int) -> Episode:
    speed = rng.uniform(0.8, 1.6)
    heading = rng.uniform(0.0, 2.0 * math.pi)
    offset = rng.uniform(0.0, CROSS_MISS) * rng.choice((-1.0, 1.0))
    walks = bool(rng.integers(2))
    frames = CROSS_FRAMES
    direction = np.array([math.cos(heading), math.sin(heading)])
    start = crossing_point(walks, heading, offset) - direction * speed * CROSS_TIME
    partner = walk_track(start, heading, speed * np.arange(frames) / FPS)
    return Episode("crossing", i, int(rng.integers(2 ** 31)), WALK_TEXT if walks else STAND_TEXT, frames,
                   partner=partner, params={"speed": speed, "heading_deg": math.degrees(heading),
                                            "offset_m": offset, "ego_walks": walks})


def _approach(rng: np.random.Generator, i: int) -> Episode:
    off = rng.uniform(0.0, math.pi) * rng.choice((-1.0, 1.0))
    stop = rng.uniform(0.9, 1.5)
    start_r = rng.uniform(4.0, 5.0)
    speed = rng.uniform(1.0, 1.4)
    start = _rotate(_facing_dir(0.0), off) * start_r
    heading = math.atan2(-start[1], -start[0])          # straight at the ego
    walk_s = (start_r - stop) / speed + 1.0              # rough arrival time incl. the slow-down
    frames = int(round((walk_s + APPROACH_AFTER) * FPS))
    partner = walk_track(start, heading, cruise_then_stop(start_r - stop, speed, frames))
    return Episode("approach", i, int(rng.integers(2 ** 31)), STAND_TEXT, frames, partner=partner,
                   params={"off_facing_deg": math.degrees(off), "stop_m": stop, "speed": speed})


def _goal_point(rng: np.random.Generator, near: float, far: float) -> tuple[np.ndarray, float]:
    off = rng.uniform(0.0, math.pi) * rng.choice((-1.0, 1.0))
    return _rotate(_facing_dir(0.0), off) * rng.uniform(near, far), off


def _goal(rng: np.random.Generator, i: int) -> Episode:
    g, off = _goal_point(rng, 2.0, 5.0)
    return Episode("goal", i, int(rng.integers(2 ** 31)), GOAL_TEXT, GOAL_EPISODE_FRAMES,
                   goal=(float(g[0]), float(g[1]), 0.0),
                   params={"off_facing_deg": math.degrees(off), "distance_m": float(np.linalg.norm(g))})


def _box_at(centre_xy, size_xy, height: float, z0: float = 0.0) -> Box:
    cx, cy = centre_xy
    sx, sy = size_xy
    return Box((cx - sx / 2, cy - sy / 2, z0), (cx + sx / 2, cy + sy / 2, z0 + height))


def _table(centre_xy, size_xy, height: float = 0.74) -> list[Box]:
    top = _box_at(centre_xy, size_xy, 0.04, height - 0.04)
    legs = [_box_at((centre_xy[0] + sx * (size_xy[0] / 2 - 0.04), centre_xy[1] + sy * (size_xy[1] / 2 - 0.04)),
                    (0.05, 0.05), height - 0.04) for sx in (-1, 1) for sy in (-1, 1)]
    return [top] + legs


def _wall_with_door(centre_xy, along_x: bool, door: float, half_length: float = 3.0) -> list[Box]:
    """Two wall pieces (0.15 m thick, 2 m high) leaving a `door` m gap centred at centre_xy."""
    c = np.asarray(centre_xy, np.float64)
    axis = np.array([1.0, 0.0]) if along_x else np.array([0.0, 1.0])
    piece = half_length - door / 2
    out = []
    for sign in (-1.0, 1.0):
        mid = c + axis * sign * (door / 2 + piece / 2)
        size = (piece, 0.15) if along_x else (0.15, piece)
        out.append(_box_at(mid, size, 2.0))
    return out


def _inside_any(p: np.ndarray, boxes: list[Box], margin: float) -> bool:
    return any(all(b.lo[k] - margin < p[k] < b.hi[k] + margin for k in range(2)) for b in boxes)


def _obstacles(rng: np.random.Generator, i: int) -> Episode:
    for _ in range(100):
        g, off = _goal_point(rng, 3.0, 5.0)
        mid = g * rng.uniform(0.4, 0.6)
        kind = ("box", "doorway", "table")[i % 3]
        if kind == "box":
            boxes = [_box_at(mid, rng.uniform(0.5, 1.0, 2), rng.uniform(0.5, 1.0))]
            params = {}
        elif kind == "table":
            size = rng.uniform((1.0, 0.6), (1.6, 1.0))
            boxes = _table(mid, size if rng.integers(2) else size[::-1])
            params = {}
        else:
            door = rng.uniform(0.9, 1.4)
            along_x = abs(g[1]) >= abs(g[0])           # the wall runs across the way to the goal
            centre = mid + (np.array([1.0, 0.0]) if along_x else np.array([0.0, 1.0])) * rng.uniform(-0.3, 0.3)
            boxes = _wall_with_door(centre, along_x, door)
            params = {"door_m": door}
        if not _inside_any(np.zeros(2), boxes, 0.4) and not _inside_any(g, boxes, 0.4):
            break
    params.update({"kind": kind, "off_facing_deg": math.degrees(off), "distance_m": float(np.linalg.norm(g))})
    return Episode("obstacles", i, int(rng.integers(2 ** 31)), GOAL_TEXT, GOAL_EPISODE_FRAMES,
                   goal=(float(g[0]), float(g[1]), 0.0), boxes=boxes, params=params)


def _text(rng: np.random.Generator, i: int) -> Episode:
    prompt = TEXT_PROMPTS[i % len(TEXT_PROMPTS)]
    return Episode("text", i, int(rng.integers(2 ** 31)), prompt, TEXT_EPISODE_FRAMES, params={"prompt": prompt})


def _walk_forward(rng: np.random.Generator, i: int) -> Episode:
    return Episode("walk_forward", i, int(rng.integers(2 ** 31)), WALK_TEXT, 200)


def _stand(rng: np.random.Generator, i: int) -> Episode:
    return Episode("stand", i, int(rng.integers(2 ** 31)), STAND_TEXT, 600)


_DRAW = {"crossing": _crossing, "approach": _approach, "goal": _goal, "obstacles": _obstacles,
         "text": _text, "walk_forward": _walk_forward, "stand": _stand}


def draw_episodes(family: str, split: str, n: int = EPISODES_PER_FAMILY) -> list[Episode]:
    """The first n episodes of a family in a split ("val" for every choice, "test" only to report)."""
    if family not in _DRAW:
        raise ValueError(f"unknown family {family!r}: pick one of {', '.join(FAMILIES)}")
    if split not in SPLIT_SEEDS:
        raise ValueError(f"unknown split {split!r}: pick 'val' or 'test'")
    rng = np.random.default_rng([SPLIT_SEEDS[split], FAMILIES.index(family)])
    return [_DRAW[family](rng, i) for i in range(n)]


def box_triangles(boxes: list[Box]) -> tuple[np.ndarray, np.ndarray]:
    """All boxes as one triangle mesh (vertices (8B, 3), faces (12B, 3)) for OccupancyGrid.from_triangles."""
    quads = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                      [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    verts, faces = [], []
    for k, b in enumerate(boxes):
        lo, hi = b.lo, b.hi
        verts.append([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        faces.append(quads + 8 * k)
    return np.asarray(verts, np.float64).reshape(-1, 3), np.concatenate(faces)
