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


def test_peak_pelvis_speed_finds_the_one_glided_step():
    walk = np.tile(standing_body()[None], (20, 1, 1))
    walk[:, :, 1] += (np.arange(20) * 0.12)[:, None]        # 1.2 m/s along +Y
    assert M.peak_pelvis_speed(walk) == pytest.approx(1.2)
    walk[12:, :, 0] += 0.5                                   # 0.5 m sideways between frames 11 and 12
    assert M.peak_pelvis_speed(walk) == pytest.approx(math.hypot(5.0, 1.2)) and M.peak_pelvis_speed(walk) > M.GLIDE_SPEED
    assert M.peak_pelvis_speed(walk[:1]) == 0.0


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


def test_dragged_toe_steps_are_the_planted_steps_swept_along_the_floor():
    """A toe swept along the floor at 2 m/s is dragged; one creeping at 3 cm/s or standing is not; the real walk the
    suite replays drags none, and the suite reports the share beside the planted-toe mean."""
    from model_runtime.behaviour.suite import real_reference, summarise
    j = np.tile(standing_body()[None], (11, 1, 1))
    toes = list(M.TOES)
    j[:, toes, 2] = SOLE_BELOW_FOOT_JOINT + 0.01
    j[:, toes[0], 0] += np.arange(11) * 0.003               # creeping
    assert M.dragged_toe_percent(M.planted_toe_speed(j)) == 0.0
    j[6:, toes[1], 0] += np.arange(5) * 0.2 + 0.2           # the right toe swept 0.2 m a frame from frame 6 on
    s = M.planted_toe_speed(j)
    assert M.dragged_toe_percent(s) == pytest.approx(100.0 * 5 / 20)
    assert math.isnan(M.dragged_toe_percent(np.zeros(0)))
    assert real_reference()["walk_clip"]["percent_dragged_toe_steps"] == 0.0
    ep = {"toe_speeds": s, "seam_steps": (0.0, 0, 1.0, 1), "peak_pelvis_speed": 0.0}
    assert summarise("walk_forward", [dict(ep, net_yaw_deg_per_20s=0.0)])["percent_dragged_toe_steps"] == \
        pytest.approx(25.0)


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


# ----------------------------------------------------------------------------- text statistics
def moving_body(frames: int, velocity_xy, yaw: float = 0.0) -> np.ndarray:
    """(frames, 22, 3) the standing rest body gliding at velocity_xy (m/s), turned by yaw, 10 fps."""
    return np.stack([standing_body(yaw, (velocity_xy[0] * k / 10.0, velocity_xy[1] * k / 10.0))
                     for k in range(frames)])


def test_travel_against_facing_reads_backwards_forwards_and_sideways():
    # yaw 0 faces -Y; the rest hips are 2.2 deg off square, hence 3 deg of slack
    assert M.travel_vs_facing_deg(moving_body(31, (0.0, 1.0))) == pytest.approx(180.0, abs=3.0)   # backs away
    assert M.travel_vs_facing_deg(moving_body(31, (0.0, -1.0))) == pytest.approx(0.0, abs=3.0)
    assert M.travel_vs_facing_deg(moving_body(31, (1.0, 0.0))) == pytest.approx(90.0, abs=3.0)
    turned = moving_body(31, (-1.0, 0.0), yaw=math.pi / 2)                 # faces +X, moves -X
    assert M.travel_vs_facing_deg(turned) == pytest.approx(180.0, abs=3.0)
    assert M.travel_vs_facing_deg(moving_body(31, (0.0, 0.005))) == 0.0    # 15 mm: no direction to judge
    m = M.text_measures(moving_body(31, (0.0, 1.0)))
    assert m["speed_mps"] == pytest.approx(1.0) and m["forward_m"] == pytest.approx(-3.0, abs=0.01)


def test_a_standing_body_stands_on_both_its_toes_and_heels():
    sole = M.lowest_sole(standing_body()[None])
    assert sole[0] == pytest.approx(0.0, abs=0.005)


def test_airborne_share_of_a_body_off_the_floor_half_the_time():
    j = moving_body(20, (0.0, 0.0))
    j[1::2, :, 2] += 0.10                               # both soles 10 cm up on every other frame
    assert M.airborne_percent(j) == pytest.approx(50.0)
    assert M.text_measures(j)["airborne_percent"] == pytest.approx(50.0)
    heel_strike = moving_body(20, (0.0, 0.0))
    heel_strike[:, list(M.TOES), 2] += 0.10             # toes up, heels down: still on the ground
    assert M.airborne_percent(heel_strike) == 0.0


def test_a_real_clips_floor_follows_a_sloped_capture_but_not_a_jump():
    j = moving_body(60, (0.0, 0.0))
    j[..., 2] += np.linspace(0.0, 0.12, 60)[:, None]    # the capture's floor rises 12 cm over 6 s
    assert M.airborne_percent(j) > 40.0                 # against z = 0 it reads as lifting off
    assert M.airborne_percent(j, M.rolling_floor(j)) == 0.0
    j[28:32, :, 2] += 0.3                               # a 0.4 s jump
    assert M.airborne_percent(j, M.rolling_floor(j)) == pytest.approx(100.0 * 4 / 60)


def test_kick_height_is_the_highest_ankle_above_the_floor():
    j = moving_body(10, (0.0, 0.0))
    ankle = M.ANKLES[1]
    j[5, ankle, 2] = 0.55
    assert M.text_measures(j)["max_ankle_height_m"] == pytest.approx(0.55)
    assert M.text_measures(j, floor=np.full(10, 0.05))["max_ankle_height_m"] == pytest.approx(0.50)


def waving_body(frames: int, amplitude: float, above: float, yaw: float = 0.0) -> np.ndarray:
    """A standing body whose right wrist sits `above` m over its shoulder and swings side to side by
    amplitude * sin (one cycle a second), the whole body turned by yaw."""
    j = moving_body(frames, (0.0, 0.0))                 # yaw 0: the body's side-to-side axis is X
    wrist, shoulder = M.WRISTS[1], M.SHOULDERS[1]
    swing = amplitude * np.sin(2.0 * math.pi * np.arange(frames) / 10.0)
    j[:, wrist] = j[:, shoulder] + np.stack((swing, np.zeros(frames), np.full(frames, above)), -1)
    c, s = math.cos(yaw), math.sin(yaw)
    x, y = j[..., 0].copy(), j[..., 1].copy()
    j[..., 0], j[..., 1] = c * x - s * y, s * x + c * y
    return j


def test_a_waving_wrist_gives_the_sd_of_its_swing():
    sd, raised = M.wave_measures(waving_body(40, 0.10, 0.2))
    # the rest hips are 2.2 deg off square: the body's side-to-side axis is cos(2.2 deg) = 0.9993 along X
    assert sd == pytest.approx(0.10 / math.sqrt(2.0), rel=1e-3) and raised == pytest.approx(100.0)
    turned = M.wave_measures(waving_body(40, 0.10, 0.2, yaw=1.0))
    assert turned[0] == pytest.approx(sd, abs=1e-6)     # measured on the body's own side-to-side axis
    assert M.wave_measures(waving_body(40, 0.10, -0.3)) == (0.0, 0.0)        # swinging below the shoulder
    short = waving_body(40, 0.10, -0.3)
    short[:5, M.WRISTS[1], 2] += 0.6                    # raised for only 0.5 s
    assert M.wave_measures(short) == (0.0, 0.0)
    assert M.text_measures(waving_body(40, 0.10, 0.2))["wave_sd_m"] == pytest.approx(sd)


# ----------------------------------------------------------------------------- takes that differ
def test_pose_distance_ignores_where_and_which_way_a_take_starts():
    a = waving_body(30, 0.1, 0.2)
    moved = waving_body(30, 0.1, 0.2, yaw=2.0) + np.array([3.0, -1.0, 0.0])
    assert M.pose_distance_m(a, a) == 0.0
    assert M.pose_distance_m(a, moved) == pytest.approx(0.0, abs=1e-9)
    assert M.mean_pairwise_distance([a, a.copy(), moved]) == (pytest.approx(0.0, abs=1e-9), 3)
    other = a.copy()
    other[:, M.WRISTS[1], 2] += 0.22                    # one of 22 joints 22 cm off in every frame
    assert M.pose_distance_m(a, other[:20]) == pytest.approx(0.01)
    assert math.isnan(M.mean_pairwise_distance([a])[0])
