"""Slowed copies of forward walks (model_runtime.data.slowed_walks): walking slowly, made from real walks."""
import numpy as np
import pytest

from model_runtime.checkpoint import load_model
from model_runtime.data.mirror import add_mirrors
from model_runtime.data.reversals import mean_speed
from model_runtime.data.slowed_walks import SLOW_RATES, add_slowed_walks, slow_down, slowed_caption
from model_runtime.training.recipe import SLOWED_WALK_WEIGHT
from model_runtime.training.samples import SegmentSampler
from synthetic import library_of, rigid_clip, walking_clip


@pytest.fixture(scope="module")
def lib():
    return library_of([("walk", "a person walks forward, tired", "bandai", walking_clip(40, 1.1, 0.0, yaw0=0.4)),
                       ("turn", "a person walks and turns left", "cmu", walking_clip(40, 1.1, 0.3)),
                       ("run", "a person runs", "cmu", walking_clip(40, 2.8, 0.0)),
                       ("idle", "a person walks", "cmu", rigid_clip(np.tile([[1.0, 2.0]], (40, 1)), 0.0)),
                       ("dash", "a person walks", "cmu", walking_clip(40, 3.0, 0.0))])


def test_only_plain_forward_walks_get_the_slow_caption():
    assert slowed_caption("a person walks forward, tired") == "a person walks slowly, tired"
    assert slowed_caption("a person walks") == "a person walks slowly"
    for other in ("a person walks and turns left", "a person walks backwards", "a person runs"):
        assert slowed_caption(other) is None


def test_slowing_down_keeps_the_path_and_stretches_the_time():
    clip = walking_clip(21, 1.0, 0.0)
    rot, pel = slow_down(*clip, 0.5)
    assert len(pel) == 41
    # every other frame is a source frame; the ones between lie halfway along the path
    src_rot, src_pel = clip
    assert np.allclose(pel[::2], src_pel, atol=1e-6)
    assert np.allclose(pel[1::2], 0.5 * (src_pel[:-1] + src_pel[1:]), atol=1e-6)
    assert np.allclose(np.abs(rot[::2]), np.abs(src_rot), atol=1e-5)
    assert mean_speed(pel) == pytest.approx(0.5 * mean_speed(src_pel), rel=1e-6)


def test_a_slowed_copy_walks_the_same_path_at_a_slow_pace(lib):
    out, new = add_slowed_walks(lib, list(range(len(lib))))
    # the turning walk, the run, the standing "walk" and the 3 m/s "walk" (too fast when slowed) get no copy
    assert [out.names[i] for i in new] == ["walk#slowed0"]
    i = new[0]
    assert out.captions[i] == "a person walks slowly, tired" and out.sources[i] == "bandai"
    assert out.is_held_out(i) == lib.is_held_out(0)
    a, b = out.offsets[i], out.offsets[i + 1]
    rate = mean_speed(out.pelvis[a:b]) / mean_speed(lib.pelvis[:40])
    assert SLOW_RATES[0] - 1e-3 <= rate <= SLOW_RATES[1] + 1e-3
    assert b - a == pytest.approx(39 / rate + 1, abs=1.0)
    # it starts where the walk starts and stops less than one source frame (0.11 m) short of its end
    assert np.allclose(out.pelvis[a], lib.pelvis[0])
    assert np.linalg.norm(out.pelvis[b - 1] - lib.pelvis[39]) < 0.11


def test_slowed_copies_of_mirrored_walks_are_named_apart_and_drawn_less_often(lib):
    mirrored, _ = add_mirrors(lib, list(range(len(lib))))
    out, new = add_slowed_walks(mirrored, list(range(len(mirrored))))
    assert sorted(out.names[i] for i in new) == ["walk#slowed0", "walk#slowed1"]
    model = load_model(config="tiny")
    sampler = SegmentSampler(out, [0] + new, model.cfg, model.stats, seed=0)
    w = sampler.weights.numpy()
    # a copy is drawn SLOWED_WALK_WEIGHT times as often as a real walk with as many segment starts
    starts = np.array([out.frames(i) - sampler.span for i in [0] + new], float)
    assert w[1] / w[0] == pytest.approx(SLOWED_WALK_WEIGHT * starts[1] / starts[0])


def test_the_slowed_recipe_adds_slow_walks_to_the_prior_and_no_slow_set_offs(lib):
    from model_runtime.data.library import derived_kind
    from model_runtime.training.recipe import WINDOW_RECIPES
    from model_runtime.training.setup import build_samplers
    model = load_model(config="tiny")
    tr, _ = build_samplers("prior", model, lib, seed=0, rank=0, windows=WINDOW_RECIPES["kicks_slowed"])
    kinds = {derived_kind(n) for n in tr.lib.names}
    assert {"walk#slowed0", "walk#slowed1"} <= set(tr.lib.names) and "startup" in kinds
    # the start-up copies set off into real (or mirrored) clips only
    assert all(n.endswith(("startup0", "startup1")) for n in tr.lib.names if derived_kind(n) == "startup")
    for recipe, stage in (("kicks", "prior"), ("kicks_slowed", "decoder")):
        other, _ = build_samplers(stage, model, lib, seed=0, rank=0, windows=WINDOW_RECIPES[recipe])
        assert "slowed" not in {derived_kind(n) for n in other.lib.names}


def test_the_light_recipe_draws_the_slowed_copies_at_its_own_weight(lib):
    from model_runtime.training.recipe import SLOWED_WALK_WEIGHT_LIGHT, WINDOW_RECIPES
    from model_runtime.training.setup import build_samplers
    model = load_model(config="tiny")
    full, _ = build_samplers("prior", model, lib, seed=0, rank=0, windows=WINDOW_RECIPES["kicks_slowed"])
    light, _ = build_samplers("prior", model, lib, seed=0, rank=0, windows=WINDOW_RECIPES["kicks_slowed_light"])
    assert full.lib.names == light.lib.names and len(full.items) == len(light.items)

    def slowed_over_real(sampler):
        """A slowed copy's draw weight over its real walk's, per segment start."""
        per_start = {sampler.lib.names[i]: w / (sampler.lib.frames(i) - sampler.span)
                     for (i, _), w in zip(sampler.items, sampler.weights.numpy())}
        return per_start["walk#slowed0"] / per_start["walk"]

    assert slowed_over_real(light) == pytest.approx(
        slowed_over_real(full) * SLOWED_WALK_WEIGHT_LIGHT / SLOWED_WALK_WEIGHT)
