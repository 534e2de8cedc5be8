"""Held-out evaluation of a model: motion quality, the prior against a baseline, and interaction scenarios.

    python -m model_runtime.evaluate --library runs/clips.npz --json [--model PATH] [--plots runs/eval]
    python -m model_runtime.evaluate --data MOTION_FOLDER ...   # builds the clip cache first when it is missing
    python -m model_runtime.evaluate --behaviour --split val --json --plots DIR   # the behaviour suite
    python -m model_runtime.evaluate --two-person FOLDER --json --plots DIR      # real two-person takes

Runs only on the clip library's held-out split (ClipLibrary.split("val")), never on training clips, and
prints one JSON object:
    vae_reconstruction_mm       encode GT history + future, decode the mean latent, FK, mean joint error
    next_segment_mm             the prior from real history and the clip's caption (default guidance) against
                                a constant-velocity extrapolation of each joint; both on the F future frames
    foot_skating_cm_per_frame   horizontal speed of foot joints whose sole is within 5 cm of the floor,
                                on prior rollouts, with the held-out clips themselves as reference
    peak_jerk_m_s3              max over joints and time of |third difference| * fps^3, same two sources
    interaction                 ReactionSession scenarios with alpha = 1 and alpha = 0 (prior only):
        facing_error_deg        partner walks from 4 m toward the ego and stops at 1 m (the ego starts
                                turned away); angle between the ego's hip facing and the partner, last frame
        min_clearance_m         smallest ego-joint to partner-joint distance in that scenario
        collision_percent       a box on the straight path to a goal: % of frames with an ego joint below
                                1.5 m inside an occupied voxel
        goal_distance_m         how far the ego ends from that goal (does it stop there)
        goal_closest_m          how close its pelvis comes to the goal at any frame (does it get there)
Plots (PNG, matplotlib Agg): training curves from runs/train/*.log.jsonl when present, and a stick-figure
strip (top and side views) of the generated reaction in the partner scenario.

This module is the command line and the report; the parts live in model_runtime.evaluation (metrics,
segments, rollouts, plots) and the scripted scenes in model_runtime.fixtures.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path
from typing import Any, Sequence

import numpy as np
import torch

from .cli_help import HelpFormatter, add_final_guidance_options, set_final_guidance
from .errors import DEFAULT_GUIDANCE, RemogenError
from .evaluation.plots import plot_reaction_strip, plot_training_curves
from .evaluation.rollouts import ALPHA_OFF, ALPHA_ON, box_scenario, evaluate_rollouts, partner_scenario
from .evaluation.segments import evaluate_segments

__all__ = ["evaluate", "load_library", "main", "partner_scenario", "box_scenario"]


def load_library(data: str | None, library: str | None):
    """The clip cache if it exists, else built from the data folder (and saved to `library` if given)."""
    from .data.library import ClipLibrary
    if library and Path(library).exists():
        return ClipLibrary.load(library)
    if not data:
        raise RemogenError(f"clip library {library} not found and no --data folder given; pass --data MOTION_FOLDER "
                           "or build it with python -m model_runtime.data.prepare")
    from .data.prepare import build_library
    lib = build_library(data, skip=(Path(library),) if library else ())
    if library:
        lib.save(library)
    return lib


def _finite(x: Any) -> Any:
    """JSON-safe: NaN/inf become null, floats rounded."""
    if isinstance(x, dict):
        return {k: _finite(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_finite(v) for v in x]
    if isinstance(x, (float, np.floating)):
        return round(float(x), 4) if math.isfinite(float(x)) else None
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def evaluate(model, lib, *, clips: int | None = None, windows: int | None = 512, rollouts: int = 8,
             rollout_frames: int = 60, scenario_frames: int = 60, seeds: Sequence[int] = (0, 1),
             yaws: Sequence[float] = (math.pi / 2, -math.pi / 2, math.pi), guidance: float = DEFAULT_GUIDANCE,
             plots: str | Path | None = None, log_dir: str | Path = "runs/train") -> dict:
    """All metrics as one dict (see the module docstring); writes plots into `plots` when given."""
    h, f = model.cfg.history, model.cfg.future
    val = lib.split("val", min_frames=h + f + 1)
    if not val:
        raise RemogenError(f"the clip library has no held-out clip with at least {h + f + 1} frames; "
                           "add clips or rebuild it with python -m model_runtime.data.prepare")
    if clips is not None:
        val = val[:clips]
    t0 = time.time()
    seg = evaluate_segments(model, lib, val, guidance=guidance, seed=seeds[0] if seeds else 0, limit=windows)
    roll_ids = [val[i] for i in np.linspace(0, len(val) - 1, min(rollouts, len(val))).round().astype(int)] \
        if rollouts > 0 else []
    roll = evaluate_rollouts(model, lib, roll_ids, rollout_frames, guidance=guidance) if roll_ids else {}
    inter: dict[str, dict[str, float]] = {"facing_error_deg": {}, "min_clearance_m": {},
                                           "collision_percent": {}, "goal_distance_m": {}, "goal_closest_m": {}}
    strip = None
    for name, alpha in (("alpha1", ALPHA_ON), ("alpha0", ALPHA_OFF)):
        p, runs = partner_scenario(model, scenario_frames, alpha, seeds, yaws, guidance)
        b = box_scenario(model, scenario_frames, alpha, seeds, guidance)
        for k, v in {**p, **b}.items():
            inter[k][name] = v
        if name == "alpha1" and runs:
            strip = runs[0]
    written = []
    if plots:
        out = Path(plots)
        tc = plot_training_curves(log_dir, out / "training_curves.png")
        if tc is not None:
            written.append(str(tc))
        if strip is not None:
            written.append(str(plot_reaction_strip(strip[0], strip[1], out / "reaction_strip.png",
                                                   title="partner walks in from 4 m and stops at 1 m (alpha = 1)")))
    result = {
        "model": model.meta.get("path", "default"),
        "trained": bool(model.meta.get("trained", False)),
        "held_out_clips": len(val),
        "windows": seg["windows"],
        "vae_reconstruction_mm": seg["vae_mm"],
        "next_segment_mm": {"prior": seg["prior_mm"], "constant_velocity": seg["cv_mm"],
                            "prior_beats_constant_velocity": seg["prior_mm"] < seg["cv_mm"]},
        "foot_skating_cm_per_frame": {"rollout": roll.get("skating_rollout"), "ground_truth": roll.get("skating_gt")},
        "peak_jerk_m_s3": {"rollout": roll.get("jerk_rollout"), "ground_truth": roll.get("jerk_gt")},
        "rollouts": {"count": roll.get("rollouts", 0), "frames": rollout_frames},
        "interaction": {**inter, "scenario_frames": scenario_frames, "runs_per_alpha": len(seeds) * len(yaws)},
        "plots": written,
        "wall_s": time.time() - t0,
    }
    return _finite(result)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    if "--behaviour" in argv:   # the scenario-distribution suite has its own options
        from .behaviour.__main__ import main as behaviour_main
        return behaviour_main([a for a in argv if a != "--behaviour"])
    if any(a == "--two-person" or a.startswith("--two-person=") for a in argv):   # its own options too
        from .evaluation.real_pairs import main as real_pairs_main
        return real_pairs_main(argv)
    ap = argparse.ArgumentParser(prog="python -m model_runtime.evaluate", description=__doc__.split("\n\n")[0],
                                 formatter_class=HelpFormatter)
    ap.add_argument("--behaviour", action="store_true",
                    help="run the behaviour suite instead: --split val|test --json --plots DIR "
                         "(python -m model_runtime.behaviour --help lists its options)")
    ap.add_argument("--two-person", metavar="FOLDER",
                    help="evaluate on real two-person takes instead: the ego replaces person B beside A's replay "
                         "(--two-person FOLDER --help lists its options)")
    ap.add_argument("--library", default="runs/clips.npz",
                    help="clip cache .npz (built from --data and saved here when missing)")
    ap.add_argument("--data", default=None, help="motion folder to build a missing --library from")
    ap.add_argument("--model", default=None, help="model file (default: the shipped weights)")
    ap.add_argument("--json", action="store_true", help="print one JSON line only")
    ap.add_argument("--plots", default="runs/eval", help="folder for PNG plots ('' = none)")
    ap.add_argument("--logs", default="runs/train", help="folder with training *.log.jsonl files")
    ap.add_argument("--clips", type=int, default=None, help="use at most this many held-out clips")
    ap.add_argument("--windows", type=int, default=512, help="at most this many segments for the VAE/prior errors")
    ap.add_argument("--rollouts", type=int, default=8, help="prior rollouts from held-out clips (skating, jerk)")
    ap.add_argument("--rollout-frames", type=int, default=60, help="frames per rollout")
    ap.add_argument("--scenario-frames", type=int, default=60, help="frames per interaction scenario run")
    ap.add_argument("--seeds", default="0,1", help="comma-separated seeds for the scenarios")
    ap.add_argument("--guidance", type=float, default=DEFAULT_GUIDANCE, help="classifier-free guidance scale")
    add_final_guidance_options(ap)
    ap.add_argument("--threads", type=int, default=1,
                    help="torch threads (1: batch-1 session steps are fastest single-threaded, as in bench)")
    args = ap.parse_args(argv)
    if args.threads > 0:
        torch.set_num_threads(args.threads)
    from .checkpoint import load_model
    try:
        seeds = [int(s) for s in args.seeds.split(",") if s.strip()]
        if not seeds:
            raise ValueError
    except ValueError:
        print(f"error: --seeds must be comma-separated integers, got {args.seeds!r}", file=sys.stderr)
        return 2
    if args.scenario_frames < 4 or args.rollout_frames < 4:
        print("error: --scenario-frames and --rollout-frames must be at least 4", file=sys.stderr)
        return 2
    try:
        lib = load_library(args.data, args.library)
        model = load_model(args.model)
        set_final_guidance(model, args)
        model.meta.setdefault("path", str(args.model) if args.model else "default")
        res = evaluate(model, lib, clips=args.clips, windows=args.windows, rollouts=args.rollouts,
                       rollout_frames=args.rollout_frames, scenario_frames=args.scenario_frames, seeds=seeds,
                       guidance=args.guidance, plots=args.plots or None, log_dir=args.logs)
    except RemogenError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(res))
    else:
        print(json.dumps(res, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

