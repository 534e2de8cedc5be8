"""Turn-then-walk arrivals (model_runtime.data.turn_arrivals) and the HSI scenes and goals built on them."""
import math

import numpy as np
import pytest

from model_runtime.checkpoint import load_model
from model_runtime.data.library import derived_kind
from model_runtime.data.pairs import analyse_path, build_hsi_scenes, clip_joints, facing_xy, hsi_goal, scene_collisions
from model_runtime.data.turn_arrivals import add_turn_arrivals, turn_frames, turned_stance
from synthetic import library_of, rigid_clip

STEP = 0.12   # m per frame: 1.2 m/s at 10 fps


def _signed_angle(a: np.ndarray, b: np.ndarray) -> float:
    """Degrees from 2-vector a to b, counter-clockwise positive."""
    return math.degrees(math.atan2(a[0] * b[1] - a[1] * b[0], float(a @ b)))


@pytest.fixture(scope="module")
def lib():
    stand = np.tile([[4.0, 1.0]], (60, 1)) + np.random.default_rng(0).normal(0, 0.003, (60, 2))
    walk = rigid_clip(np.outer(np.arange(160) * STEP, [0.0, -1.0]), 0.0)    # yaw 0 faces -Y
    return library_of([("walk", "a person walks forward, tired", "cmu", walk),
                       ("stand", "a person stands", "cmu", rigid_clip(stand, 1.0)),
                       ("bow", "a person bows", "bandai", rigid_clip(np.tile([[-3.0, 0.0]], (60, 1)), -1.0)),
                       # held out (the split holds one clip back): the walk takes its stances from "stand" alone
                       ("idle", "a person stands", "cmu", rigid_clip(stand + [0.0, 3.0], 0.5))])


def test_a_turned_stance_starts_turned_away_and_ends_as_the_stretch(lib):
    a, n = lib.offsets[1], 25
    rot, pel = lib.rotations[a:a + n], lib.pelvis[a:a + n]
    angle = math.radians(135.0)
    t_rot, t_pel = turned_stance(rot, pel, 3, angle)
    done = 3 + turn_frames(angle)
    assert np.allclose(t_rot[done:], rot[done:], atol=1e-6) and np.allclose(t_pel[done:], pel[done:], atol=1e-6)
    first = facing_xy(clip_joints(library_of([("t", "", "cmu", (t_rot, t_pel))]), 0)[:1].astype(np.float64))[0]
    last = facing_xy(clip_joints(lib, 1)[n - 1:n].astype(np.float64))[0]
    assert _signed_angle(first, last) == pytest.approx(135.0, abs=1.0)    # turns back by the angle


def test_copies_stand_turn_toward_the_goal_walk_there_and_stop(lib):
    out, new = add_turn_arrivals(lib, list(range(len(lib))), seed=2)
    assert [out.names[i] for i in new] == ["walk#turnarrive0", "walk#turnarrive1"]    # the only forward walk
    for i in new:
        assert out.captions[i] == lib.captions[0] and out.sources[i] == "cmu"
        assert out.is_held_out(i) == lib.is_held_out(0)
        j = clip_joints(out, i)
        speed = np.linalg.norm(np.diff(j[:, 0, :2], axis=0), axis=1) * 10
        assert speed[:2].max() < 0.1 and speed[-8:].max() < 0.2            # stands at both ends
        assert speed.max() == pytest.approx(1.2, rel=0.1)                  # walks at the clip's pace between
        # the goal (where it stops) lies 45-180 degrees off the first frame's facing, in the walk's direction
        facing0 = facing_xy(j[:1].astype(np.float64))[0]
        to_goal = (j[-1, 0, :2] - j[0, 0, :2]).astype(np.float64)
        assert 40.0 <= abs(_signed_angle(facing0, to_goal)) <= 180.0
        assert float(to_goal @ np.array([0.0, -1.0])) / np.linalg.norm(to_goal) > 0.99
        assert np.isfinite(out.rotations).all() and np.isfinite(out.pelvis).all()
    again, _ = add_turn_arrivals(lib, list(range(len(lib))), seed=2)
    assert np.array_equal(again.pelvis, out.pelvis) and np.array_equal(again.rotations, out.rotations)


def test_their_goal_is_where_they_stop_and_their_scenes_leave_the_path_free(lib):
    out, new = add_turn_arrivals(lib, list(range(len(lib))), seed=2)
    for i in new:
        j = clip_joints(out, i)
        assert np.allclose(hsi_goal(j, analyse_path(j), out.names[i])[:2], j[-1, 0, :2], atol=1e-5)
    scenes = build_hsi_scenes(out, new, seed=0, per_clip=2)
    assert scenes and {s.kind for s in scenes} <= {"beside_path", "corridor"}
    for s in scenes:
        assert scene_collisions(s.grid(), clip_joints(out, s.ego)) == 0


def test_the_turns_windows_add_them_to_the_hsi_stage_only(lib):
    from model_runtime.training.recipe import WINDOW_RECIPES
    from model_runtime.training.setup import build_samplers
    model = load_model(config="tiny")
    tr, _ = build_samplers("hsi", model, lib, seed=0, rank=0, windows=WINDOW_RECIPES["turns"])
    kinds = {derived_kind(n) for n in tr.lib.names}
    assert {"turnarrive", "arrive", "detour"} <= kinds
    plain, _ = build_samplers("hsi", model, lib, seed=0, rank=0, windows=WINDOW_RECIPES["captured"])
    assert "turnarrive" not in {derived_kind(n) for n in plain.lib.names}
    prior, _ = build_samplers("prior", model, lib, seed=0, rank=0, windows=WINDOW_RECIPES["turns"])
    assert "turnarrive" not in {derived_kind(n) for n in prior.lib.names}


def test_their_scenes_are_drawn_at_their_weight(lib):
    from model_runtime.data.detours import add_arrivals
    from model_runtime.training.recipe import TURN_ARRIVAL_WEIGHT
    from model_runtime.training.samples import SegmentSampler
    out, stops = add_arrivals(lib, list(range(len(lib))), seed=2)
    out, turns = add_turn_arrivals(out, list(range(len(lib))), seed=2)
    scenes = [s for s in build_hsi_scenes(out, stops + turns, seed=0, per_clip=1) if s.kind != "detour"]
    kinds = {derived_kind(out.names[s.ego]) for s in scenes}
    assert kinds == {"arrive", "turnarrive"}
    model = load_model(config="tiny")
    sampler = SegmentSampler(out, [], model.cfg, model.stats, seed=0, scenes=scenes)
    span = model.cfg.history + model.cfg.future
    per_frame = {derived_kind(out.names[i]): float(sampler.weights[n]) / (out.frames(i) - span)
                 for n, (i, _) in enumerate(sampler.items)}
    assert per_frame["turnarrive"] == pytest.approx(TURN_ARRIVAL_WEIGHT * per_frame["arrive"])
