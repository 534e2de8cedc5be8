"""The crowd family: seeded layouts of egos walking into each other's way, and its closest-approach measure."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from model_runtime.behaviour.crowd import (KEEP_CLEARANCE, LAYOUTS, closest_approach_m,
                                           draw_crowd_episodes, main, run_crowd, summarize)
from model_runtime.behaviour.scenarios import _facing_dir


def test_episodes_are_fixed_per_split_and_differ_between_splits():
    a, b = draw_crowd_episodes("val", 9), draw_crowd_episodes("val", 4)
    assert [e.positions for e in a[:4]] == [e.positions for e in b]
    assert [e.seeds for e in a[:4]] == [e.seeds for e in b]
    test = draw_crowd_episodes("test", 9)
    assert all(x.positions != y.positions for x, y in zip(a, test))
    assert [e.layout for e in a] == list(LAYOUTS) * 3


@pytest.mark.parametrize("split", ["val", "test"])
def test_every_ego_starts_apart_and_walks_into_the_others_way(split):
    for ep in draw_crowd_episodes(split, 30):
        assert len(ep.seeds) == len(ep.positions) == len(ep.yaws) == (3 if ep.layout == "three" else 2)
        assert len(set(ep.seeds)) == len(ep.seeds)
        xy = [np.asarray(p[:2]) for p in ep.positions]
        for i, (p, yaw) in enumerate(zip(xy, ep.yaws)):
            assert min(np.linalg.norm(p - q) for j, q in enumerate(xy) if j != i) > 1.5
            # every layout meets at the origin: the egos face it (three: within 15 deg)
            assert float(_facing_dir(yaw) @ (-p / np.linalg.norm(p))) >= math.cos(math.radians(15.0)) - 1e-9

def test_head_on_egos_face_each_other():
    for ep in draw_crowd_episodes("val", 12):
        if ep.layout != "head_on":
            continue
        a, b = (np.asarray(p[:2]) for p in ep.positions)
        assert _facing_dir(ep.yaws[0]) == pytest.approx((b - a) / np.linalg.norm(b - a), abs=1e-9)
        assert _facing_dir(ep.yaws[1]) == pytest.approx((a - b) / np.linalg.norm(a - b), abs=1e-9)


def test_closest_approach_on_hand_made_tracks():
    frames = 5
    a = np.zeros((frames, 22, 3))
    b = np.zeros((frames, 22, 3))
    b[:, :, 0] = np.linspace(3.0, 1.0, frames)[:, None]       # walks from 3 m to 1 m away along x
    b[3, 7] = (0.25, 0.0, 0.0)                                 # one joint swings in at frame 3
    c = np.full((frames, 22, 3), 10.0)
    assert closest_approach_m([a, b]) == pytest.approx(0.25)
    assert closest_approach_m([a, c, b]) == pytest.approx(0.25)
    assert closest_approach_m([a, c]) == pytest.approx(math.sqrt(300.0))


def test_summary_counts_episodes_that_keep_clear_per_layout():
    s = summarize([0.5, 0.05, 0.2, KEEP_CLEARANCE], ["head_on", "crossing", "three", "head_on"], [1.0, 5.0, 2.0, 3.0])
    assert s["percent_glide"] == 25.0 and s["peak_pelvis_speed_median_m_s"] == 2.5
    assert s["episodes"] == 4 and s["percent_keep_10cm"] == 75.0
    assert s["percent_keep_10cm_head_on"] == 100.0 and s["percent_keep_10cm_crossing"] == 0.0
    assert s["closest_min_m"] == pytest.approx(0.05) and s["closest_mean_m"] == pytest.approx(0.2125)


def test_run_crowd_rolls_out_every_ego_of_every_episode(tiny_model):
    report = run_crowd(tiny_model, "val", episodes=3, alphas=(1.0, 0.0))
    for key in ("alpha=1", "alpha=0"):
        assert report[key]["episodes"] == 3
        assert len(report["closest"][key]) == 3
        assert all(np.isfinite(c) and c >= 0.0 for c in report["closest"][key])
        assert 0.0 <= report[key]["percent_keep_10cm"] <= 100.0


def test_command_line_writes_a_report_and_rejects_bad_input(tiny_model, tmp_path, monkeypatch, capsys):
    import model_runtime
    monkeypatch.setattr(model_runtime, "load_model", lambda *a, **k: tiny_model)
    out = tmp_path / "crowd.json"
    assert main(["--split", "test", "--episodes", "2", "--alphas", "1", "--json", str(out)]) == 0
    report = json.loads(out.read_text())
    assert report["split"] == "test" and report["alpha=1"]["episodes"] == 2
    assert report["guidance"] == model_runtime.DEFAULT_GUIDANCE
    assert "test crowd alpha=1" in capsys.readouterr().out
    assert main(["--episodes", "0"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: --episodes must be at least 1") and "\n" not in err
    assert main(["--control-set", "glide_weight=-1", "--json", str(tmp_path / "other.json")]) == 2
    err = capsys.readouterr().err.strip()
    assert "glide_weight" in err and "\n" not in err
    assert not (tmp_path / "other.json").exists()
    assert main(["--guidance", "-1", "--json", str(tmp_path / "other.json")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: --guidance must be a number in 0..") and "\n" not in err
    assert not (tmp_path / "other.json").exists()
    assert main(["--episodes", "1", "--alphas", "1", "--guidance", "7", "--json", str(out)]) == 0
    assert json.loads(out.read_text())["guidance"] == 7.0



def test_shipped_egos_among_egos_keep_clearer_with_the_partner_module():
    """The first 12 val crowd episodes with the shipped weights: alpha_HHI 1 keeps 0.10 m in more episodes than
    alpha 0 and comes less close on average. (Over all 48 it keeps 0.10 m in 75 % of them: README lists the
    crowd family's misses.)"""
    from model_runtime import load_model
    from model_runtime.checkpoint import DEFAULT_WEIGHTS
    if not DEFAULT_WEIGHTS.is_file():
        pytest.skip("the shipped weights (model_runtime/weights/default.pt) are not in this checkout")
    model = load_model(DEFAULT_WEIGHTS)
    report = run_crowd(model, "val", episodes=12, alphas=(1.0, 0.0))
    on, off = report["alpha=1"], report["alpha=0"]
    assert on["percent_keep_10cm"] > off["percent_keep_10cm"], (on, off)
    assert on["closest_mean_m"] > off["closest_mean_m"] + 0.1, (on, off)
