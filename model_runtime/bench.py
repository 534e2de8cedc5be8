"""Per-frame latency benchmark of the online session.

    python -m model_runtime.bench --json

One JSON object per line: {"config", "mode", "p50_ms", "p99_ms", "mean_ms", "max_ms", "frames", "threads"}.
Modes: "segment" (segment rollout, diffusion spread over the running segment's frames), "fwsr"
(the same plus Frame-wise Segment Refinement every frame), "fwsr-nocontrol" (fwsr without test-time
control), "fwsr-raw" (fwsr without control and without the planted-foot cleanup), "slide" (a full
diffusion every frame, the paper's ablation). Every mode but those two has control and cleanup on, as the
runtime does by default. Batch 1, after warm-up, with a partner walking in, a box scene and a goal,
so both Meta-Interaction Modules run. "groupN" (e.g. group8) times one live tick of N egos stepped as one
ReactionGroup and, interleaved tick by tick in the same run, N separate ReactionSessions stepped one
after another (row mode "separateN"); the group row also gives p50 and p99 of group / separate. Weights
are random unless --model is given: speed does not depend on their values.

--pipeline runs each segment's diffusion in the runtime's helper process (job_worker.py; timed once it has
started), as the Blender extension does by default: the frames are the same, the caller's thread does only the
frames' own work. Steps still come back to back, so a step that starts a segment waits for the helper whenever
it is still on the previous job; --pace S instead steps once every S seconds of wall time, as a live viewport
does (0.1 s: one model frame at real time).

"model" times the networks alone, the work the paper's per-frame latency counts: at each segment start a full
reverse diffusion (the default guidance, both Meta-Interaction Modules) and its decode, and every frame an FWSR
refinement and its decode; no test-time control, cleanup, kinematics or scene voxelisation. It is the one mode
that runs on a GPU (--device cuda, or auto): the session's own work stays on the CPU.
"""
from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np
import torch

from .checkpoint import load_model
from .cli_help import HelpFormatter
from .devices import device_name, resolve_device
from .errors import DEFAULT_GUIDANCE, RemogenError
from .fixtures import BOX_GOAL, approaching_partner, box_scene
from .ego import EgoSettings
from .group import ReactionGroup
from .session import ReactionSession

BEST_THREADS = {"tiny": 1, "default": 1, "paper": 2}  # measured on a 2-core CPU


class _Clock:
    """Back to back (pace 0), or one tick every `pace` seconds of wall time."""

    def __init__(self, pace: float) -> None:
        self.pace, self.next = pace, time.perf_counter()

    def wait(self) -> None:
        if self.pace > 0.0:
            self.next += self.pace
            time.sleep(max(0.0, self.next - time.perf_counter()))


def _started(runner, pipeline: bool) -> bool:
    """Whether the helper process takes the jobs (waits for its start, as a live session is a second in)."""
    return bool(pipeline and runner.helper_ready(timeout=60.0))


def run_case(model, mode: str, frames: int, warmup: int, scene, pipeline: bool = False, pace: float = 0.0) -> dict:
    session = ReactionSession(model, text="walk to the person and wave", seed=0,
                              alpha={"hhi": 1.0, "hsi": 1.0}, guidance=DEFAULT_GUIDANCE,
                              fwsr=mode.startswith("fwsr"), scene=scene, slide=(mode == "slide"),
                              cleanup=(mode != "fwsr-raw"), control=mode not in ("fwsr-raw", "fwsr-nocontrol"),
                              pipeline=pipeline)
    helper = _started(session, pipeline)
    session.reset(root_position=(0.0, 0.0, 0.0), yaw=0.0)
    partner = approaching_partner(warmup + frames)
    goal = BOX_GOAL
    times, clock = [], _Clock(pace)
    for i in range(warmup + frames):
        t0 = time.perf_counter()
        session.step(partner=partner[i], goal=goal)
        dt = (time.perf_counter() - t0) * 1000.0
        if i >= warmup:
            times.append(dt)
        clock.wait()
    return {**_percentiles(times), "helper_process": helper}


@torch.no_grad()
def run_model_case(model, frames: int, warmup: int, device: torch.device) -> dict:
    """Per-frame time of the networks alone on `device` (see the module docstring), synchronised per frame."""
    cfg = model.cfg
    model.to(device).eval()
    gen = torch.Generator().manual_seed(0)
    res = cfg.voxel_resolution
    hist = torch.randn(1, cfg.history, cfg.feature_dim, generator=gen).to(device)
    partner = torch.randn(1, cfg.partner_window, 22, 3, generator=gen).to(device)
    present = torch.ones(1, cfg.partner_window, dtype=torch.bool, device=device)
    occupancy = (torch.rand(1, res, res, res, generator=gen) < 0.1).float().to(device)
    goal = torch.tensor([[0.0, -3.0, 0.0]], device=device)
    text = model.encode_text("walk to the person and wave").to(device)
    alpha = {"hhi": 1.0, "hsi": 1.0}
    sync = torch.cuda.synchronize if device.type == "cuda" else (lambda: None)
    times, z0 = [], None
    for i in range(warmup + frames):
        sync()
        t0 = time.perf_counter()
        f = i % cfg.future
        if f == 0:
            ctx = model.encode_contexts(partner, present, occupancy, goal, alpha)
            z0 = model.sample_latent(hist, text, ctx, alpha, 5.0, gen)
            model.decode(hist, z0)
        z = model.refine(z0, hist, partner[:, -cfg.history:], present[:, -cfg.history:], f)
        model.decode(hist, z)[:, f].cpu()   # the frame the runtime hands on, back in host memory
        sync()
        if i >= warmup:
            times.append((time.perf_counter() - t0) * 1000.0)
    model.cpu()
    return _percentiles(times)


def _group_size(mode: str) -> int:
    try:
        n = int(mode[len("group"):])
    except ValueError:
        n = 0
    if n < 1:
        raise SystemExit(f"bench: mode {mode!r} needs a number of egos, e.g. group8")
    return n


def _percentiles(times: list[float]) -> dict:
    a = np.asarray(times)
    return {"p50_ms": round(float(np.percentile(a, 50)), 3), "p99_ms": round(float(np.percentile(a, 99)), 3),
            "mean_ms": round(float(a.mean()), 3), "max_ms": round(float(a.max()), 3), "frames": len(a)}


def run_group_case(model, egos: int, frames: int, warmup: int, scene, pipeline: bool = False,
                   pace: float = 0.0) -> tuple[dict, dict]:
    """Live ticks of `egos` egos in a row 1.2 m apart, the partner walking up to the middle: as one group,
    and as separate sessions stepped one after another in the same ticks. Returns (group, separate)."""
    text, alpha = "walk to the person and wave", {"hhi": 1.0, "hsi": 1.0}
    xs = [(i - (egos - 1) / 2) * 1.2 for i in range(egos)]
    goals = [(x, BOX_GOAL[1], 0.0) for x in xs]
    group = ReactionGroup(model, [EgoSettings(text=text, seed=i, alpha=alpha) for i in range(egos)], scene=scene,
                          pipeline=pipeline)
    helper = _started(group, pipeline)
    group.reset(root_positions=[(x, 0.0, 0.0) for x in xs], yaws=[0.0] * egos)
    sessions = []
    for i, x in enumerate(xs):
        s = ReactionSession(model, text=text, seed=i, alpha=alpha, scene=scene, pipeline=pipeline)
        s.reset(root_position=(x, 0.0, 0.0), yaw=0.0)
        sessions.append(s)
    partner = approaching_partner(warmup + frames)
    together, apart, clock = [], [], _Clock(pace)
    for i in range(warmup + frames):
        t0 = time.perf_counter()
        group.step(partner=partner[i], goals=goals)
        t1 = time.perf_counter()
        for s, g in zip(sessions, goals):
            s.step(partner=partner[i], goal=g)
        t2 = time.perf_counter()
        if i >= warmup:
            together.append((t1 - t0) * 1000.0)
            apart.append((t2 - t1) * 1000.0)
        clock.wait()
    return {**_percentiles(together), "helper_process": helper}, {**_percentiles(apart), "helper_process": helper}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m model_runtime.bench", description=__doc__.split("\n\n")[0],
                                 formatter_class=HelpFormatter)
    ap.add_argument("--json", action="store_true", help="print JSON lines only")
    ap.add_argument("--configs", default="default,paper", help="comma-separated model presets: tiny, default, paper")
    ap.add_argument("--modes", default="segment,fwsr,fwsr-nocontrol,fwsr-raw,slide,group8",
                    help="comma-separated modes: model (the networks alone), segment, fwsr, fwsr-nocontrol (no test-time control), "
                         "fwsr-raw (no control, no foot cleanup), slide, groupN (N egos as one group against "
                         "N separate sessions, e.g. group8)")
    ap.add_argument("--frames", type=int, default=300, help="timed frames per case (segment and fwsr modes)")
    ap.add_argument("--slide-frames", type=int, default=300, help="timed frames for the (slow) slide mode")
    ap.add_argument("--warmup", type=int, default=24, help="untimed frames before timing")
    ap.add_argument("--threads", type=int, default=0, help="torch threads (0 = the measured best per config)")
    ap.add_argument("--model", default=None, help="a model file instead of random weights (its config is used)")
    ap.add_argument("--device", default="cpu", help="cpu, cuda or auto; anything but cpu runs the model mode only")
    ap.add_argument("--pipeline", action="store_true",
                    help="run each segment's diffusion in the helper process (as the Blender extension does)")
    ap.add_argument("--pace", type=float, default=0.0,
                    help="seconds of wall time per step (0.1: real time, as a live viewport); 0 = back to back")
    ap.add_argument("--precisions", default="fp32,bf16:paper,int8:paper",
                    help="precisions to run; 'bf16:paper' = bf16 for the paper config only")
    args = ap.parse_args(argv)
    if args.device not in ("cpu", "auto") and set(args.modes.split(",")) != {"model"}:
        raise SystemExit(f"bench: only the model mode runs on {args.device}; pass --modes model")
    try:
        device = resolve_device(args.device)   # auto: the model mode on a GPU, the session modes on the CPU
    except RemogenError as exc:
        raise SystemExit(f"bench: {exc}") from None
    scene = box_scene()
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
                common = {"threads": threads, "precision": prec, "scene": scene is not None,
                          "device": device_name(device) if mode == "model" else "cpu",
                          "pipeline": args.pipeline, "pace_s": args.pace}
                if mode.startswith("group"):
                    egos = _group_size(mode)
                    together, apart = run_group_case(model, egos, args.frames, args.warmup, scene, args.pipeline,
                                                     args.pace)
                    ratio = {f"ratio_{k}": round(together[k] / apart[k], 3) for k in ("p50_ms", "p99_ms")}
                    found = [{"config": cfg, "mode": mode, **together, **ratio, "egos": egos, **common},
                             {"config": cfg, "mode": f"separate{egos}", **apart, "egos": egos, **common}]
                elif mode == "model":
                    found = [{"config": cfg, "mode": mode, **run_model_case(model, args.frames, args.warmup, device),
                              **common}]
                else:
                    n = args.slide_frames if mode == "slide" else args.frames
                    found = [{"config": cfg, "mode": mode,
                              **run_case(model, mode, n, args.warmup, scene, args.pipeline, args.pace), **common}]
                for row in found:
                    rows.append(row)
                    print(json.dumps(row), flush=True)
            by_mode = {r["mode"]: r for r in rows if r["config"] == cfg and r["precision"] == prec}
            if not args.json and "fwsr" in by_mode and "slide" in by_mode:
                ratio = by_mode["fwsr"]["p50_ms"] / by_mode["slide"]["p50_ms"]
                print(f"# {cfg} {prec}: fwsr p50 / slide p50 = {ratio:.3f}", file=sys.stderr)
            for mode, row in by_mode.items():
                if not args.json and mode.startswith("group"):
                    print(f"# {cfg} {prec}: {mode} p50 {row['p50_ms']} ms, {row['ratio_p50_ms']:.3f} of "
                          f"{row['egos']} separate sessions", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
