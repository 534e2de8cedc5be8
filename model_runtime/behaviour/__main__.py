"""The behaviour suite: python -m model_runtime.behaviour (or python -m model_runtime.evaluate --behaviour)."""
from __future__ import annotations

import argparse
import json
import sys

import numpy as np


def _jsonable(x):
    if isinstance(x, dict):
        return {k: _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (np.floating, float)):
        return None if not np.isfinite(x) else round(float(x), 4)
    if isinstance(x, np.integer):
        return int(x)
    return x


def main(argv: list[str] | None = None) -> int:
    from .scenarios import EPISODES_PER_FAMILY, FAMILIES
    ap = argparse.ArgumentParser(prog="python -m model_runtime.evaluate --behaviour", description=__doc__,
                                 formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    ap.add_argument("--split", choices=("val", "test"), default="val",
                    help="val for every choice (checkpoint, weights, thresholds); test only to report")
    ap.add_argument("--model", default=None, help="model file (default: the shipped weights)")
    ap.add_argument("--families", nargs="+", choices=FAMILIES, default=list(FAMILIES))
    ap.add_argument("--episodes", type=int, default=EPISODES_PER_FAMILY, help="episodes per family")
    ap.add_argument("--guidance", type=float, default=5.0)
    ap.add_argument("--threads", type=int, default=1, help="torch CPU threads")
    ap.add_argument("--no-control", action="store_true",
                    help="roll out without test-time control: what the model has learned by itself")
    ap.add_argument("--json", action="store_true", help="print the report as one JSON object")
    ap.add_argument("--plots", default=None, help="folder for top-view paths and stick-figure strips")
    args = ap.parse_args(argv)
    if args.episodes < 1:
        ap.error("--episodes must be at least 1")
    import torch

    from ..checkpoint import load_model
    from ..errors import RemogenError
    from .suite import run_suite
    torch.set_num_threads(args.threads)
    try:
        model = load_model(args.model)
    except RemogenError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    report = run_suite(model, args.split, families=args.families, episodes=args.episodes,
                       guidance=args.guidance, progress=lambda m: print(m, file=sys.stderr, flush=True),
                       control=not args.no_control)
    report["control"] = not args.no_control
    if args.plots:
        from .plots import plot_report
        for p in plot_report(report, args.plots):
            print(f"wrote {p}", file=sys.stderr)
    out = {k: v for k, v in report.items() if k != "tracks"}
    if args.json:
        print(json.dumps(_jsonable(out)))
    else:
        for family, by_alpha in out["families"].items():
            for alpha, s in by_alpha.items():
                flat = {k: v for k, v in s.items() if k != "prompts"}
                print(family, alpha, json.dumps(_jsonable(flat)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
