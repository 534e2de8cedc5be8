"""The behaviour metrics give known values on hand-made motions, and the scenario generator is seeded."""
import math

import numpy as np
import pytest

from model_runtime.behaviour import metrics as M
from model_runtime.behaviour.scenarios import (FAMILIES, Box, cruise_then_stop, draw_episodes, walk_clip)
from model_runtime.joints import SOLE_BELOW_FOOT_JOINT, rest_joints_np, standing_pelvis_height


def standing_body(yaw: float = 0.0, xy=(0.0, 0.0)) -> np.ndarray:
    """(22, 3) the rest body standing on the floor at xy, turned by yaw (yaw 0 faces -Y)."""
    j = rest_joints_np() + np.array([0.0, 0.0, standing_pelvis_height()])
    c, s = math.cos(yaw), math.sin(yaw)
    x, y = j[:, 0].copy(), j[:, 1].copy()
    j[:, 0], j[:, 1] = c * x - s * y + xy[0], s * x + c * y + xy[1]
    return j


def test_facing_error_of_a_rest_body():
    # the SMPL-X rest hips are 2.2 deg off square, hence 3 deg of slack
    body = standing_body()
    assert M.facing_error_deg(body, (0.0, -3.0)) == pytest.approx(0.0, abs=3.0)      # straight ahead
    assert M.facing_error_deg(body, (0.0, 3.0)) == pytest.approx(180.0, abs=3.0)     # behind
    assert M.facing_error_deg(body, (3.0, 0.0)) == pytest.approx(90.0, abs=3.0)      # beside
    turned = standing_body(math.pi / 2)                                               # yaw 90: faces +X
    assert M.facing_error_deg(turned, (3.0, 0.0)) == pytest.approx(0.0, abs=3.0)


def test_min_joint_clearance_two_points():
    a = np.zeros((3, 22, 3))
    b = np.zeros((3, 22, 3))
    b[..., 0] = [[5.0], [0.7], [2.0]]
    assert M.min_joint_clearance(a, b) == pytest.approx(0.7)


def test_goal_arrival_and_settling():
    t = np.arange(60)
    ego = np.zeros((60, 22, 3))
    ego[:, 0, 1] = -np.minimum(t * 0.1, 3.0)               # walks 1 m/s to y = -3 and stops at frame 30
    reached, closest, settle = M.goal_arrival(ego, (0.0, -3.0, 0.0), limit_frames=50)
    assert reached and closest == pytest.approx(0.0)
    assert settle == pytest.approx(0.0)                     # within 0.5 m at frame 25; at frame 45 it stands on it
    walker = np.zeros((60, 22, 3))
    walker[:, 0, 1] = -t * 0.1                              # walks on through the goal
    reached, _, settle = M.goal_arrival(walker, (0.0, -3.0, 0.0), limit_frames=50)
    assert reached and settle == pytest.approx(1.6, abs=1e-6)   # arrives at frame 26 (2.6 m); frame 46: 4.6 m
    assert not M.goal_arrival(walker, (5.0, 0.0, 0.0), limit_frames=50)[0]


def test_frames_inside_boxes():
    j = np.zeros((4, 22, 3))
    j[:, 3] = [[0, 0, 0.5], [2, 2, 0.5], [0.1, 0.1, 1.5], [-0.2, 0.2, 0.1]]
    box = Box((-0.3, -0.3, 0.0), (0.3, 0.3, 1.0))
    assert M.frames_inside_boxes(j, [box]).tolist() == [True, False, False, True]


def test_seam_ratio_sees_a_pop_every_segment():
    t = np.arange(81, dtype=np.float64)
    smooth = np.zeros((81, 22, 3))
    smooth[..., 0] = (t * 0.1)[:, None]                     # steady 0.1 m per frame
    assert M.seam_ratio(smooth) == pytest.approx(1.0)
    popping = smooth.copy()
    popping[..., 0] += (0.2 * (t // 8))[:, None]           # an extra 0.2 m jump into frames 8, 16, ...
    assert M.seam_ratio(popping) == pytest.approx(3.0)


def test_planted_toe_speed_counts_only_planted_toes():
    j = np.tile(standing_body()[None], (11, 1, 1))
    toes = list(M.TOES)
    j[:, toes, 2] = SOLE_BELOW_FOOT_JOINT + 0.01            # soles 1 cm above the floor: planted
    j[:, toes[0], 0] += np.arange(11) * 0.003               # left toe slides 3 mm a frame = 3 cm/s
    s = M.planted_toe_speed(j)
    assert s.size == 20
    assert s.max() == pytest.approx(0.03) and s.min() == pytest.approx(0.0)
    j[:, toes, 2] += 0.2                                    # lifted: nothing counts
    assert M.planted_toe_speed(j).size == 0


def test_net_yaw_and_drift():
    bodies = np.stack([standing_body(math.radians(0.5 * k), (0.01 * k, 0.0)) for k in range(101)])  # 10 s
    assert M.net_yaw_deg(bodies, 20.0) == pytest.approx(100.0, abs=0.5)     # 50 deg in 10 s -> 100 per 20 s
    assert M.standing_drift_m(bodies, 60.0) == pytest.approx(6.0, abs=1e-6)   # 1 m in 10 s -> 6 m per minute


def test_generator_is_seeded_and_splits_differ():
    for family in FAMILIES:
        a, b = draw_episodes(family, "val", 4), draw_episodes(family, "val", 4)
        assert [e.seed for e in a] == [e.seed for e in b]
        assert [e.seed for e in a] != [e.seed for e in draw_episodes(family, "test", 4)]


def test_crossing_partners_pass_close_and_approaching_partners_stop_where_drawn():
    for ep in draw_episodes("crossing", "val", 12):
        if not ep.params["ego_walks"]:
            closest = np.linalg.norm(ep.partner[:, 0, :2], axis=-1).min()
            assert closest < 0.3 + 0.1, ep.params           # the path passes within 0-0.3 m (plus gait sway)
    for ep in draw_episodes("approach", "val", 12):
        assert np.linalg.norm(ep.partner[-1, 0, :2]) == pytest.approx(ep.params["stop_m"], abs=0.02)
        assert 0.0 <= abs(ep.params["off_facing_deg"]) <= 180.0


def test_retimed_walk_keeps_feet_planted():
    joints, speed = walk_clip()
    assert 0.7 < speed < 1.5
    s = cruise_then_stop(3.0, 1.5, 40)
    assert s[-1] == pytest.approx(3.0) and np.all(np.diff(s) >= -1e-12)
