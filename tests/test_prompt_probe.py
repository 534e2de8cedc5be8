"""The prompt probe: a prompt's rollouts measured as the text family measures them."""
import json

import numpy as np
import pytest

from model_runtime.behaviour.metrics import text_measures
from model_runtime.behaviour.prompts import SHOWN, main as prompts_main, measure_prompts
from model_runtime.behaviour.scenarios import Episode
from model_runtime.behaviour.suite import roll_out


def test_a_prompt_is_measured_as_a_text_episode_of_the_same_seed(tiny_model):
    report = measure_prompts(tiny_model, ["a person runs"], seeds=(4, 5), frames=20)
    row = report["a person runs"]
    assert len(row["per_seed"]) == 2
    expected = text_measures(roll_out(tiny_model, Episode("text", 0, 5, "a person runs", 20), 1.0))
    assert row["per_seed"][1] == pytest.approx(expected)
    assert row["speed_mps"] == pytest.approx(np.mean([r["speed_mps"] for r in row["per_seed"]]))


def test_the_command_line_prints_a_table_or_json_and_refuses_bad_input(tiny_model, monkeypatch, capsys):
    import model_runtime.checkpoint as checkpoint
    monkeypatch.setattr(checkpoint, "load_model", lambda path=None: tiny_model)
    assert prompts_main(["a person jumps", "--seeds", "0", "--frames", "12"]) == 0
    table = capsys.readouterr().out
    assert "| a person jumps |" in table and all(k in table for k in SHOWN)
    assert prompts_main(["a person jumps", "--seeds", "0,1", "--frames", "12", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["seeds"] == [0, 1] and out["frames"] == 12 and len(out["prompts"]["a person jumps"]["per_seed"]) == 2
    with pytest.raises(SystemExit):
        prompts_main(["a person jumps", "--seeds", "x"])
    assert "--seeds must be comma-separated integers" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        prompts_main(["a person jumps", "--frames", "1"])
    assert "--frames must be at least 2" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        prompts_main(["  "])
    assert "a prompt is empty" in capsys.readouterr().err
