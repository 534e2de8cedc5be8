"""The text family's prompts, kinds and targets, its real-clip references and the diversity measure, on
hand-made libraries and the untrained tiny model (no shipped weights or data needed)."""
import json
import math
from collections import Counter

import numpy as np
import pytest

from model_runtime.behaviour.__main__ import _jsonable
from model_runtime.behaviour.__main__ import main as behaviour_main
from model_runtime.behaviour.diversity import DIVERSITY_TARGET, diversity_report, diversity_seeds, real_takes
from model_runtime.behaviour.metrics import text_measures
from model_runtime.behaviour.real_clips import text_reference
from model_runtime.behaviour.scenarios import EPISODES_PER_FAMILY, TEXT_PROMPTS, draw_episodes
from model_runtime.behaviour.suite import run_suite
from model_runtime.behaviour.tables import report_tables
from model_runtime.behaviour.text_targets import KINDS, PROMPT_KINDS, is_held_out, judge_text
from model_runtime.data.phrasings import HELD_OUT_PROMPTS
from synthetic import library_of, rigid_clip


def test_every_prompt_has_a_kind_with_a_statistic_and_enough_are_held_out():
    assert len(TEXT_PROMPTS) >= 20
    assert sum(is_held_out(p) for p in TEXT_PROMPTS) >= 8
    measured = text_measures(np.zeros((3, 22, 3)) + np.arange(22)[None, :, None] * 0.01)
    for p in TEXT_PROMPTS:
        assert PROMPT_KINDS[p] in KINDS, p
        assert KINDS[PROMPT_KINDS[p]].statistic in measured, p
    for p in TEXT_PROMPTS:
        if is_held_out(p):
            assert HELD_OUT_PROMPTS[p] == PROMPT_KINDS[p], p
    for kind in KINDS:                                   # every kind is asked literally and in new words
        prompts = [p for p in TEXT_PROMPTS if PROMPT_KINDS[p] == kind]
        assert any(is_held_out(p) for p in prompts) and not all(is_held_out(p) for p in prompts), kind


def test_the_family_spreads_its_episodes_evenly_over_the_prompts():
    counts = Counter(ep.text for ep in draw_episodes("text", "val"))
    assert set(counts) == set(TEXT_PROMPTS)
    assert max(counts.values()) - min(counts.values()) <= 1
    assert sum(counts.values()) == EPISODES_PER_FAMILY
    first = {PROMPT_KINDS[ep.text] for ep in draw_episodes("text", "val", len(KINDS))}
    assert first == set(KINDS)                           # a short run already sees every kind


def test_targets_judge_prompts_and_kinds_on_their_means():
    assert KINDS["walk slowly"].judge(0.6) and not KINDS["walk slowly"].judge(1.0)
    assert not KINDS["stand"].judge(0.2) and KINDS["stand"].judge(0.05)
    assert KINDS["dance"].judge(3.0) is None and KINDS["run"].judge(float("nan")) is False
    assert KINDS["run"].target == ">= 2 m/s" and KINDS["walk slowly"].target == "0.4-0.9 m/s"
    held_run = next(p for p in TEXT_PROMPTS if is_held_out(p) and PROMPT_KINDS[p] == "run")
    results = [{"prompt": "a person runs", "speed_mps": 2.5}, {"prompt": "a person runs", "speed_mps": 1.9},
               {"prompt": held_run, "speed_mps": 1.0}, {"prompt": "a person dances", "speed_mps": 0.1,
                                                        "wrist_speed_mps": 1.2},
               {"prompt": "a person does something new", "speed_mps": 0.3}]
    for r in results:
        r.setdefault("wrist_speed_mps", 0.0)
    j = judge_text(results)
    assert j["prompts"]["a person runs"]["measured"] == pytest.approx(2.2)
    assert j["prompts"]["a person runs"]["pass"] is True and j["prompts"][held_run]["pass"] is False
    assert j["prompts"][held_run]["held_out"] is True
    assert j["kinds"]["run"]["measured"] == pytest.approx((2.5 + 1.9 + 1.0) / 3)      # over all episodes
    assert j["kinds"]["run"]["pass"] is False and j["kinds"]["run"]["prompts"] == 2
    assert j["kinds"]["dance"]["pass"] is None and j["kinds"]["dance"]["measured"] == pytest.approx(1.2)
    assert j["prompts"]["a person does something new"]["kind"] is None
    assert j["passed"] == {"prompts": 1, "prompts_judged": 2, "held_out_prompts": 0, "held_out_prompts_judged": 1,
                           "kinds": 0, "kinds_judged": 1}


def straight(frames: int, velocity_xy, start=(0.0, 0.0)) -> np.ndarray:
    return np.asarray(start) + np.outer(np.arange(frames) / 10.0, velocity_xy)


@pytest.fixture(scope="module")
def small_library():
    """Hand-made clips: a run at 2.5 m/s, two backward walks at 1 m/s, a walk (no kind), two takes of one
    jump caption (the same motion started elsewhere, facing elsewhere), two dances with their own details
    (one arm turning at different rates: rigid_clip turns it by 1 rad over the clip)."""
    return library_of([
        ("run", "a person runs", "cmu", rigid_clip(straight(30, (0.0, -2.5)), 0.0)),
        ("back1", "a person walks backwards", "bandai", rigid_clip(straight(30, (0.0, 1.0)), 0.0)),
        ("back2", "a person walks backwards, sadly", "bandai", rigid_clip(straight(40, (-1.0, 0.0)), math.pi / 2)),
        ("walk", "a person walks", "cmu", rigid_clip(straight(30, (0.0, -1.0)), 0.0)),
        ("jump1", "a person jumps", "cmu", rigid_clip(straight(20, (0.0, 0.0)), 0.0)),
        ("jump2", "a person jumps", "cmu", rigid_clip(straight(20, (0.0, 0.0), (2.0, 1.0)), 1.5)),
        ("dance1", "a person dances: small jetes", "cmu", rigid_clip(straight(20, (0.0, 0.0)), 0.0)),
        ("dance2", "a person dances: pirouette", "cmu", rigid_clip(straight(40, (0.5, 0.0)), 0.0)),
    ])


def test_the_real_reference_reads_each_kinds_clips(small_library):
    ref = text_reference(small_library)
    assert ref["run"]["clips"] == 1 and ref["run"]["mean"] == pytest.approx(2.5, rel=1e-4)
    assert ref["backwards"]["clips"] == 2 and ref["backwards"]["mean"] == pytest.approx(180.0, abs=3.0)
    assert ref["backwards"]["split"] == "all"            # fewer than 3 held-out clips of the kind
    assert ref["stand"] == {"statistic": "speed_mps", "clips": 0, "split": None, "mean": None}


def test_real_takes_of_one_caption_and_of_a_caption_head(small_library):
    takes, match = real_takes(small_library, "a person jumps")
    assert match == "caption" and len(takes) == 2
    dances, match = real_takes(small_library, "a person dances")
    assert match == "caption head" and len(dances) == 2
    assert real_takes(small_library, "a person kicks") == ([], "caption head")


def test_diversity_of_the_tiny_model_against_identical_real_takes(tiny_model, small_library):
    d = diversity_report(tiny_model, "val", seeds=2, frames=12, prompts=("a person jumps", "a person dances"),
                         library=small_library)
    jump, dance = d["prompts"]["a person jumps"], d["prompts"]["a person dances"]
    assert jump["real_between_takes_m"] == pytest.approx(0.0, abs=1e-6) and jump["real_pairs"] == 1
    assert jump["ratio"] is None and jump["pass"] is None    # identical real takes: no scale to compare with
    assert dance["real_pairs"] == 1 and dance["real_match"] == "caption head"
    assert dance["ratio"] == pytest.approx(dance["between_seeds_m"] / dance["real_between_takes_m"])
    assert dance["pass"] == (dance["ratio"] >= DIVERSITY_TARGET)
    assert d["seeds"] == 2 and diversity_seeds("val", 2) != diversity_seeds("test", 2)
    alone = diversity_report(tiny_model, "val", seeds=2, frames=12, prompts=("a person jumps",))
    assert alone["prompts"]["a person jumps"]["real_pairs"] == 0 and "absent" in alone["reference"]
    with pytest.raises(ValueError, match="at least 2 seeds"):
        diversity_report(tiny_model, "val", seeds=1)


def test_the_suite_reports_text_targets_references_and_tables(tiny_model, small_library, tmp_path, capsys):
    report = run_suite(tiny_model, "val", families=("text",), episodes=2, alphas=(1.0,), keep_tracks=0,
                       library=small_library)
    s = report["families"]["text"]["alpha=1"]
    assert list(s["prompts"]) == list(TEXT_PROMPTS[:2])
    for p, row in s["prompts"].items():
        kind = KINDS[PROMPT_KINDS[p]]
        assert row["statistic"] == kind.statistic and row["target"] == kind.target
        assert row["pass"] == kind.judge(row["measured"])
    assert report["reference"]["text"]["run"]["clips"] == 1
    assert "absent" in run_suite(tiny_model, "val", families=("text",), episodes=1, alphas=(1.0,),
                                 keep_tracks=0)["reference"]["text"]
    saved = tmp_path / "report.json"
    saved.write_text(json.dumps(_jsonable({k: v for k, v in report.items() if k != "tracks"})))
    assert behaviour_main(["--table", str(saved)]) == 0
    printed = capsys.readouterr().out
    assert printed.strip() == report_tables(json.loads(saved.read_text())).strip()
    assert "| a person runs | run | no | speed_mps |" in printed and "2.50 (1 clip)" in printed


def test_the_table_option_joins_reports_and_keeps_the_real_clip_references(tmp_path, capsys):
    """The partner families and the text family run separately (the text family with a library): joined, the
    tables show both, and the text run's real references win over the other run's "absent" placeholder."""
    text = {"split": "test", "control": True, "families": {"text": {"alpha=1": {"prompts": {}, "kinds": {
        "run": {"prompts": 3, "statistic": "speed_mps", "measured": 2.1, "target": ">= 2 m/s", "pass": True}},
        "passed": {"prompts": 0, "prompts_judged": 0, "held_out_prompts": 0, "held_out_prompts_judged": 0,
                   "kinds": 1, "kinds_judged": 1}}}},
        "reference": {"text": {"run": {"statistic": "speed_mps", "clips": 4, "split": "val", "mean": 2.6}}}}
    partner = {"split": "test", "control": True, "reference": {"text": {"absent": "no clip library given"}},
               "families": {"crossing": {"alpha=1": {"episodes": 48, "percent_under_10cm": 4.2, "seam_ratio": 1.1}}}}
    paths = []
    for name, rep in (("partner", partner), ("text", text)):
        paths.append(tmp_path / f"{name}.json")
        paths[-1].write_text(json.dumps(rep))
    assert behaviour_main(["--table", *map(str, paths)]) == 0
    printed = capsys.readouterr().out
    assert "| >= 90 % at alpha 1 | 95.8 % |" in printed
    assert "| **run: all 3 prompts** | run | | speed_mps | 2.10 | >= 2 m/s | yes | 2.60 (4 held-out clips) |" in printed
    assert behaviour_main(["--table", str(paths[0]), str(paths[0])]) == 2
    assert "more than one report" in capsys.readouterr().err
    other = tmp_path / "val.json"
    other.write_text(json.dumps({**text, "split": "val"}))
    assert behaviour_main(["--table", str(paths[0]), str(other)]) == 2
    assert "differ in split" in capsys.readouterr().err


def test_the_table_option_refuses_a_file_that_is_no_report(tmp_path, capsys):
    bad = tmp_path / "bad.json"
    bad.write_text("[1, 2]")
    assert behaviour_main(["--table", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error:") and "not a behaviour report" in err and "\n" not in err
    assert behaviour_main(["--table", str(tmp_path / "missing.json")]) == 2
    assert "cannot read" in capsys.readouterr().err


def test_targets_table_from_a_hand_made_report():
    from model_runtime.behaviour.tables import report_tables
    fam = {"crossing": {"alpha=1": {"episodes": 48, "percent_under_10cm": 12.5, "seam_ratio": 1.4},
                        "alpha=0": {"episodes": 48, "percent_under_10cm": 80.0, "seam_ratio": 1.1}},
           "stand": {"alpha=1": {"episodes": 48, "drift_mean_m_per_min": 0.25, "seam_ratio": 1.2,
                                 "planted_toe_cm_s": 0.5},
                     "alpha=0": {"episodes": 48, "drift_mean_m_per_min": 0.25, "seam_ratio": 1.2,
                                 "planted_toe_cm_s": 0.5}}}
    table = report_tables({"split": "val", "control": False, "families": fam})
    assert "val split, control off" in table
    assert "| >= 90 % at alpha 1 | 87.5 % | 20.0 % |" in table          # clear = 100 - under
    assert "worst family (crossing at alpha 1; stand at alpha 0) | <= 1.3 | 1.40 | 1.20 |" in table
    assert "| standing drift per minute | <= 0.3 m | 0.25 m | 0.25 m |" in table
    assert "goal" not in table                                          # families not run are left out


def test_targets_table_counts_the_text_family_among_the_seams():
    from model_runtime.behaviour.tables import targets_table
    fam = {"stand": {"alpha=1": {"seam_ratio": 1.16}, "alpha=0": {"seam_ratio": 1.16}},
           "text": {"alpha=1": {"seam_ratio": 1.29}, "alpha=0": {"seam_ratio": 1.29}}}
    table = targets_table({"split": "test", "families": fam})
    assert "worst family (text at alpha 1; text at alpha 0) | <= 1.3 | 1.29 | 1.29 |" in table
    assert "text 1.29 / 1.29" in table
