"""Reversed copies of forward walks (model_runtime.data.reversals): walking backwards, made from real walks."""
import numpy as np
import pytest

from model_runtime.data.mirror import add_mirrors
from model_runtime.data.pairs import clip_joints, facing_xy
from model_runtime.data.reversals import add_reversals, mean_speed, reversed_caption
from model_runtime.training.samples import SegmentSampler
from model_runtime.checkpoint import load_model
from synthetic import library_of, rigid_clip, walking_clip


@pytest.fixture(scope="module")
def lib():
    return library_of([("walk", "a person walks forward, tired", "bandai", walking_clip(40, 1.2, 0.0, yaw0=0.4)),
                       ("turn", "a person walks and turns left", "cmu", walking_clip(40, 1.2, 0.3)),
                       ("run", "a person runs", "cmu", walking_clip(40, 2.8, 0.0)),
                       ("idle", "a person walks", "cmu", rigid_clip(np.tile([[1.0, 2.0]], (40, 1)), 0.0)),
                       ("dash", "a person walks", "cmu", walking_clip(40, 3.0, 0.0))])


def test_only_plain_forward_walks_get_a_backward_caption():
    assert reversed_caption("a person walks forward, tired") == "a person walks backwards, tired"
    assert reversed_caption("a person walks") == "a person walks backwards"
    for other in ("a person walks and turns left", "a person walks to the left", "a person runs",
                  "a person walks backwards"):
        assert reversed_caption(other) is None


def test_a_reversed_walk_faces_as_before_and_travels_the_other_way(lib):
    out, new = add_reversals(lib, list(range(len(lib))))
    # the turning walk, the run, the standing "walk" and the 3 m/s "walk" are not reversed
    assert [out.names[i] for i in new] == ["walk#reversed0"]
    i = new[0]
    assert out.captions[i] == "a person walks backwards, tired" and out.sources[i] == "bandai"
    assert out.is_held_out(i) == lib.is_held_out(0)
    a, b = out.offsets[i], out.offsets[i + 1]
    assert np.array_equal(out.pelvis[a:b], lib.pelvis[:40][::-1])
    assert np.array_equal(out.rotations[a:b], lib.rotations[:40][::-1])
    assert mean_speed(out.pelvis[a:b]) == pytest.approx(1.2, rel=0.02)
    # travel against the first frame's facing: forward in the source, backward in the copy
    def travel_vs_facing(library, k):
        j = clip_joints(library, k)
        p = library.pelvis[library.offsets[k]:library.offsets[k + 1], :2].astype(np.float64)
        t = (p[-1] - p[0]) / np.linalg.norm(p[-1] - p[0])
        return np.degrees(np.arccos(np.clip(facing_xy(j[:1].astype(np.float64))[0] @ t, -1, 1)))
    assert travel_vs_facing(lib, 0) < 10 and travel_vs_facing(out, i) > 170


def test_reversed_copies_of_mirrored_walks_are_named_apart_and_drawn_less_often(lib):
    mirrored, m = add_mirrors(lib, list(range(len(lib))))
    out, new = add_reversals(mirrored, list(range(len(mirrored))))
    assert sorted(out.names[i] for i in new) == ["walk#reversed0", "walk#reversed1"]
    model = load_model(config="tiny")
    sampler = SegmentSampler(out, [0] + new, model.cfg, model.stats, seed=0)
    w = sampler.weights.numpy()
    # equal frame counts: each reversed copy is drawn REVERSAL_WEIGHT (0.5) times as often as the real walk
    assert w[1] == pytest.approx(0.5 * w[0]) and w[2] == pytest.approx(0.5 * w[0])


def test_the_reversed_windows_set_off_backwards_too(lib):
    from model_runtime.data.library import derived_kind
    from model_runtime.training.recipe import WINDOW_RECIPES
    from model_runtime.training.setup import build_samplers
    model = load_model(config="tiny")
    tr, _ = build_samplers("prior", model, lib, seed=0, rank=0, windows=WINDOW_RECIPES["reversed"])
    names = set(tr.lib.names)
    assert {"walk#reversed0", "walk#reversed1"} <= names
    # start-up copies of the reversed walks (numbers 2 and 3) keep the backward caption
    backward_startups = [i for i, n in enumerate(tr.lib.names) if n in ("walk#startup2", "walk#startup3")]
    assert backward_startups and all(tr.lib.captions[i] == "a person walks backwards, tired" for i in backward_startups)
    plain, _ = build_samplers("prior", model, lib, seed=0, rank=0, windows=WINDOW_RECIPES["balanced"])
    assert "reversed" not in {derived_kind(n) for n in plain.lib.names}
