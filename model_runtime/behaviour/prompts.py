"""What a prompt makes the ego do, measured as the text family measures it.

    python -m model_runtime.behaviour.prompts "someone sprints" "a person runs" [--seeds 0,1,2] [--model FILE]

Each prompt is rolled out from standing at the origin like a text-family episode (no partner, goal or scene,
TEXT_EPISODE_FRAMES frames), once per seed, and judged on the text family's statistics (metrics.text_measures),
averaged over the seeds. For prompts the suite does not hold, and for comparing weights files on the same
prompts; choices between weights still go by the suite's val split.
"""
from __future__ import annotations

import argparse
import json
import sys
from typing import Sequence

import numpy as np

from ..cli_help import HelpFormatter, seeds_option
from ..errors import DEFAULT_GUIDANCE
from .metrics import text_measures
from .scenarios import TEXT_EPISODE_FRAMES, Episode
from .suite import roll_out

# The statistics printed per prompt (text_targets.py judges each kind on one of them).
SHOWN = ("speed_mps", "travel_vs_facing_deg", "airborne_percent", "max_ankle_height_m", "wave_sd_m",
         "wrist_speed_mps")


def measure_prompts(model, prompts: Sequence[str], seeds: Sequence[int] = (0, 1, 2), *,
                    frames: int = TEXT_EPISODE_FRAMES, guidance: float = DEFAULT_GUIDANCE) -> dict[str, dict]:
    """{prompt: {statistic: mean over the seeds, "per_seed": [text_measures of each rollout]}}."""
    out: dict[str, dict] = {}
    for prompt in prompts:
        runs = [text_measures(roll_out(model, Episode("text", 0, seed, prompt, frames), 1.0, guidance=guidance))
                for seed in seeds]
        means = {k: float(np.nanmean([r[k] for r in runs])) for k in runs[0]}
        out[prompt] = {**means, "per_seed": runs}
    return out


def markdown(report: dict[str, dict]) -> str:
    rows = ["| prompt | " + " | ".join(SHOWN) + " |", "|---|" + "---|" * len(SHOWN)]
    rows += [f"| {p} | " + " | ".join(f"{r[k]:.2f}" for k in SHOWN) + " |" for p, r in report.items()]
    return "\n".join(rows)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m model_runtime.behaviour.prompts",
                                 description=__doc__.split("\n\n")[0], formatter_class=HelpFormatter)
    ap.add_argument("prompts", nargs="+", help="the prompts to roll out")
    ap.add_argument("--seeds", default="0,1,2", help="comma-separated seeds per prompt")
    ap.add_argument("--frames", type=int, default=TEXT_EPISODE_FRAMES, help="model frames a rollout (10 a second)")
    ap.add_argument("--model", default=None, help="model file (default: the shipped weights)")
    ap.add_argument("--guidance", type=float, default=DEFAULT_GUIDANCE, help="classifier-free guidance scale")
    ap.add_argument("--threads", type=int, default=1, help="torch CPU threads")
    ap.add_argument("--json", action="store_true", help="print one JSON object instead of a markdown table")
    args = ap.parse_args(argv)
    seeds = seeds_option(ap, args.seeds)
    if args.frames < 2:
        ap.error(f"--frames must be at least 2, got {args.frames}")
    if not all(p.strip() for p in args.prompts):
        ap.error("a prompt is empty; give each prompt as one quoted argument")
    import torch

    from ..checkpoint import load_model
    from ..errors import RemogenError
    torch.set_num_threads(max(args.threads, 1))
    try:
        report = measure_prompts(load_model(args.model), args.prompts, seeds, frames=args.frames,
                                 guidance=args.guidance)
    except RemogenError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps({"model": args.model or "default", "seeds": seeds, "frames": args.frames, "prompts": report}))
    else:
        print(markdown(report))
    return 0


if __name__ == "__main__":
    sys.exit(main())
