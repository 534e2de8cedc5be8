"""Synthetic detours and stops (model_runtime.data.detours) and the HSI scenes and goals built on them."""
import math

import numpy as np
import pytest
import torch

from model_runtime.data.detours import (SLOW_IN, SLOW_OUT, add_arrivals, bend_path, detour_frames, detour_profile,
                                        slow_to_rest)
from model_runtime.data.library import ClipLibrary
from model_runtime.data.pairs import analyse_path, build_hsi_scenes, clip_joints, hsi_goal, scene_collisions
from model_runtime.skeleton import yaw_matrix
from synthetic import library_of, rigid_clip

STEP = 0.12   # m per frame: 1.2 m/s at 10 fps


def _walk_along_minus_y(frames: int) -> tuple[np.ndarray, np.ndarray]:
    return rigid_clip(np.outer(np.arange(frames) * STEP, [0.0, -1.0]), 0.0)   # yaw 0 faces -Y


@pytest.fixture(scope="module")
def lib():
    stand = np.tile([[4.0, 1.0]], (60, 1)) + np.random.default_rng(0).normal(0, 0.005, (60, 2))
    return library_of([("walk", "a person walks forward", "cmu", _walk_along_minus_y(160)),
                       ("stand", "a person stands", "cmu", rigid_clip(stand, 1.0)),
                       ("bow", "a person bows", "bandai", rigid_clip(np.tile([[-3.0, 0.0]], (60, 1)), -1.0))])


def _lateral(xy: np.ndarray) -> np.ndarray:
    """Signed distance from the -Y axis through the start (the walk's original line)."""
    return xy[:, 0] - xy[0, 0]


def test_detour_profile_swings_out_and_back_and_ends_straight():
    angle, hold = math.radians(40.0), 8
    y = detour_profile(80, onset=5, angle=angle, hold=hold)
    assert np.all(y[:6] == 0)
    assert y.max() == pytest.approx(angle) and y.min() == pytest.approx(-angle)
    assert np.allclose(y[5 + detour_frames(angle, hold):], 0.0)


def test_bend_path_leaves_the_line_and_rejoins_it(lib):
    a, b = lib.offsets[0], lib.offsets[1]
    rot, pel = lib.rotations[a:b][:70], lib.pelvis[a:b][:70]
    angle, hold, onset = math.radians(40.0), 10, 5
    yaw = detour_profile(len(pel), onset, angle, hold)
    rot2, pel2 = bend_path(rot, pel, yaw)
    assert np.allclose(rot2[:, 1:], rot[:, 1:])                       # only the root turns
    lat = _lateral(pel2[:, :2])
    assert np.abs(lat).max() > 0.7                                    # about 1 m out at 1.2 m/s
    assert abs(lat[-1]) < 0.02                                        # back on the line
    steps = np.linalg.norm(np.diff(pel2[:, :2], axis=0), axis=1)
    assert np.allclose(steps, STEP, atol=1e-5)                        # same pace, only the direction turns
    tmp = ClipLibrary(["x", "y"], ["", ""], ["cmu"] * 2, np.concatenate((rot, rot2)), np.concatenate((pel, pel2)),
                      np.array([0, len(pel), 2 * len(pel)]), [])
    j0, j1 = clip_joints(tmp, 0), clip_joints(tmp, 1)
    k = onset + 8                                                     # mid swing-out: the body turned with the path
    r = yaw_matrix(torch.tensor(yaw[k])).numpy()
    assert np.abs((j1[k] - j1[k, :1]) - (j0[k] - j0[k, :1]) @ r.T).max() < 1e-4


def test_slow_to_rest_eases_the_last_steps_to_a_stop(lib):
    a = lib.offsets[0]
    rot, pel = lib.rotations[a:a + 30], lib.pelvis[a:a + 30]
    rot2, pel2 = slow_to_rest(rot, pel)
    assert len(pel2) == 30 - SLOW_IN + SLOW_OUT
    steps = np.linalg.norm(np.diff(pel2[:, :2], axis=0), axis=1)
    assert steps[-SLOW_OUT] == pytest.approx(STEP, rel=0.15)         # starts at walking pace
    assert np.all(np.diff(steps[-SLOW_OUT:]) < 1e-6)                 # then only slows
    assert steps[-1] < 0.15 * STEP
    assert np.allclose(pel2[-1], pel[-1], atol=1e-5)                 # ends where the walk's last frame was


def test_add_arrivals_makes_detour_and_stop_copies_that_end_standing(lib):
    out, new = add_arrivals(lib, list(range(len(lib))), seed=3)
    assert [out.names[i] for i in new] == ["walk#detour0", "walk#detour1", "walk#arrive2"]
    for i in new:
        assert out.captions[i] == "a person walks forward" and out.sources[i] == "cmu"
        assert out.is_held_out(i) == lib.is_held_out(0)
        j = clip_joints(out, i)
        speed = np.linalg.norm(np.diff(j[-10:, 0, :2], axis=0), axis=1).mean() * 10
        assert speed < 0.2, (out.names[i], speed)                   # ends standing
        start_speed = np.linalg.norm(j[5, 0, :2] - j[4, 0, :2]) * 10
        assert start_speed == pytest.approx(1.2, rel=0.1)             # starts walking
        # the standing part is the real standing clip: its arm keeps moving as in the source
        a = out.offsets[i + 1]
        assert not np.allclose(out.rotations[a - 1, 16], out.rotations[a - 8, 16])
    assert len(out) == len(lib) + 3 and out.names[:3] == lib.names
    again, _ = add_arrivals(lib, list(range(len(lib))), seed=3)
    assert np.array_equal(again.pelvis, out.pelvis)                   # deterministic


def test_detour_scenes_put_a_box_on_the_straight_line_between_start_and_goal(lib):
    out, new = add_arrivals(lib, list(range(len(lib))), seed=3)
    scenes = build_hsi_scenes(out, new, seed=0)
    detours = [s for s in scenes if s.kind == "detour"]
    assert detours and all(out.names[s.ego].split("#")[1].startswith("detour") for s in detours)
    for s in detours:
        j = clip_joints(out, s.ego)
        assert np.allclose(s.goal[:2], j[-1, 0, :2], atol=1e-5) and s.goal[2] == 0   # stop here
        centre = s.vertices[:, :2].mean(0)
        start, goal = j[0, 0, :2], s.goal[:2]
        u = (goal - start) / np.linalg.norm(goal - start)
        along = float((centre - start) @ u)
        assert 0.3 < along < float(np.linalg.norm(goal - start)) - 0.3             # between start and goal
        assert abs(float((centre - start) @ np.array([-u[1], u[0]]))) < 0.15         # on the line
        assert scene_collisions(s.grid(), j) == 0


def test_a_clip_still_walking_at_its_end_gets_a_goal_ahead(lib):
    j = clip_joints(lib, 0)
    path = analyse_path(j)
    goal = hsi_goal(j, path, "walk")
    ahead = float((goal[:2] - j[-1, 0, :2]) @ np.array([0.0, -1.0]))
    assert ahead == pytest.approx(min(2.5, 1.5 * path.end_speed), abs=0.05)
    stand = clip_joints(lib, 1)
    assert np.allclose(hsi_goal(stand, analyse_path(stand), "stand")[:2], stand[-1, 0, :2])
