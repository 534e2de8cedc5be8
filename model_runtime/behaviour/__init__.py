"""Behaviour suite: the model judged on whole distributions of seeded scenarios, not on a few cases.

    python -m model_runtime.behaviour --split val --json --plots DIR [--library CLIPS.npz] [--diversity]

Families (scenarios.py): partner crossing, partner approach-and-stop, goal in any direction, goal past
obstacles, free text, and heading (walk forward for 20 s, stand for a minute). Each family is drawn by a
seeded generator whose seed differs per split: choose checkpoints, weights and thresholds on `val`; report
`test` only. Metrics (metrics.py) are plain NumPy functions on joint arrays, unit-tested on hand-made motions,
and the ones that apply to real motion are also computed on real clips as the reference.

Each text prompt has a kind with a statistic and a target (text_targets.py), compared with real clips of
that kind when a clip library is given (real_clips.py). diversity.py measures how far apart different
seeds' takes of one prompt are, against real takes of its caption; tables.py prints both as markdown.
"""
from .metrics import (SEAM_PERIOD, dragged_toe_percent, facing_error_deg, frames_inside_boxes, goal_arrival,
                      min_joint_clearance, net_yaw_deg, planted_toe_speed, seam_ratio, standing_drift_m)
from .scenarios import FAMILIES, SPLIT_SEEDS, Box, Episode, draw_episodes

__all__ = ["FAMILIES", "SPLIT_SEEDS", "Box", "Episode", "draw_episodes", "SEAM_PERIOD", "dragged_toe_percent",
           "facing_error_deg", "frames_inside_boxes", "goal_arrival", "min_joint_clearance", "net_yaw_deg",
           "planted_toe_speed", "seam_ratio", "standing_drift_m"]
