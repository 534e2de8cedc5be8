"""HSI goals: a floor point taken from the ego's own path, so the real motion reads as heading for it."""
from __future__ import annotations

import numpy as np

from ..library import derived_kind
from .clips import PathInfo

GOAL_LEAD = 1.5           # s: a clip still walking at its end gets its goal this far ahead (at its final speed)
GOAL_LEAD_MAX = 2.5       # m
STOPPED_SPEED = 0.3       # m/s: a clip slower than this at its end has stopped there


def hsi_goal(joints: np.ndarray, path: PathInfo, name: str) -> np.ndarray:
    """(3,) floor goal: where the clip stops, or, for a clip still walking at its end (captured walks end
    mid-stride), GOAL_LEAD seconds further along its final heading, so a goal under the ego always means
    "stop here" and a goal ahead "keep going" (data/detours.py makes the stops)."""
    end = joints[-1, 0, :2].astype(np.float64)
    stopped = derived_kind(name) in ("arrive", "detour", "turnarrive")
    if not stopped and path.end_speed >= STOPPED_SPEED:
        end = end + min(GOAL_LEAD_MAX, GOAL_LEAD * path.end_speed) * path.h_end
    return np.array([end[0], end[1], 0.0], np.float32)
