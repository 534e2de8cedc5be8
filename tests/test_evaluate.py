"""Evaluation metrics on hand-made trajectories with known answers, and one end-to-end smoke run."""
import json
import math

import numpy as np
import pytest

from model_runtime.evaluate import main as evaluate_main
from model_runtime.evaluation import metrics as ev
from model_runtime.data.library import ClipLibrary, held_out
from model_runtime.skeleton import rest_joints, standing_pelvis_height
from model_runtime.voxel import OccupancyGrid

from synthetic import walking_clip


def _standing_body(at=(0.0, 0.0)) -> np.ndarray:
    """(22, 3) rest body on the floor (soles at z = 0, foot joints 2 cm up), facing -Y."""
    return rest_joints().numpy() + np.array([at[0], at[1], standing_pelvis_height()], np.float32)


def _moving(velocity, frames=20) -> np.ndarray:
    """Rest body translated at a constant velocity (m/s) for `frames` frames at 10 fps."""
    t = np.arange(frames)[:, None, None] / 10.0
    return _standing_body()[None] + t * np.asarray(velocity, np.float64)


def test_sliding_grounded_feet_at_1_m_s_is_10_cm_per_frame():
    assert ev.foot_skating_cm(_moving((1.0, 0.0, 0.0))) == pytest.approx(10.0, abs=1e-3)
    assert ev.foot_skating_cm(_moving((0.0, 0.0, 0.0))) == pytest.approx(0.0, abs=1e-6)
    flying = _moving((1.0, 0.0, 0.0)) + np.array([0.0, 0.0, 0.5])
    assert math.isnan(ev.foot_skating_cm(flying))           # no grounded foot: nothing to measure


def test_jerk_of_constant_velocity_is_zero_and_of_a_cubic_is_six():
    assert ev.peak_jerk(_moving((1.3, -0.4, 0.0))) == pytest.approx(0.0, abs=1e-6)
    t = np.arange(12) / 10.0
    cubic = _standing_body()[None] + np.stack((t ** 3, 0 * t, 0 * t), -1)[:, None, :]
    assert ev.peak_jerk(cubic) == pytest.approx(6.0, rel=1e-6)    # d3(t^3)/dt3 = 6 m/s^3
    assert math.isnan(ev.peak_jerk(cubic[:3]))


def test_constant_velocity_baseline_is_exact_on_constant_velocity_motion():
    motion = _moving((0.8, 0.5, 0.0), frames=10)
    pred = ev.constant_velocity(motion[:2], 8)
    assert pred.shape == (8, 22, 3)
    assert ev.joint_error_mm(pred, motion[2:]) == pytest.approx(0.0, abs=1e-6)
    assert ev.joint_error_mm(motion + np.array([0.03, 0.0, 0.0]), motion) == pytest.approx(30.0, abs=1e-3)
    batched = ev.constant_velocity(np.stack((motion[:2], motion[:2])), 8)   # leading batch axis
    assert np.allclose(batched[1], pred)


def test_facing_error_toward_the_partner():
    ego = _standing_body()      # faces -Y (its hips are 2 degrees off symmetric in the SMPL-X rest pose)
    assert ev.facing_error_deg(ego, np.array([0.0, -2.0])) == pytest.approx(0.0, abs=3.0)
    assert ev.facing_error_deg(ego, np.array([0.0, 2.0, 1.0])) == pytest.approx(180.0, abs=3.0)
    assert ev.facing_error_deg(ego, np.array([2.0, 0.0])) == pytest.approx(90.0, abs=3.0)
    many = ev.facing_error_deg(np.stack((ego, ego)), np.array([[0.0, -1.0], [0.0, 1.0]]))
    assert np.allclose(many, [0.0, 180.0], atol=3.0)


def test_clearance_and_collisions():
    a = np.zeros((3, 1, 3))
    b = np.tile(np.array([[[3.0, 4.0, 0.0]]]), (3, 1, 1))
    b[1] = [[0.6, 0.8, 0.0]]
    assert ev.min_body_clearance(a, b) == pytest.approx(1.0)
    box = np.array([[x, y, z] for x in (0.0, 1.0) for y in (0.0, 1.0) for z in (0.0, 2.0)])
    faces = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                      [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    grid = OccupancyGrid.from_triangles(box, faces, voxel_size=0.05)
    traj = np.array([[[-1.0, 0.5, 1.0]], [[0.5, 0.5, 1.0]], [[0.5, 0.5, 1.8]], [[2.0, 0.5, 1.0]]])
    # frame 1 is inside; frame 2 is inside too but above 1.5 m, which does not count
    assert ev.collision_frames(traj, grid).tolist() == [False, True, False, False]
    assert ev.collision_percent(traj, grid) == pytest.approx(25.0)


def _tiny_library(path) -> None:
    """A few walking clips, most of them in the held-out split (names chosen by the split's hash)."""
    names = [f"synthetic_{i:03d}" for i in range(400)]
    val = [n for n in names if held_out(n)][:3]
    train = [n for n in names if not held_out(n)][:2]
    rots, pels, off = [], [], [0]
    for k, name in enumerate(val + train):
        q, p = walking_clip(30, 1.0 + 0.1 * k, (0.0, math.pi / 2, 0.0, -math.pi / 2, 0.0)[k], start=(k, 0.0))
        rots.append(q)
        pels.append(p)
        off.append(off[-1] + len(p))
    n = len(val + train)
    ClipLibrary(val + train, ["a person walks"] * n, ["cmu"] * n, np.concatenate(rots), np.concatenate(pels),
                np.asarray(off, np.int64), [0.0] * n).save(path)


def test_evaluate_main_smoke(tmp_path, capsys):
    from model_runtime import load_model, save_model
    model_path = save_model(load_model(config="tiny", seed=0), tmp_path / "tiny.pt")
    lib_path = tmp_path / "clips.npz"
    _tiny_library(lib_path)
    logs = tmp_path / "train"
    logs.mkdir()
    with (logs / "vae.log.jsonl").open("w") as fh:
        for step in range(1, 41):
            row = {"stage": "vae", "step": step, "loss": 1.0 / step}
            if step % 10 == 0:
                row["val_loss"] = 1.2 / step
            fh.write(json.dumps(row) + "\n")
    plots = tmp_path / "plots"
    rc = evaluate_main(["--data", str(tmp_path / "no_data_needed"), "--library", str(lib_path),
                        "--model", str(model_path), "--json", "--plots", str(plots), "--logs", str(logs),
                        "--rollouts", "2", "--rollout-frames", "12", "--scenario-frames", "12", "--seeds", "0",
                        "--windows", "16"])
    out = capsys.readouterr().out.strip().splitlines()
    assert rc == 0 and len(out) == 1
    res = json.loads(out[0])
    assert res["held_out_clips"] == 3 and res["windows"] > 0
    for v in (res["vae_reconstruction_mm"], res["next_segment_mm"]["prior"], res["next_segment_mm"]["constant_velocity"],
              res["peak_jerk_m_s3"]["rollout"], res["peak_jerk_m_s3"]["ground_truth"]):
        assert isinstance(v, float) and v >= 0
    inter = res["interaction"]
    for key in ("facing_error_deg", "min_clearance_m", "collision_percent", "goal_distance_m", "goal_closest_m"):
        assert set(inter[key]) == {"alpha1", "alpha0"}
        assert all(isinstance(x, float) for x in inter[key].values())
    assert 0 <= inter["facing_error_deg"]["alpha1"] <= 180
    assert sorted(res["plots"]) == sorted([str(plots / "training_curves.png"), str(plots / "reaction_strip.png")])
    for p in res["plots"]:
        with open(p, "rb") as fh:
            assert fh.read(8) == b"\x89PNG\r\n\x1a\n"


def test_missing_library_and_data_is_one_line_error(tmp_path, capsys):
    rc = evaluate_main(["--data", str(tmp_path / "nowhere"), "--library", str(tmp_path / "none.npz"), "--json"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and err.startswith("error:") and "nowhere" in err
