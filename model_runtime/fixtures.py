"""The scripted scenes the latency benchmark and the evaluation share: a partner walking up to the ego and a
box between the ego and a goal. The ego starts at the origin facing -Y (the rest pose's facing)."""
from __future__ import annotations

import numpy as np

from .skeleton import rest_joints, standing_pelvis_height

BOX_GOAL = (0.0, -3.0, 0.0)   # the goal 3 m ahead of the ego, beyond the box


def approaching_partner(frames: int, start: float = 4.0, stop: float = 1.0, speed: float = 1.2) -> np.ndarray:
    """(frames, 22, 3) a rest-pose partner walking along -Y towards an ego at the origin, then standing."""
    body = rest_joints().numpy() + np.array([0.0, 0.0, standing_pelvis_height()], np.float32)
    # The ego faces -Y, so the partner stands in front of it at negative y; turned 180 degrees about Z
    # it faces +Y, back towards the ego, while it walks in from y = -start to y = -stop.
    body = body * np.array([-1.0, -1.0, 1.0], np.float32)
    t = np.arange(frames) / 10.0
    y = -np.maximum(start - speed * t, stop)
    return (body[None] + np.stack((np.zeros_like(y), y, np.zeros_like(y)), -1)[:, None, :]).astype(np.float32)


def box_scene():
    """An OccupancyGrid of a 0.8 m box 1.1-1.9 m in front of the ego (0.05 m voxels), on its way to BOX_GOAL."""
    from .voxel import OccupancyGrid
    lo, hi = np.array([-0.4, -1.9, 0.0]), np.array([0.4, -1.1, 0.8])
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    faces = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                      [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    return OccupancyGrid.from_triangles(corners, faces, voxel_size=0.05)
