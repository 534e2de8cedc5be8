"""Interaction training data built from single-person clips: stand-ins for Inter-X (HHI) and LINGO (HSI).

The open motion data has no two-person or scene-paired capture, so the interaction stages train on pairs
generated here. The ego's motion is a real clip, or a copy derived from one where the data holds no example
of a reaction (turned on the spot, bent around a walker or a box, stopped, re-timed: data/turns.py,
data/detours.py, data/hhi_copies.py); the partner or the scene is invented, or is a real walk moved and re-timed,
and placed so that the ego's motion reads as a plausible reaction to it. Every generator checks what it
guarantees (a partner never closer than MIN_CLEARANCE to the ego, AVOID_CLEARANCE for one passing close by; no
ego joint below 1.5 m inside an obstacle, checked on the voxel grid the model will read) and resamples or skips
a placement that breaks it.

    clips       clip analysis: joints, facing, pelvis path (travel, headings, turn), a per-build cache
    placement   partner bodies from other real clips, placed, scaled and time-shifted
    hhi         the HHI pair rules and `build_hhi_pairs`
    obstacles   boxes, walls, tables and steps pushed out of the ego's swept volume
    goals       the HSI goal taken from the ego's own path
    hsi         the HSI scene rules and `build_hsi_scenes`

The loaders for the real datasets' published layouts are in data/research; these builders only exist
because those datasets are not part of the open data.
"""
from __future__ import annotations

from .clips import (FPS, MOVING_DISTANCE, STANDING_RANGE, ClipCache, PathInfo, analyse_path, clip_joints,
                    facing_xy, is_gesture, pose_joints)
from .goals import GOAL_LEAD, GOAL_LEAD_MAX, STOPPED_SPEED, hsi_goal
from .hhi import HHI_KINDS, MIN_CLEARANCE, HHIPair, build_hhi_pairs
from .hsi import HSI_KINDS, SCENE_CHECK_HEIGHT, VOXEL_SIZE, HSIScene, build_hsi_scenes, scene_collisions
from .placement import min_clearance, place_standing

__all__ = ["FPS", "MOVING_DISTANCE", "STANDING_RANGE", "ClipCache", "PathInfo", "analyse_path", "clip_joints",
           "facing_xy", "is_gesture", "pose_joints", "GOAL_LEAD", "GOAL_LEAD_MAX", "STOPPED_SPEED", "hsi_goal", "HHI_KINDS",
           "MIN_CLEARANCE", "HHIPair", "build_hhi_pairs", "HSI_KINDS", "SCENE_CHECK_HEIGHT", "VOXEL_SIZE",
           "HSIScene", "build_hsi_scenes", "scene_collisions", "min_clearance", "place_standing"]
