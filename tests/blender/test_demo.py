"""The demo command: builds the scene from the shipped CMU clip, bakes, saves demo.blend and a PNG strip."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

bpy = pytest.importorskip("bpy")
ROOT = Path(__file__).resolve().parents[2]


def test_demo_scene_and_strip(tmp_path, tiny_model_file):
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    r = subprocess.run([sys.executable, "-m", "remogen_blender.demo", "--out", str(tmp_path), "--model",
                        str(tiny_model_file), "--shots", "2", "--size", "64"], cwd=tmp_path, env=env,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "remogen demo: baked 118 frames" in r.stdout
    assert (tmp_path / "demo.blend").is_file()
    png = (tmp_path / "demo_strip.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    width, height = int.from_bytes(png[16:20], "big"), int.from_bytes(png[20:24], "big")
    assert (width, height) == (128, 64)


def test_demo_clip_is_small_cmu_data():
    import numpy as np
    clip = np.load(ROOT / "remogen_blender" / "demo_data" / "cmu_05_01_walk.npz")
    assert clip["local_rotations"].shape[1:] == (22, 4) and len(clip["pelvis"]) == len(clip["local_rotations"])
    assert "mocap.cs.cmu.edu" in str(clip["credit"])
    assert (ROOT / "remogen_blender" / "demo_data" / "cmu_05_01_walk.npz").stat().st_size < 100_000
