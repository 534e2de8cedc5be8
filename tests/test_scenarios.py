"""Behaviour targets of the shipped default model with the runtime's defaults (FWSR, test-time control and
planted-foot cleanup on), on the first 8 episodes of each family of the behaviour suite's val generator, and what
the scene module has learned by itself (control off) on the goal family.

The whole suite (48 episodes a family, val and test splits) is `python -m model_runtime.evaluate --behaviour`;
README lists every target and what it measures. Only targets the model meets are asserted here; the ones it
still misses are listed in README as missed, not hidden behind an expected failure.
"""
from __future__ import annotations

import pytest

from model_runtime import load_model
from model_runtime.behaviour.suite import run_suite
from model_runtime.checkpoint import DEFAULT_WEIGHTS

pytestmark = pytest.mark.skipif(not DEFAULT_WEIGHTS.exists(), reason="no shipped default weights")

EPISODES = 8
# A reach rate of >= 90 % on 8 episodes means none may miss; 24 give the rate a resolution of about 4 %.
REACH_EPISODES = 24


@pytest.fixture(scope="module")
def model():
    return load_model()


def family(model, name: str, alphas=(1.0,), episodes: int = EPISODES) -> dict:
    report = run_suite(model, "val", families=(name,), episodes=episodes, alphas=alphas, keep_tracks=0)
    return report["families"][name]


def test_goal_in_any_direction_is_reached_and_the_ego_stops_there(model):
    s = family(model, "goal", alphas=(0.0, 1.0), episodes=REACH_EPISODES)
    on, off = s["alpha=1"], s["alpha=0"]
    assert on["reach_percent"] >= 90.0, on
    assert on["settle_mean_m"] <= 0.3, on
    assert off["reach_percent"] < on["reach_percent"] - 30.0, (on, off)
    assert on["seam_ratio"] <= 1.3, on
    assert off["seam_ratio"] <= 1.3, off          # the prior alone, walking on past the goal, joins its segments too


def test_the_scene_module_alone_turns_toward_a_goal_in_any_direction_and_reaches_it(model):
    """What the HSI module has learned, without test-time control: goals behind and beside the ego included."""
    def rollouts(alpha):
        report = run_suite(model, "val", families=("goal",), episodes=REACH_EPISODES, alphas=(alpha,),
                           keep_tracks=0, control=False)
        return report["families"]["goal"][f"alpha={alpha:g}"]
    on, off = rollouts(1.0), rollouts(0.0)
    assert on["reach_percent"] >= 70.0, on
    assert off["reach_percent"] < on["reach_percent"] - 30.0, (on, off)


def test_goal_past_obstacles_is_reached_without_walking_into_them(model):
    on = family(model, "obstacles", episodes=REACH_EPISODES)["alpha=1"]
    assert on["reach_percent"] >= 90.0, on
    assert on["settle_mean_m"] <= 0.3, on
    assert on["inside_obstacle_percent"] <= 1.0, on
    assert on["seam_ratio"] <= 1.3, on


def test_partner_crossing_clearance_is_better_with_the_partner_module(model):
    s = family(model, "crossing", alphas=(0.0, 1.0))
    on, off = s["alpha=1"], s["alpha=0"]
    assert on["percent_under_10cm"] < off["percent_under_10cm"], (on, off)
    assert on["min_clearance_mean_m"] > off["min_clearance_mean_m"] + 0.1, (on, off)
    assert on["seam_ratio"] <= 1.3, on


def test_approach_from_any_direction_ends_facing_the_partner(model):
    on = family(model, "approach")["alpha=1"]
    assert on["facing_error_mean_deg"] <= 30.0, on
    assert on["percent_within_45deg"] >= 85.0, on
    assert on["min_clearance_min_m"] >= 0.2, on
    assert on["seam_ratio"] <= 1.3, on


def test_walking_forward_joins_its_segments_keeps_its_feet_and_its_heading(model):
    on = family(model, "walk_forward")["alpha=1"]
    assert on["seam_ratio"] <= 1.3, on
    assert on["planted_toe_cm_s"] <= 5.0, on
    assert on["abs_net_yaw_mean_deg"] <= 20.0, on


def test_standing_stays_put_keeps_its_feet_planted_and_its_segments_joined(model):
    on = family(model, "stand")["alpha=1"]
    assert on["planted_toe_cm_s"] <= 1.0, on
    assert on["seam_ratio"] <= 1.3, on
    assert on["drift_mean_m_per_min"] <= 0.3, on
