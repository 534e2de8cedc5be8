"""Two-person takes: the pair loader keeps both actors in one world frame, and the real-pair evaluation compares
the ego's path with the real person's.

Synthetic takes are written to tmp_path; real CMU takes come from REMOGEN_TWO_PERSON_DIR (tests/paths.py) and
are skipped without it.
"""
import numpy as np
import pytest

from model_runtime.data.two_person import load_pair, load_pairs, pair_files
from model_runtime.errors import InputError
from model_runtime.evaluation.real_pairs import (evaluate_takes, main as real_pairs_main, path_comparison, replay,
                                                start_frame, start_frames)
from paths import two_person_dir
from synthetic import humanoid_bvh, scaled_copy


def test_actors_keep_their_placement_in_one_world_frame(tmp_path):
    a, _ = humanoid_bvh(tmp_path / "a.bvh", fps=120, seconds=2.0, unit=0.01)
    b = scaled_copy(a, tmp_path / "b.bvh", scale=1.2, shift_x=150.0)     # 1.2x taller, 1.5 m to the side
    take = load_pair(a, b, caption="two walkers")
    assert take.frames == take.b.joints.shape[0] == 21
    # one common scale for the scene: A at SMPL-X size (1.0), B at 1/1.2; their mean
    common = (1.0 + 1 / 1.2) / 2
    assert take.a.fit_error_mm["scale"] == pytest.approx(common, rel=1e-6)
    assert take.b.fit_error_mm["scale"] == pytest.approx(common, rel=1e-6)
    d = take.b.joints[:, 0, :2] - take.a.joints[:, 0, :2]
    assert np.allclose(d[:, 0], 1.5 * common, atol=0.02)                 # side by side, 1.5 m apart at scene scale
    assert np.abs(d[:, 1]).max() < 0.02                                   # walking abreast
    assert take.text == "two walkers"


def test_a_rest_frame_in_one_file_drops_the_frame_from_both(tmp_path):
    a, _ = humanoid_bvh(tmp_path / "a.bvh", fps=120, amplitude=40, rest_frame=True)
    b = scaled_copy(humanoid_bvh(tmp_path / "b0.bvh", fps=120, amplitude=40)[0], tmp_path / "b.bvh", shift_x=100.0)
    with pytest.warns(UserWarning, match="dropped .* from both"):
        take = load_pair(a, b)
    assert take.a.joints.shape == take.b.joints.shape


def test_files_of_different_rates_are_refused(tmp_path):
    a, _ = humanoid_bvh(tmp_path / "a.bvh", fps=120)
    b, _ = humanoid_bvh(tmp_path / "b.bvh", fps=60)
    with pytest.raises(InputError, match="differ in frame rate"):
        load_pair(a, b)


def test_cmu_names_pair_up_and_pairs_csv_overrides(tmp_path):
    for rel in ("020/20_05.bvh", "021/21_05.bvh", "020/20_07.bvh"):
        (tmp_path / rel).parent.mkdir(exist_ok=True)
        humanoid_bvh(tmp_path / rel, fps=120, seconds=1.0)
    takes = pair_files(tmp_path)
    assert [(t.name, t.a.name, t.b.name) for t in takes] == [("20_21_05", "20_05.bvh", "21_05.bvh")]
    (tmp_path / "pairs.csv").write_text("a,b,caption,text\n020/20_07.bvh,021/21_05.bvh,a march,a person marches\n")
    (listed,) = pair_files(tmp_path)
    assert (listed.a.name, listed.caption, listed.text) == ("20_07.bvh", "a march", "a person marches")
    (tmp_path / "pairs.csv").write_text("a,b\n020/20_07.bvh,021/21_99.bvh\n")
    with pytest.raises(InputError, match="line 2: .*21_99.bvh does not exist"):
        pair_files(tmp_path)


def test_a_folder_without_takes_says_what_to_add(tmp_path):
    humanoid_bvh(tmp_path / "walk.bvh", fps=120, seconds=1.0)
    with pytest.raises(InputError, match="no two-person take"):
        pair_files(tmp_path)


# ------------------------------------------------------------------------------ the evaluation

def _walker(frames=12, x=0.0, speed=1.0):
    """(T, 22, 3): a stick body of 22 joints on a vertical line, walking along +Y."""
    t = np.arange(frames)[:, None] / 10.0
    body = np.zeros((frames, 22, 3))
    body[:, :, 0] = x
    body[:, :, 1] = speed * t
    body[:, :, 2] = np.linspace(0.0, 1.6, 22)[None]
    return body


def test_an_ego_on_the_real_path_scores_zero_distance():
    real, partner = _walker(), _walker(x=1.0)
    same = path_comparison(real, real, partner)
    assert same["mean_distance_m"] == same["final_distance_m"] == 0.0
    assert same["min_clearance_m"] == pytest.approx(1.0)
    assert same["travel_m"] == pytest.approx(1.1)
    off = path_comparison(real + np.array([0.3, 0.4, 0.0]), real, partner)
    assert off["mean_distance_m"] == pytest.approx(0.5) and off["final_distance_m"] == pytest.approx(0.5)
    assert off["min_clearance_m"] == pytest.approx(np.hypot(0.7, 0.4))                 # frame by frame


def test_replay_starts_as_person_b_and_reports_both_alphas(tiny_model, tmp_path):
    a, _ = humanoid_bvh(tmp_path / "a.bvh", fps=120, seconds=1.0, unit=0.01)
    b = scaled_copy(a, tmp_path / "b.bvh", shift_x=120.0)
    take = load_pair(a, b, name="walkers", caption="two walkers")
    ego = replay(tiny_model, take, seed=0, alpha_hhi=1.0)
    assert ego.shape == take.b.joints.shape and np.isfinite(ego).all()
    k = start_frames(tiny_model, take)
    assert k == tiny_model.cfg.history                           # B's first frames: the model's history
    assert np.allclose(ego[:k], take.b.joints[:k])
    assert not np.allclose(ego[k], take.b.joints[k])             # then the model's own frames
    report = evaluate_takes(tiny_model, [take], seeds=(0,))
    entry = report["takes"]["walkers"]
    assert set(entry) >= {"alpha1", "alpha0", "real"}
    assert entry["real"]["min_clearance_m"] == pytest.approx(
        path_comparison(take.b.joints, take.b.joints, take.a.joints)["min_clearance_m"])
    assert report["overall"]["alpha1"] == entry["alpha1"]


def test_replay_without_control_is_a_session_without_control(tiny_model, tmp_path):
    from model_runtime.session import ReactionSession
    a, _ = humanoid_bvh(tmp_path / "a.bvh", fps=120, seconds=1.0, unit=0.01)
    b = scaled_copy(a, tmp_path / "b.bvh", shift_x=60.0)                 # close enough for the partner cost
    take = load_pair(a, b, name="walkers", caption="two walkers")
    k = start_frames(tiny_model, take)
    s = ReactionSession(tiny_model, text=take.text, seed=3, alpha={"hhi": 1.0, "hsi": 1.0}, control=False)
    s.reset(frame=[start_frame(take.b, i) for i in range(k)])
    expected = [s.step(partner=take.a.joints[i]).joints for i in range(k, take.frames)]
    off = replay(tiny_model, take, seed=3, alpha_hhi=1.0, control=False)
    assert np.allclose(off[k:], np.stack(expected))
    assert not np.allclose(off[k:], replay(tiny_model, take, seed=3, alpha_hhi=1.0)[k:])   # control on differs


def test_command_line_writes_json_and_one_plot_per_take(tmp_path, capsys, monkeypatch):
    import json

    from model_runtime import load_model
    import model_runtime.checkpoint as checkpoint
    monkeypatch.setattr(checkpoint, "load_model", lambda path=None: load_model(config="tiny", seed=0))
    folder = tmp_path / "takes"
    folder.mkdir()
    a, _ = humanoid_bvh(folder / "a.bvh", fps=120, seconds=0.6)
    scaled_copy(a, folder / "b.bvh", shift_x=120.0)
    (folder / "pairs.csv").write_text("a,b,caption\na.bvh,b.bvh,two walkers\n")
    assert real_pairs_main(["--two-person", str(folder), "--seeds", "0", "--json", "--plots", str(tmp_path / "p")]) == 0
    out = json.loads(capsys.readouterr().out)
    assert set(out["takes"]) == {"a+b"} and (tmp_path / "p" / "a+b.png").is_file() and out["control"] is True
    assert real_pairs_main(["--two-person", str(folder), "--seeds", "0", "--json", "--no-control"]) == 0
    assert json.loads(capsys.readouterr().out)["control"] is False
    assert real_pairs_main(["--two-person", str(tmp_path / "missing")]) == 2
    assert "not found" in capsys.readouterr().err


# ------------------------------------------------------------------------------ real CMU takes

def test_real_takes_share_one_floor_and_world():
    takes = load_pairs(two_person_dir())
    assert takes
    for t in takes:
        a, b = t.a.joints, t.b.joints
        assert a.shape == b.shape and np.isfinite(a).all() and np.isfinite(b).all()
        for j in (a, b):
            assert abs(float(j[:, [7, 8, 10, 11], 2].min()) - 0.02) < 0.01       # soles on the common floor
            assert 0.7 < float(np.median(j[:, 0, 2])) < 1.1                        # standing adults
        gap = np.linalg.norm(a[:, 0, :2] - b[:, 0, :2], axis=-1)
        assert gap.min() > 0.2 and gap.max() < 10.0
        if t.caption in ("synchronized walk", "soldiers march"):                   # abreast, same direction
            da, db = a[-1, 0, :2] - a[0, 0, :2], b[-1, 0, :2] - b[0, 0, :2]
            assert np.dot(da, db) / (np.linalg.norm(da) * np.linalg.norm(db)) > 0.9
            assert 0.5 < gap.mean() < 1.2
