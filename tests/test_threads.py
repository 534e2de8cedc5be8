"""A seed gives the same frames at any PyTorch thread count (checked in a fresh process: the math
library reads its reproducibility setting once, at its first matrix product)."""
import json
import os
import subprocess
import sys

from paths import ROOT

ROLLOUT = """
import json, sys
import numpy as np, torch
from model_runtime import ReactionSession, load_model, rest_joints_np, standing_pelvis_height
partner = rest_joints_np() * np.array([-1.0, -1.0, 1.0]) + np.array([0.3, -1.5, standing_pelvis_height()])
worst = {}
for config in sys.argv[1:]:
    model = load_model(config=config, seed=0)
    runs = []
    for threads in (1, 2):
        torch.set_num_threads(threads)
        s = ReactionSession(model, text="walk to the person and wave", seed=0)
        s.reset(yaw=0.3)
        runs.append(np.stack([s.step(partner=partner, goal=(0.0, -3.0, 0.0)).joints for _ in range(10)]))
    worst[config] = float(np.abs(runs[0] - runs[1]).max())
print(json.dumps(worst))
"""


def test_same_frames_at_one_and_two_threads():
    """Default and paper presets (random weights; the paper sizes were the ones that drifted). Ten frames
    cover a segment's decode, its FWSR re-decodes and the next segment's spread diffusion."""
    env = {k: v for k, v in os.environ.items() if k not in ("MKL_CBWR", "OMP_NUM_THREADS", "MKL_NUM_THREADS")}
    env["PYTHONPATH"] = str(ROOT)
    out = subprocess.run([sys.executable, "-c", ROLLOUT, "default", "paper"], env=env, cwd=ROOT,
                         capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    assert json.loads(out.stdout.splitlines()[-1]) == {"default": 0.0, "paper": 0.0}
