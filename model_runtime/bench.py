"""Per-frame latency benchmark of the online session.

    python -m model_runtime.bench --json

One JSON object per line: {"config", "mode", "p50_ms", "p99_ms", "mean_ms", "max_ms", "frames", "threads"}.
Modes: "segment" (segment rollout, diffusion spread over the running segment's frames), "fwsr"
(the same plus Frame-wise Segment Refinement every frame), "slide" (a full diffusion every frame,
the paper's ablation). Batch 1, after warm-up, with a partner walking in, a box scene and a goal,
so both Meta-Interaction Modules run. Weights are random unless --model is given: speed does not
depend on their values.
"""
from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np
import torch

from .checkpoint import load_model
from .session import ReactionSession
from .skeleton import rest_joints, standing_pelvis_height

BEST_THREADS = {"tiny": 1, "default": 1, "paper": 2}  # measured on the 2-core project machine


def approaching_partner(frames: int, start: float = 4.0, stop: float = 1.0, speed: float = 1.2) -> np.ndarray:
    """(frames, 22, 3) a rest-pose partner walking along -Y towards an ego at the origin, then standing."""
    body = rest_joints().numpy() + np.array([0.0, 0.0, standing_pelvis_height()], np.float32)
    # The ego faces -Y, so the partner stands in front of it at negative y; turned 180 degrees about Z
    # it faces +Y, back towards the ego, while it walks in from y = -start to y = -stop.
    body = body * np.array([-1.0, -1.0, 1.0], np.float32)
    t = np.arange(frames) / 10.0
    y = -np.maximum(start - speed * t, stop)
    return (body[None] + np.stack((np.zeros_like(y), y, np.zeros_like(y)), -1)[:, None, :]).astype(np.float32)


def box_scene():
    """A 0.8 m box 1.5 m in front of the ego (the ego faces -Y), or None when voxel.py is unavailable."""
    from .voxel import OccupancyGrid
    lo, hi = np.array([-0.4, -1.9, 0.0]), np.array([0.4, -1.1, 0.8])
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    faces = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                      [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    return OccupancyGrid.from_triangles(corners, faces, voxel_size=0.05)


def run_case(model, mode: str, frames: int, warmup: int, scene) -> dict:
    session = ReactionSession(model, text="walk to the person and wave", seed=0,
                              alpha={"hhi": 1.0, "hsi": 1.0}, guidance=5.0,
                              fwsr=(mode == "fwsr"), scene=scene, slide=(mode == "slide"))
    session.reset(root_position=(0.0, 0.0, 0.0), yaw=0.0)
    partner = approaching_partner(warmup + frames)
    goal = (0.0, -3.0, 0.0)
    times = []
    for i in range(warmup + frames):
        t0 = time.perf_counter()
        session.step(partner=partner[i], goal=goal)
        dt = (time.perf_counter() - t0) * 1000.0
        if i >= warmup:
            times.append(dt)
    a = np.asarray(times)
    return {"p50_ms": round(float(np.percentile(a, 50)), 3), "p99_ms": round(float(np.percentile(a, 99)), 3),
            "mean_ms": round(float(a.mean()), 3), "max_ms": round(float(a.max()), 3), "frames": len(a)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m model_runtime.bench", description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", action="store_true", help="print JSON lines only")
    ap.add_argument("--configs", default="default,paper")
    ap.add_argument("--modes", default="segment,fwsr,slide")
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--slide-frames", type=int, default=300, help="frames for the (slow) slide mode")
    ap.add_argument("--warmup", type=int, default=24)
    ap.add_argument("--threads", type=int, default=0, help="torch threads (0 = the measured best per config)")
    ap.add_argument("--model", default=None, help="a model file instead of random weights (its config is used)")
    ap.add_argument("--precisions", default="fp32,bf16:paper,int8:paper",
                    help="precisions to run; 'bf16:paper' = bf16 for the paper config only")
    args = ap.parse_args(argv)
    try:
        scene = box_scene()
    except ImportError:
        scene = None
    rows = []
    for cfg in args.configs.split(","):
        threads = args.threads or BEST_THREADS.get(cfg, 2)
        torch.set_num_threads(threads)
        for prec in args.precisions.split(","):
            prec, _, only = prec.partition(":")
            if only and only != cfg:
                continue
            model = load_model(args.model, precision=prec) if args.model else load_model(config=cfg, precision=prec)
            for mode in args.modes.split(","):
                n = args.slide_frames if mode == "slide" else args.frames
                res = run_case(model, mode, n, args.warmup, scene)
                row = {"config": cfg, "mode": mode, **res, "threads": threads, "precision": prec,
                       "scene": scene is not None}
                rows.append(row)
                print(json.dumps(row), flush=True)
            by_mode = {r["mode"]: r for r in rows if r["config"] == cfg and r["precision"] == prec}
            if not args.json and "fwsr" in by_mode and "slide" in by_mode:
                ratio = by_mode["fwsr"]["p50_ms"] / by_mode["slide"]["p50_ms"]
                print(f"# {cfg} {prec}: fwsr p50 / slide p50 = {ratio:.3f}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
