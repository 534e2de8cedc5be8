"""The behaviour suite rolls a family without partner, goal or scene out once for all alphas."""
from dataclasses import replace

import numpy as np
import pytest

from model_runtime import load_model
from model_runtime.behaviour import suite
from model_runtime.behaviour.scenarios import draw_episodes


@pytest.fixture(scope="module")
def model():
    return load_model()


def _short(family: str, n: int = 1, frames: int = 24):
    return [replace(ep, frames=frames, partner=None if ep.partner is None else ep.partner[:frames])
            for ep in draw_episodes(family, "val", n)]


@pytest.mark.parametrize("family", ["text", "walk_forward", "stand"])
def test_without_partner_goal_or_scene_every_alpha_rolls_out_the_same_frames(model, family):
    ep = _short(family)[0]
    assert not suite.has_cue(ep)
    assert np.array_equal(suite.roll_out(model, ep, 0.0), suite.roll_out(model, ep, 1.0))


def test_a_cue_free_family_is_rolled_out_once_and_a_cued_one_at_every_alpha(model, monkeypatch):
    calls = []
    real_roll_out = suite.roll_out

    def counting(m, ep, alpha, **kw):
        calls.append((ep.family, alpha))
        return real_roll_out(m, ep, alpha, **kw)

    monkeypatch.setattr(suite, "roll_out", counting)
    monkeypatch.setattr(suite, "draw_episodes", lambda family, split, n=None: _short(family, 2))
    report = suite.run_suite(model, "val", families=["stand", "crossing"], alphas=(1.0, 0.0))
    assert calls.count(("stand", 1.0)) == 2 and ("stand", 0.0) not in calls
    assert calls.count(("crossing", 1.0)) == 2 and calls.count(("crossing", 0.0)) == 2
    stand = report["families"]["stand"]
    assert stand["alpha=0"]["same_as"] == "alpha=1" and "same_as" not in stand["alpha=1"]
    drop = ("seconds", "same_as")
    assert {k: v for k, v in stand["alpha=0"].items() if k not in drop} == \
        {k: v for k, v in stand["alpha=1"].items() if k not in drop}
    assert len(report["tracks"]["stand"][0.0]) == 2        # the plots draw both alphas
