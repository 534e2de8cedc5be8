"""The crowd family: two or three egos stepped as one ReactionGroup, walking into each other's way.

The seven families of scenarios.py pit one ego against a replayed partner. Egos among egos are a different
problem: each one reacts to another that is itself reacting, one frame behind. A fixed handful of seeds
says little about that, so this family draws its episodes from the same per-split generator seeds as the
others (val to choose, test to report), in three layouts taken in turn, each aimed at the origin:

- head_on: two egos 3-5 m apart facing each other, up to 0.4 m off the same line
- crossing: two egos 2-3.5 m from a common point, walking at it from directions 45-135 deg apart
- three: three egos on a circle of radius 1.8-2.8 m, each facing its centre within 15 deg

Every ego is told "a person walks forward" with its own seed; an episode lasts 6 s. Measured: the
smallest joint-to-joint distance between any two egos over the episode, and the fastest pelvis step of any
of them (a glide, metrics.GLIDE_SPEED), at alpha_HHI 1 (each ego reacts to the nearest other one, test-time
control on) and at alpha 0 (they ignore each other).

    python -m model_runtime.behaviour.crowd --split val --model FILE [--episodes 48] [--json OUT]
"""
from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import dataclass, field
from itertools import combinations
from typing import Callable, Iterable, Sequence

import numpy as np

from ..checks import check_final_guidance_min_speed, check_final_guidance_share, check_guidance
from ..cli_help import add_final_guidance_options, set_final_guidance
from ..errors import DEFAULT_GUIDANCE, InputError
from .control_overrides import control_config_from
from .metrics import GLIDE_SPEED, finite_mean, min_joint_clearance, peak_pelvis_speed
from .scenarios import EPISODES_PER_FAMILY, SPLIT_SEEDS, WALK_TEXT

LAYOUTS = ("head_on", "crossing", "three")
CROWD_FRAMES = 60                 # 6 s: every layout's egos meet within about 3 s at a walk
KEEP_CLEARANCE = 0.10             # m: an episode "keeps clear" if no two egos' joints come closer
CROWD_STREAM = 100                # the generator stream, apart from the seven families' 0-6


@dataclass
class CrowdEpisode:
    index: int
    layout: str
    seeds: list[int]                              # one noise seed per ego
    positions: list[tuple[float, float, float]]   # world Z-up, pelvis xy on the floor
    yaws: list[float]                             # radians; yaw 0 faces -Y, as ReactionGroup.reset takes it
    text: str = WALK_TEXT
    frames: int = CROWD_FRAMES
    params: dict = field(default_factory=dict)


def _yaw_facing(direction_xy: np.ndarray) -> float:
    """The yaw whose facing is `direction_xy`: the inverse of scenarios._facing_dir (yaw 0 faces -Y)."""
    d = np.asarray(direction_xy, np.float64)
    return float(math.atan2(d[0], -d[1]))


def _unit(angle: float) -> np.ndarray:
    return np.array([math.cos(angle), math.sin(angle)])


def _head_on(rng: np.random.Generator) -> tuple[list[np.ndarray], list[np.ndarray], dict]:
    gap, offset, turn = rng.uniform(3.0, 5.0), rng.uniform(-0.4, 0.4), rng.uniform(-math.pi, math.pi)
    along, across = _unit(turn), _unit(turn + math.pi / 2)
    a = -along * gap / 2 + across * offset / 2
    b = along * gap / 2 - across * offset / 2
    return [a, b], [b - a, a - b], {"gap_m": gap, "offset_m": offset}


def _crossing(rng: np.random.Generator) -> tuple[list[np.ndarray], list[np.ndarray], dict]:
    first = rng.uniform(-math.pi, math.pi)
    between = rng.uniform(math.radians(45.0), math.radians(135.0)) * rng.choice((-1.0, 1.0))
    dists = rng.uniform(2.0, 3.5, 2)
    starts = [-_unit(first) * dists[0], -_unit(first + between) * dists[1]]
    return starts, [-s for s in starts], {"between_deg": math.degrees(between), "distances_m": dists.tolist()}


def _three(rng: np.random.Generator) -> tuple[list[np.ndarray], list[np.ndarray], dict]:
    radius, first = rng.uniform(1.8, 2.8), rng.uniform(-math.pi, math.pi)
    angles = first + np.array([0.0, 2 * math.pi / 3, 4 * math.pi / 3]) + rng.uniform(-0.3, 0.3, 3)
    starts = [_unit(a) * radius for a in angles]
    facing = [_unit(a + math.pi + rng.uniform(-1.0, 1.0) * math.radians(15.0)) for a in angles]
    return starts, facing, {"radius_m": radius}


_LAYOUT_DRAW = {"head_on": _head_on, "crossing": _crossing, "three": _three}


def draw_crowd_episodes(split: str, n: int = EPISODES_PER_FAMILY) -> list[CrowdEpisode]:
    """The split's first n crowd episodes; episode i is the same whatever n is."""
    if split not in SPLIT_SEEDS:
        raise ValueError(f"unknown split {split!r}: pick one of {', '.join(SPLIT_SEEDS)}")
    if n < 1:
        raise ValueError(f"episodes must be at least 1, got {n}")
    rng = np.random.default_rng([SPLIT_SEEDS[split], CROWD_STREAM])
    out = []
    for i in range(n):
        layout = LAYOUTS[i % len(LAYOUTS)]
        starts, facing, params = _LAYOUT_DRAW[layout](rng)
        seeds = [int(s) for s in rng.integers(2 ** 31, size=len(starts))]
        out.append(CrowdEpisode(i, layout, seeds, [(float(p[0]), float(p[1]), 0.0) for p in starts],
                                [_yaw_facing(f) for f in facing], params=params))
    return out


def closest_approach_m(tracks: Sequence[np.ndarray]) -> float:
    """Smallest joint-to-joint distance between any two of the (frames, J, 3) tracks at any frame."""
    return min(min_joint_clearance(a, b) for a, b in combinations(tracks, 2))


def roll_out_crowd(model, ep: CrowdEpisode, alpha: float, guidance: float = DEFAULT_GUIDANCE,
                   **group_options) -> list[np.ndarray]:
    """Each ego's (frames, 22, 3) world joints in one crowd episode, alpha_HHI `alpha` and text guidance
    `guidance` for all."""
    from ..ego import EgoSettings
    from ..group import ReactionGroup
    g = ReactionGroup(model, [EgoSettings(text=ep.text, seed=s, alpha={"hhi": alpha, "hsi": 0.0}, guidance=guidance)
                              for s in ep.seeds], **group_options)
    g.reset(root_positions=ep.positions, yaws=ep.yaws)
    tracks = [np.empty((ep.frames, 22, 3), np.float32) for _ in ep.seeds]
    for f in range(ep.frames):
        for track, frame in zip(tracks, g.step()):
            track[f] = frame.joints
    return tracks


def summarize(closest: Sequence[float], layouts: Sequence[str], peaks: Sequence[float] | None = None) -> dict:
    c = np.asarray(closest, np.float64)
    out = {"episodes": len(c), "percent_keep_10cm": float(100.0 * np.mean(c >= KEEP_CLEARANCE)),
           "closest_mean_m": finite_mean(c), "closest_min_m": float(c.min())}
    if peaks is not None:
        p = np.asarray(peaks, np.float64)
        out["peak_pelvis_speed_median_m_s"] = float(np.median(p))
        out["percent_glide"] = float(100.0 * np.mean(p > GLIDE_SPEED))
    for layout in LAYOUTS:
        mine = [x for x, l in zip(c, layouts) if l == layout]
        if mine:
            out[f"percent_keep_10cm_{layout}"] = float(100.0 * np.mean(np.asarray(mine) >= KEEP_CLEARANCE))
    return out


def run_crowd(model, split: str, *, episodes: int = EPISODES_PER_FAMILY, alphas: Iterable[float] = (1.0, 0.0),
              progress: Callable[[str], None] | None = None, guidance: float = DEFAULT_GUIDANCE,
              **group_options) -> dict:
    """{"alpha=A": summary} plus "closest": {"alpha=A": [per-episode closest approach, m]}."""
    eps = draw_crowd_episodes(split, episodes)
    report: dict = {"split": split, "family": "crowd", "guidance": guidance, "closest": {}}
    for alpha in alphas:
        t0 = time.perf_counter()
        closest, peaks = [], []
        for ep in eps:
            tracks = roll_out_crowd(model, ep, alpha, guidance, **group_options)
            closest.append(closest_approach_m(tracks))
            peaks.append(max(peak_pelvis_speed(t) for t in tracks))
        key = f"alpha={alpha:g}"
        report[key] = dict(summarize(closest, [ep.layout for ep in eps], peaks),
                           seconds=round(time.perf_counter() - t0, 1))
        report["closest"][key] = [round(c, 4) for c in closest]
        if progress:
            progress(f"crowd {key}: {len(eps)} episodes in {report[key]['seconds']} s")
    return report


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m model_runtime.behaviour.crowd",
                                 description="Egos among egos: closest approach of 2-3 egos walking into each "
                                             "other's way, at alpha_HHI 1 and 0.")
    ap.add_argument("--split", choices=tuple(SPLIT_SEEDS), default="val",
                    help="val to choose anything, test only to report")
    ap.add_argument("--model", default=None, help="model file (default: the shipped weights)")
    ap.add_argument("--episodes", type=int, default=EPISODES_PER_FAMILY)
    ap.add_argument("--alphas", type=float, nargs="+", default=[1.0, 0.0])
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--guidance", type=float, default=DEFAULT_GUIDANCE,
                    help=f"text guidance of every ego (the runtime's default {DEFAULT_GUIDANCE:g})")
    add_final_guidance_options(ap)
    ap.add_argument("--control-set", action="append", default=[], metavar="NAME=VALUE",
                    help="override one test-time control setting (a field of model_runtime.ControlConfig); "
                         "repeatable. For choosing settings on the val split")
    ap.add_argument("--json", default=None, help="write the report here")
    args = ap.parse_args(argv)
    if args.episodes < 1:
        print(f"error: --episodes must be at least 1, got {args.episodes}", file=sys.stderr)
        return 2
    try:
        check_guidance(args.guidance)      # the runtime's own rules, before any model loads
        check_final_guidance_share(args.final_guidance_share)
        check_final_guidance_min_speed(args.final_guidance_min_speed)
    except InputError as exc:
        print(f"error: --{exc}", file=sys.stderr)
        return 2
    try:
        control_config = control_config_from(args.control_set)
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    import torch

    from .. import load_model
    from ..errors import RemogenError
    torch.set_num_threads(args.threads)
    try:
        model = load_model(args.model) if args.model else load_model()
        final_guidance = set_final_guidance(model, args)
    except RemogenError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    report = run_crowd(model, args.split, episodes=args.episodes, alphas=args.alphas,
                       progress=lambda m: print(m, file=sys.stderr, flush=True), guidance=args.guidance,
                       control_config=control_config)
    report["control_set"] = list(args.control_set)
    report.update(final_guidance)
    for key in (k for k in report if k.startswith("alpha=")):
        s = report[key]
        print(f"{args.split} crowd {key}: {s['percent_keep_10cm']:.1f} % of {s['episodes']} episodes keep "
              f"{KEEP_CLEARANCE:.2f} m (head_on {s.get('percent_keep_10cm_head_on', float('nan')):.1f}, crossing "
              f"{s.get('percent_keep_10cm_crossing', float('nan')):.1f}, three "
              f"{s.get('percent_keep_10cm_three', float('nan')):.1f}); closest mean {s['closest_mean_m']:.2f} m, "
              f"min {s['closest_min_m']:.3f} m; pelvis faster than {GLIDE_SPEED:g} m/s in "
              f"{s['percent_glide']:.1f} % of episodes")
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump(report, fh, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
