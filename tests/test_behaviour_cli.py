"""The behaviour suite's command line: what --prior-only, --no-control, --no-fwsr, --no-cleanup and
--final-guidance-share roll out."""
import json

from model_runtime.behaviour.__main__ import main


def _report(capsys, *flags):
    assert main(["--families", "walk_forward", "--episodes", "1", "--json", *flags]) == 0
    return json.loads(capsys.readouterr().out)


def test_prior_only_runs_alpha_0_without_fwsr_cleanup_or_control(capsys):
    report = _report(capsys, "--prior-only")
    assert report["prior_only"] is True and report["control"] is False
    assert list(report["families"]["walk_forward"]) == ["alpha=0"]
    from model_runtime import load_model
    from model_runtime.behaviour import metrics as M
    from model_runtime.behaviour.scenarios import draw_episodes
    from model_runtime.behaviour.suite import roll_out
    ego = roll_out(load_model(), draw_episodes("walk_forward", "val", 1)[0], 0.0, fwsr=False, cleanup=False,
                   control=False)
    assert abs(report["families"]["walk_forward"]["alpha=0"]["abs_net_yaw_mean_deg"]
               - abs(M.net_yaw_deg(ego, 20.0))) < 1e-3


def test_no_control_is_recorded_and_runs_both_alphas(capsys):
    report = _report(capsys, "--no-control")
    assert report["control"] is False and "prior_only" not in report
    assert list(report["families"]["walk_forward"]) == ["alpha=0", "alpha=1"]


def test_no_fwsr_and_no_cleanup_roll_out_without_them(capsys):
    report = _report(capsys, "--no-fwsr", "--no-cleanup")
    assert report["fwsr"] is False and report["cleanup"] is False and report["control"] is True
    from model_runtime import load_model
    from model_runtime.behaviour import metrics as M
    from model_runtime.behaviour.scenarios import draw_episodes
    from model_runtime.behaviour.suite import roll_out
    ego = roll_out(load_model(), draw_episodes("walk_forward", "val", 1)[0], 1.0, fwsr=False, cleanup=False)
    assert abs(report["families"]["walk_forward"]["alpha=1"]["abs_net_yaw_mean_deg"]
               - abs(M.net_yaw_deg(ego, 20.0))) < 1e-3


def test_control_set_overrides_a_control_setting_and_alphas_picks_the_runs(capsys):
    report = _report(capsys, "--alphas", "1", "--control-set", "seam_steers=0")
    assert list(report["families"]["walk_forward"]) == ["alpha=1"]
    assert report["control_config"] == {"seam_steers": "0"}
    from dataclasses import replace

    from model_runtime import ControlConfig, load_model
    from model_runtime.behaviour import metrics as M
    from model_runtime.behaviour.scenarios import draw_episodes
    from model_runtime.behaviour.suite import roll_out
    ego = roll_out(load_model(), draw_episodes("walk_forward", "val", 1)[0], 1.0,
                   control_config=replace(ControlConfig(), seam_steers=0))
    assert abs(report["families"]["walk_forward"]["alpha=1"]["abs_net_yaw_mean_deg"]
               - abs(M.net_yaw_deg(ego, 20.0))) < 1e-3


def test_a_bad_control_setting_is_one_line_before_any_rollout(capsys):
    import pytest
    for bad, words in (("nonsense=1", "NAME=VALUE with NAME one of"), ("seam_steers=x", "is not a number"),
                       ("step_size=-1", "must be a finite number >= 0")):
        with pytest.raises(SystemExit) as stop:
            main(["--families", "walk_forward", "--episodes", "1", "--control-set", bad])
        assert stop.value.code == 2
        err = capsys.readouterr().err.strip().splitlines()[-1]
        assert words in err, err


def test_the_final_guidance_share_is_recorded_and_one_outside_0_to_1_refused(capsys):
    assert _report(capsys, "--final-guidance-share", "0.5")["final_guidance_share"] == 0.5
    assert main(["--families", "walk_forward", "--episodes", "1", "--final-guidance-share", "1.5"]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert "final guidance share must be a number in 0..1" in captured.err.strip().splitlines()[-1]
