"""Behaviour of the shipped default model in scripted interaction scenarios (issue 3's acceptance).

alpha = 0 (prior only) is the contrast that shows the Meta-Interaction Modules do the work.
"""
import math

import pytest

from model_runtime import load_model
from model_runtime.checkpoint import DEFAULT_WEIGHTS
from model_runtime.evaluate import box_scenario, partner_scenario

pytestmark = pytest.mark.skipif(not DEFAULT_WEIGHTS.exists(), reason="no shipped default weights")

# The box scenario is a known failure of the shipped weights, kept strict so that a model which passes turns CI
# red until the mark comes off. Measured (seeds 0, 1): HSI on, 0 % of frames in the box, and 0.67 m from the goal
# on average (seed 0 1.19 m, seed 1 0.15 m), against 20 % / 3.4 m prior-only (it walks through the box and on).
# So the half that fails is the stop: over seeds 0-7 none touches the box, 5 end within 0.5 m of the goal
# (0.15-0.38 m), the others 0.52, 0.63 and 1.19 m. It learned that from the synthetic detour-and-stop copies of data/detours.py (before them: 20 % and
# 3.0 m); the open data has no walk-around paths and no stops at a target (MODEL_CARD.md).
# The partner scenario passes (seeds 0, 1): facing error 26 deg, clearance 0.64 m vs prior-only 85 deg; it
# needed the pivot-turned clips of data/turns.py (without them 103 vs 89 deg). It does not hang on float
# rounding: with every weight scaled by 1 + 1e-3 * N(0, 1) (4 draws) it measured 25.7-26.1 deg, 0.64-0.65 m.
NOT_LEARNED_YET = pytest.mark.xfail(strict=True, reason="shipped weights do not show this reaction yet (issue 3)")

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


@NOT_LEARNED_YET
def test_ego_reaches_a_goal_around_a_box(model):
    on = box_scenario(model, BOX_FRAMES, {"hhi": 0.0, "hsi": 1.0}, seeds=(0, 1))
    off = box_scenario(model, BOX_FRAMES, {"hhi": 0.0, "hsi": 0.0}, seeds=(0, 1))
    assert on["collision_percent"] == 0.0, on
    assert on["goal_distance_m"] < 0.5, on
    assert off["goal_distance_m"] > on["goal_distance_m"] + 0.5 or off["collision_percent"] > 0, (on, off)
