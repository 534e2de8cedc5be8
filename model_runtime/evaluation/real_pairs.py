"""Held-out evaluation on real two-person captures: the ego replaces person B of a take.

    python -m model_runtime.evaluate --two-person FOLDER [--seeds 0,1,2,3] [--json] [--plots DIR]

For each take of the folder (model_runtime.data.two_person says which files make a take) and each seed, a
ReactionSession continues from person B's first frames (the model's history: two frames, so pose, position,
heading and pace, so a B who is already walking is not made to set off from a stand) with B's prompt, partner A is
replayed frame by frame, and the ego's path is set beside B's real one, with the interaction module on
(alpha_HHI 1) and off (0); test-time control stays as shipped (`--no-control`: off, to see what the modules
learned by themselves). Per take and on average over takes:
    mean_distance_m       horizontal pelvis distance between the ego and real B, mean over the frames the
                          model made
    final_distance_m      the same at the last frame
    min_clearance_m       smallest ego-joint to A-joint distance over the take (real B's under "real")
    travel_m              horizontal pelvis path length (real B's under "real")
Plots: one top view per take (A's path, B's real path, the ego's paths per seed; alpha 1 and alpha 0).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from ..errors import DEFAULT_GUIDANCE
from ..cli_help import HelpFormatter, seeds_option
from ..data.pairs.placement import min_clearance
from .plots import _pyplot, save_figure

ALPHAS = (1.0, 0.0)
METRICS = ("mean_distance_m", "final_distance_m", "min_clearance_m", "travel_m")


def travel(joints: np.ndarray) -> float:
    """Horizontal pelvis path length (m) of (T, 22, 3) joints."""
    return float(np.linalg.norm(np.diff(np.asarray(joints, np.float64)[:, 0, :2], axis=0), axis=-1).sum())


def path_comparison(ego: np.ndarray, real: np.ndarray, partner: np.ndarray, start: int = 1) -> dict:
    """The ego's take against the real person's, both (T, 22, 3) world joints beside the same partner; the
    mean distance counts the frames from `start` on (those before are the real frames the ego started from)."""
    d = np.linalg.norm(np.asarray(ego, np.float64)[:, 0, :2] - np.asarray(real, np.float64)[:, 0, :2], axis=-1)
    after = d[start:] if len(d) > start else d[-1:]
    return {"mean_distance_m": float(after.mean()), "final_distance_m": float(d[-1]),
            "min_clearance_m": min_clearance(ego, partner), "travel_m": travel(ego)}


def start_frame(motion, index: int = 0):
    """Frame `index` of a Motion as an EgoFrame (to start a session from real motion)."""
    from ..ego import EgoFrame
    return EgoFrame(0, motion.joints[index].copy(), motion.root[index].copy(), motion.local_rotations[index].copy())


def start_frames(model, take) -> int:
    """How many of person B's real frames a replay starts from: the model's history (fewer in a very short
    take, which keeps at least one frame to make)."""
    return max(1, min(model.cfg.history, take.frames - 1))


def replay(model, take, *, seed: int, alpha_hhi: float, text: str | None = None,
           guidance: float = DEFAULT_GUIDANCE, control: bool = True) -> np.ndarray:
    """(T, 22, 3): the ego continuing from person B's first frames (start_frames), stepped beside person A's
    replayed frames; `control` False turns test-time control off."""
    from ..session import ReactionSession
    s = ReactionSession(model, text=take.text if text is None else text, seed=seed,
                        alpha={"hhi": alpha_hhi, "hsi": 1.0}, guidance=guidance, control=control)
    k = start_frames(model, take)
    s.reset(frame=[start_frame(take.b, i) for i in range(k)])
    out = np.empty_like(take.b.joints)
    out[:k] = take.b.joints[:k]
    for i in range(k, take.frames):
        out[i] = s.step(partner=take.a.joints[i]).joints
    return out


def _mean(rows: list[dict]) -> dict:
    return {k: float(np.mean([r[k] for r in rows])) for k in METRICS}


def evaluate_takes(model, takes: Sequence, seeds: Sequence[int] = (0, 1, 2, 3), *, text: str | None = None,
                   guidance: float = DEFAULT_GUIDANCE, control: bool = True,
                   progress: Callable[[str], None] | None = None) -> dict:
    """{"takes": {name: {...}}, "overall": {alpha: means}, "tracks": {name: {alpha: [ego joints per seed]}}}."""
    report: dict = {"takes": {}, "overall": {}, "tracks": {}}
    per_alpha: dict[float, list[dict]] = {a: [] for a in ALPHAS}
    for take in takes:
        real = take.b.joints
        entry = {"caption": take.caption, "text": take.text if text is None else text, "frames": take.frames,
                 "seconds": (take.frames - 1) / take.a.fps,
                 "real": {"min_clearance_m": min_clearance(real, take.a.joints), "travel_m": travel(real)}}
        report["tracks"][take.name] = {}
        for alpha in ALPHAS:
            runs, rows = [], []
            for seed in seeds:
                if progress:
                    progress(f"{take.name}: alpha_HHI {alpha:g}, seed {seed}")
                ego = replay(model, take, seed=seed, alpha_hhi=alpha, text=text, guidance=guidance, control=control)
                runs.append(ego)
                rows.append(path_comparison(ego, real, take.a.joints, start=start_frames(model, take)))
            entry[f"alpha{alpha:g}"] = _mean(rows)
            per_alpha[alpha].append(entry[f"alpha{alpha:g}"])
            report["tracks"][take.name][alpha] = runs
        report["takes"][take.name] = entry
    for alpha, rows in per_alpha.items():
        if rows:
            report["overall"][f"alpha{alpha:g}"] = _mean(rows)
    return report


def plot_take(take, runs: dict, out_png: str | Path, seeds: Sequence[int] | None = None) -> Path:
    """Top view: A's pelvis path (red, dashed), B's real path (black), the ego's paths (one colour per seed);
    one panel per alpha, on common axes. Starts are marked with a dot."""
    plt = _pyplot()
    alphas = sorted(runs, reverse=True)
    fig, axes = plt.subplots(1, len(alphas), figsize=(5.0 * len(alphas), 5.0), squeeze=False, sharex=True,
                             sharey=True)
    colours = plt.get_cmap("tab10")
    a, b = take.a.joints[:, 0], take.b.joints[:, 0]
    for ax, alpha in zip(axes[0], alphas):
        ax.plot(a[:, 0], a[:, 1], color="tab:red", ls="--", lw=1.4, label="A (replayed)")
        ax.plot(b[:, 0], b[:, 1], color="k", lw=2.0, label="B (real)")
        for k, ego in enumerate(runs[alpha]):
            seed = seeds[k] if seeds is not None and k < len(seeds) else k
            ax.plot(ego[:, 0, 0], ego[:, 0, 1], color=colours(k % 10), lw=1.1, label=f"ego, seed {seed}")
        for path, c in ((a, "tab:red"), (b, "k")):
            ax.plot(path[0, 0], path[0, 1], marker="o", color=c, ms=5)
        ax.set_aspect("equal")
        ax.grid(alpha=0.3)
        ax.tick_params(labelsize=7)
        ax.set_title(f"{take.name} ({take.caption or take.text}), alpha_HHI {alpha:g}", fontsize=8)
        ax.legend(fontsize=6, loc="best")
    return save_figure(plt, fig, out_png, dpi=100)


def _jsonable(x):
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (float, np.floating)):
        return round(float(x), 4) if np.isfinite(x) else None
    return x


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m model_runtime.evaluate --two-person FOLDER",
                                 description=__doc__.split("\n\n")[0], formatter_class=HelpFormatter)
    ap.add_argument("--two-person", required=True, metavar="FOLDER",
                    help="folder with the two BVH files of each take (a pairs.csv or CMU SS_NN.bvh names)")
    ap.add_argument("--model", default=None, help="model file (default: the shipped weights)")
    ap.add_argument("--seeds", default="0,1,2,3", help="comma-separated seeds per take and alpha")
    ap.add_argument("--text", default=None, help="prompt for the ego in every take (default: each take's own)")
    ap.add_argument("--guidance", type=float, default=DEFAULT_GUIDANCE, help="classifier-free guidance scale")
    ap.add_argument("--no-control", action="store_true",
                    help="test-time control off: what the interaction module does by itself")
    ap.add_argument("--threads", type=int, default=1, help="torch CPU threads")
    ap.add_argument("--json", action="store_true", help="print the report as one JSON object")
    ap.add_argument("--plots", default=None, help="folder for one top-view PNG per take")
    args = ap.parse_args(argv)
    seeds = seeds_option(ap, args.seeds)
    import torch

    from ..checkpoint import load_model
    from ..data.two_person import load_pairs
    from ..errors import RemogenError
    torch.set_num_threads(max(args.threads, 1))
    try:
        takes = load_pairs(args.two_person)
        model = load_model(args.model)
        report = evaluate_takes(model, takes, seeds, text=args.text, guidance=args.guidance,
                                control=not args.no_control, progress=lambda m: print(m, file=sys.stderr, flush=True))
    except RemogenError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    written = []
    if args.plots:
        for take in takes:
            written.append(str(plot_take(take, report["tracks"][take.name], Path(args.plots) / f"{take.name}.png",
                                         seeds)))
    out = {"model": model.meta.get("path", args.model or "default"), "folder": str(args.two_person),
           "seeds": seeds, "control": not args.no_control, "takes": report["takes"], "overall": report["overall"],
           "plots": written}
    print(json.dumps(_jsonable(out)) if args.json else json.dumps(_jsonable(out), indent=2))
    return 0
