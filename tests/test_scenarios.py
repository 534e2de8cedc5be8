"""Behaviour of the shipped default model in scripted interaction scenarios.

alpha = 0 (prior only) is the contrast that shows the Meta-Interaction Modules do the work.
"""
import math

import pytest

from model_runtime import load_model
from model_runtime.checkpoint import DEFAULT_WEIGHTS
from model_runtime.evaluate import box_scenario, partner_scenario

pytestmark = pytest.mark.skipif(not DEFAULT_WEIGHTS.exists(), reason="no shipped default weights")

# The box scenario: the issue asks that the ego reach the goal without entering the box. Measured (seeds 0, 1):
# HSI on, 0 % of frames in the box, its pelvis comes within 0.10 m of the goal on average (0.14, 0.06), against
# 20 % in the box prior-only (it walks through the box and on). Over seeds 0-11 none touches the box and all pass
# within 0.05-0.27 m of the goal. What it does not do yet is stop there: half the rollouts arrive at 0.9-1.8 m/s
# (frames 38-49) and drift on, ending 0.67 m from the goal on average over seeds 0-1 (seed 0 1.19 m, seed 1
# 0.15 m; seeds 0-11 0.49 m), so the stricter "still within 0.5 m at the end" test is a strict expected failure.
# It learned the detour from the synthetic detour-and-stop copies of data/detours.py (before them: 20 % and
# 3.0 m); the open data has no walk-around paths and no stops at a target (MODEL_CARD.md).
# The partner scenario passes (seeds 0, 1): facing error 26 deg, clearance 0.64 m vs prior-only 85 deg; it
# needed the pivot-turned clips of data/turns.py (without them 103 vs 89 deg). It does not hang on float
# rounding: with every weight scaled by 1 + 1e-3 * N(0, 1) (4 draws) it measured 25.7-26.1 deg, 0.64-0.65 m.
NOT_LEARNED_YET = pytest.mark.xfail(strict=True, reason="shipped weights do not stop at the goal yet")

# the partner walks 3 m at 1.2 m/s (2.5 s) and stops at 1 m; we look one second of model time later
PARTNER_FRAMES = 25 + 10
BOX_FRAMES = 60


@pytest.fixture(scope="module")
def model():
    return load_model()


def test_ego_turns_to_face_an_approaching_partner(model):
    yaws = (math.pi / 2, -math.pi / 2)   # the ego starts side-on to the partner
    on, _ = partner_scenario(model, PARTNER_FRAMES, {"hhi": 1.0, "hsi": 0.0}, seeds=(0, 1), yaws=yaws)
    off, _ = partner_scenario(model, PARTNER_FRAMES, {"hhi": 0.0, "hsi": 0.0}, seeds=(0, 1), yaws=yaws)
    assert on["facing_error_deg"] < 30.0, on
    assert on["min_clearance_m"] > 0.3, on
    assert off["facing_error_deg"] > on["facing_error_deg"] + 20.0, (on, off)


@pytest.fixture(scope="module")
def box_runs(model):
    return (box_scenario(model, BOX_FRAMES, {"hhi": 0.0, "hsi": 1.0}, seeds=(0, 1)),
            box_scenario(model, BOX_FRAMES, {"hhi": 0.0, "hsi": 0.0}, seeds=(0, 1)))


def test_ego_reaches_a_goal_around_a_box(box_runs):
    """The issue's words: the ego reaches the goal without entering the box; prior-only walks through it."""
    on, off = box_runs
    assert on["collision_percent"] == 0.0, on
    assert on["goal_closest_m"] < 0.5, on
    assert off["collision_percent"] > 0, off


@NOT_LEARNED_YET
def test_ego_stops_at_the_goal_around_a_box(box_runs):
    """Stricter than the issue: the ego is still within 0.5 m of the goal when the 6 s end (it walks on past it)."""
    on, off = box_runs
    assert on["collision_percent"] == 0.0, on
    assert on["goal_distance_m"] < 0.5, on
    assert off["goal_distance_m"] > on["goal_distance_m"] + 0.5 or off["collision_percent"] > 0, (on, off)
