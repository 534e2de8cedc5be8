"""Start-up copies (model_runtime.data.startups) and the slow-walk captions of training windows."""
import numpy as np
import pytest
import torch

from model_runtime.checkpoint import load_model
from model_runtime.data.mirror import add_mirrors
from model_runtime.data.pairs import clip_joints, facing_xy
from model_runtime.data.startups import (BLEND_FRAMES, SPEED_IN, SPEED_OUT, add_startups, speed_up_from_rest,
                                         starts_moving)
from model_runtime.features import features_from_pose
from model_runtime.skeleton import quat_to_matrix
from model_runtime.training.samples import SegmentSampler, slow_walk_caption, window_speed
from synthetic import library_of, rigid_clip, walking_clip

STEP = 0.25   # m per frame: 2.5 m/s at 10 fps


@pytest.fixture(scope="module")
def lib():
    stand = np.tile([[4.0, 1.0]], (40, 1)) + np.random.default_rng(0).normal(0, 0.003, (40, 2))
    return library_of([("run", "a person runs forward, happily", "bandai", walking_clip(40, 2.5, 0.0, yaw0=0.7)),
                       ("stand", "a person stands", "cmu", rigid_clip(stand, 1.0)),
                       ("wave", "a person waves", "bandai", rigid_clip(np.tile([[-3.0, 0.0]], (40, 1)), -1.0)),
                       ("slow", "a person walks", "cmu", rigid_clip(np.outer(np.arange(40) * 0.01, [0, -1]), 0.0))])


def test_speed_up_from_rest_starts_still_and_reaches_the_clips_pace(lib):
    a = lib.offsets[0]
    rot, pel = lib.rotations[a:a + 30], lib.pelvis[a:a + 30]
    rot2, pel2 = speed_up_from_rest(rot, pel)
    assert len(pel2) == 30 - SPEED_IN + SPEED_OUT
    steps = np.linalg.norm(np.diff(pel2[:, :2], axis=0), axis=1)
    assert steps[0] < 0.1 * STEP                                      # sets off from rest
    assert np.all(np.diff(steps[:SPEED_OUT - 1]) > 0)                 # only speeds up
    assert steps[SPEED_OUT] == pytest.approx(STEP, rel=0.05)          # then the clip as captured
    assert np.allclose(pel2[0], pel[0]) and np.allclose(pel2[SPEED_OUT:], pel[SPEED_IN:])


def test_start_up_copies_stand_then_set_off_where_and_as_the_clip_starts(lib):
    assert starts_moving(lib.pelvis[:40]) and not starts_moving(lib.pelvis[lib.offsets[3]:lib.offsets[4]])
    out, new = add_startups(lib, list(range(len(lib))), seed=0)
    assert [out.names[i] for i in new] == ["run#startup0"]            # the only clip that starts moving
    i = new[0]
    assert out.captions[i] == lib.captions[0] and out.sources[i] == "bandai"
    assert out.is_held_out(i) == lib.is_held_out(0)
    pel = out.pelvis[out.offsets[i]:out.offsets[i + 1]]
    j = clip_joints(out, i)
    speed = np.linalg.norm(np.diff(pel[:, :2], axis=0), axis=1) * 10
    still = len(pel) - (SPEED_OUT + 8) - BLEND_FRAMES - 6             # well before the cross-fade
    assert speed[:max(still, 1)].max() < 0.1                          # stands ...
    assert speed[-5:].mean() == pytest.approx(2.5, rel=0.1)           # ... then runs at the clip's pace
    # the run itself starts where the real clip starts, facing the way it faces; the stance faces that way too
    k = int(np.argmin(np.linalg.norm(pel[:, :2] - lib.pelvis[0, :2], axis=1)))
    assert np.linalg.norm(pel[k, :2] - lib.pelvis[0, :2]) < 1e-4
    want = facing_xy(clip_joints(lib, 0)[:1].astype(np.float64))[0]
    assert float(facing_xy(j[:1].astype(np.float64))[0] @ want) > 0.999
    assert np.isfinite(out.rotations).all() and np.isfinite(out.pelvis).all()


def test_start_ups_of_mirrored_copies_are_named_apart_and_are_deterministic(lib):
    mirrored, m = add_mirrors(lib, list(range(len(lib))))
    a, new_a = add_startups(mirrored, list(range(len(mirrored))), seed=4)
    b, new_b = add_startups(mirrored, list(range(len(mirrored))), seed=4)
    assert [a.names[i] for i in new_a] == ["run#startup0", "run#startup1"]
    assert np.array_equal(a.pelvis, b.pelvis) and np.array_equal(a.rotations, b.rotations)
    assert a.captions[new_a[1]] == "a person runs forward, happily"


def test_slow_plain_walks_sometimes_train_as_walking_slowly():
    assert slow_walk_caption("a person walks forward, tired") == "a person walks slowly, tired"
    assert slow_walk_caption("a person walks and turns left") == "a person walks slowly"
    assert slow_walk_caption("a person walks backwards") is None and slow_walk_caption("a person runs") is None
    rest = quat_to_matrix(torch.tensor([1.0, 0.0, 0.0, 0.0]).repeat(12, 22, 1))
    def window(speed):
        return features_from_pose(rest, torch.tensor([0.0, speed / 10, 0.0]) * torch.arange(12.0).view(-1, 1))
    slow, brisk = window(0.6), window(1.3)
    assert window_speed(slow) == pytest.approx(0.6, rel=1e-3)
    lib = library_of([("w", "a person walks forward, tired", "cmu", walking_clip(30, 0.6, 0.0))])
    model = load_model(config="tiny")
    s = SegmentSampler(lib, [0], model.cfg, model.stats, seed=0, slow_walk_share=0.5)
    picks = [s._caption(slow, 0) for _ in range(400)]
    share = picks.count("a person walks slowly, tired") / 400
    assert abs(share - 0.5) < 0.1 and set(picks) == {"a person walks slowly, tired", lib.captions[0]}
    assert all(s._caption(brisk, 0) == lib.captions[0] for _ in range(50))
    off = SegmentSampler(lib, [0], model.cfg, model.stats, seed=0, slow_walk_share=0.0)
    assert off._caption(slow, 0) == lib.captions[0]


def test_start_up_copies_are_drawn_at_their_weight(lib):
    from model_runtime.training.recipe import STARTUP_WEIGHT
    out, new = add_startups(lib, list(range(len(lib))), seed=0)
    model = load_model(config="tiny")
    s = SegmentSampler(out, [0, new[0]], model.cfg, model.stats, seed=0)
    span = model.cfg.history + model.cfg.future
    w = {out.names[i]: float(s.weights[k]) for k, (i, _) in enumerate(s.items)}
    ratio = w["run#startup0"] / w["run"]
    assert ratio == pytest.approx(STARTUP_WEIGHT * (out.frames(new[0]) - span) / (out.frames(0) - span))


def test_caption_balance_evens_out_caption_heads_by_their_frames():
    from model_runtime.training.samples import caption_balance, caption_head
    clips = [("a", "a person walks forward, tired", "cmu", rigid_clip(np.zeros((90, 2)), 0.0)),
             ("b", "a person walks forward", "cmu", rigid_clip(np.zeros((10, 2)), 0.0)),
             ("c", "a person kicks", "cmu", rigid_clip(np.zeros((25, 2)), 0.0))]
    lib = library_of(clips)
    assert caption_head("a person walks forward, tired") == "a person walks forward"
    assert np.allclose(caption_balance(lib, [0, 1, 2], 0.0), 1.0)
    f = caption_balance(lib, [0, 1, 2], 0.5)
    share = np.array([90, 10, 25]) * f
    share /= share.sum()
    # head shares go as frame shares to the power 1/2: walking 100 frames, kicking 25 -> 2 : 1
    assert (share[0] + share[1]) / share[2] == pytest.approx(2.0)
    assert f.mean() == pytest.approx(1.0) and f[0] == f[1]


def test_head_shares_set_the_share_of_draws_of_the_named_caption_heads():
    from model_runtime.training.samples import caption_head, with_head_shares
    clips = [("a", "a person walks forward, tired", "cmu", rigid_clip(np.zeros((90, 2)), 0.0)),
             ("b", "a person kicks a ball", "cmu", rigid_clip(np.zeros((25, 2)), 0.0)),
             ("c", "a person kicks, angry", "bandai", rigid_clip(np.zeros((25, 2)), 0.0)),
             ("d", "a person waves", "bandai", rigid_clip(np.zeros((45, 2)), 0.0))]
    lib = library_of(clips)
    heads = [caption_head(c) for c in lib.captions]
    w = with_head_shares(np.array([90.0, 25.0, 25.0, 45.0]), heads, (("a person kicks", 0.3),))
    assert w.sum() == pytest.approx(185.0)                        # the same total
    assert (w[1] + w[2]) / w.sum() == pytest.approx(0.3)           # kicks: 30 % of the draws
    assert w[1] == pytest.approx(w[2]) and w[0] / w[3] == pytest.approx(2.0)   # proportions kept within each side
    assert np.array_equal(with_head_shares(np.array([90.0, 25.0, 25.0, 45.0]), heads, ()), [90, 25, 25, 45])
    assert np.array_equal(with_head_shares(np.array([1.0, 2.0, 3.0, 4.0]), heads, (("a person jumps", 0.5),)),
                          [1, 2, 3, 4])                            # no clip of that head: nothing changes
    model = load_model(config="tiny")
    s = SegmentSampler(lib, [0, 1, 2, 3], model.cfg, model.stats, seed=0, head_shares=(("a person kicks", 0.3),))
    kick_share = sum(float(s.weights[k]) for k, (i, _) in enumerate(s.items) if "kicks" in lib.captions[i])
    assert kick_share == pytest.approx(0.3)                        # the sampler draws kicks 30 % of the time
