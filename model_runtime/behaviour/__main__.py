"""The behaviour suite: python -m model_runtime.behaviour (or python -m model_runtime.evaluate --behaviour)."""
from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from ..errors import DEFAULT_GUIDANCE
from .control_overrides import control_config_from


def _jsonable(x):
    if isinstance(x, dict):
        return {k: _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (np.floating, float)):
        return None if not np.isfinite(x) else round(float(x), 4)
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def _print_tables(paths: list[str]) -> int:
    """Markdown tables of saved --json reports, joined into one."""
    from pathlib import Path

    from .tables import merge_reports, report_tables
    reports = []
    for path in paths:
        try:
            reports.append(json.loads(Path(path).read_text(encoding="utf-8")))
        except OSError as exc:
            print(f"error: cannot read {path} ({exc.strerror or exc}); give a report saved with --json",
                  file=sys.stderr)
            return 2
        except ValueError:
            print(f"error: {path} is not JSON; give a report saved with --json", file=sys.stderr)
            return 2
    path = " + ".join(paths)
    try:
        text = report_tables(merge_reports(reports))
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except (KeyError, TypeError, AttributeError) as exc:
        print(f"error: {path} is not a behaviour report ({type(exc).__name__}: {exc}); give one saved with --json",
              file=sys.stderr)
        return 2
    print(text or f"{path} has neither the text family nor diversity; run with --families text or --diversity")
    return 0


def main(argv: list[str] | None = None) -> int:
    from ..cli_help import HelpFormatter, add_final_guidance_options, set_final_guidance
    from .diversity import DIVERSITY_PROMPTS, DIVERSITY_SEEDS
    from .scenarios import EPISODES_PER_FAMILY, FAMILIES
    ap = argparse.ArgumentParser(prog="python -m model_runtime.evaluate --behaviour", description=__doc__,
                                 formatter_class=HelpFormatter)
    ap.add_argument("--split", choices=("val", "test"), default="val",
                    help="val for every choice (checkpoint, weights, thresholds); test only to report")
    ap.add_argument("--model", default=None, help="model file (default: the shipped weights)")
    ap.add_argument("--families", nargs="+", choices=FAMILIES, default=list(FAMILIES))
    ap.add_argument("--episodes", type=int, default=EPISODES_PER_FAMILY, help="episodes per family")
    ap.add_argument("--guidance", type=float, default=DEFAULT_GUIDANCE)
    add_final_guidance_options(ap)
    ap.add_argument("--threads", type=int, default=1, help="torch CPU threads")
    ap.add_argument("--no-control", action="store_true",
                    help="roll out without test-time control: what the model has learned by itself")
    ap.add_argument("--no-fwsr", action="store_true", help="roll out without Frame-wise Segment Refinement")
    ap.add_argument("--no-cleanup", action="store_true", help="roll out without the planted-foot cleanup")
    ap.add_argument("--prior-only", action="store_true",
                    help="roll out the prior alone: alpha 0, no FWSR, planted-foot cleanup or control")
    ap.add_argument("--control-set", action="append", default=[], metavar="NAME=VALUE",
                    help="override one test-time control setting (a field of model_runtime.ControlConfig), e.g. "
                         "scene_weight=80; repeatable. For choosing settings on the val split")
    ap.add_argument("--alphas", type=float, nargs="+", default=None,
                    help="interaction alphas to roll out each family at (default: 0 and 1)")
    ap.add_argument("--json", action="store_true", help="print the report as one JSON object")
    ap.add_argument("--plots", default=None, help="folder for top-view paths and stick-figure strips")
    ap.add_argument("--library", default=None,
                    help="clip library .npz (e.g. runs/clips_full.npz): real-clip references for the text "
                         "family's kinds and the diversity measure; without it they are reported as absent")
    ap.add_argument("--prompt-blend", type=float, default=None, metavar="KEEP",
                    help="read each prompt as KEEP of its own vector and the rest its nearest training phrasing's "
                         "(model_runtime/text_blend.py), in place of the model file's setting; 1 reads prompts as "
                         "they are. A file that keeps no training captions takes them from --library's train split")
    ap.add_argument("--diversity", action="store_true",
                    help=f"also measure takes that differ: the {len(DIVERSITY_PROMPTS)} diversity prompts "
                         "rolled out with --diversity-seeds seeds each (100 frames a take), pose distance "
                         "between seeds against real takes of the same caption")
    ap.add_argument("--diversity-seeds", type=int, default=DIVERSITY_SEEDS, help="seeds per diversity prompt")
    ap.add_argument("--table", default=None, nargs="+", metavar="REPORT_JSON",
                    help="print the markdown tables (targets, text family, diversity) of saved --json reports, "
                         "joined (e.g. the partner families' run and the text family's), and exit")
    args = ap.parse_args(argv)
    if args.table:
        return _print_tables(args.table)
    if args.episodes < 1:
        ap.error("--episodes must be at least 1")
    if args.diversity and args.diversity_seeds < 2:
        ap.error("--diversity-seeds must be at least 2")
    try:
        control_config = control_config_from(args.control_set)
    except ValueError as exc:
        ap.error(str(exc))
    import torch

    from ..checkpoint import load_model
    from ..errors import RemogenError
    from .suite import run_suite
    torch.set_num_threads(args.threads)
    try:
        model = load_model(args.model)
        final_guidance = set_final_guidance(model, args)
        library = None
        if args.library:
            from ..data.library import ClipLibrary
            library = ClipLibrary.load(args.library)
        if args.prompt_blend is not None:
            from ..text_blend import attach_prompt_blend, library_blend_meta
            if not 0.0 <= args.prompt_blend <= 1.0:
                ap.error(f"--prompt-blend {args.prompt_blend} is outside 0-1")
            if "prompt_blend" not in model.meta:
                if library is None:
                    ap.error("--prompt-blend: the model file keeps no training captions; give --library, the "
                             "library its prior trained on")
                model.meta["prompt_blend"] = library_blend_meta(library)
            attach_prompt_blend(model, keep=args.prompt_blend)
    except RemogenError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    # the runtime's parts each run can switch off; --prior-only switches off all of them (and the alphas)
    switches = {part: not (getattr(args, f"no_{part}") or args.prior_only) for part in ("fwsr", "cleanup", "control")}
    alphas = (0.0,) if args.prior_only else args.alphas
    report = run_suite(model, args.split, families=args.families, episodes=args.episodes,
                       guidance=args.guidance, progress=lambda m: print(m, file=sys.stderr, flush=True),
                       library=library, diversity_seeds=args.diversity_seeds if args.diversity else 0,
                       **({"alphas": tuple(alphas)} if alphas else {}), control_config=control_config, **switches)
    report.update(switches)
    report.update(final_guidance)
    report["prompt_blend"] = model.prompt_blend.keep if model.prompt_blend is not None else None
    if args.control_set:
        report["control_config"] = dict(kv.split("=", 1) for kv in args.control_set)
    if args.prior_only:
        report["prior_only"] = True
    if args.library:
        report["reference"]["library"] = args.library
    if args.plots:
        from .plots import plot_report
        for p in plot_report(report, args.plots):
            print(f"wrote {p}", file=sys.stderr)
    out = {k: v for k, v in report.items() if k != "tracks"}
    if args.json:
        print(json.dumps(_jsonable(out)))
    else:
        from .tables import report_tables
        for family, by_alpha in out["families"].items():
            for alpha, s in by_alpha.items():
                flat = {k: v for k, v in s.items() if k not in ("prompts", "kinds")}
                print(family, alpha, json.dumps(_jsonable(flat)))
        tables = report_tables(_jsonable(out))
        if tables:
            print("\n" + tables)
    return 0


if __name__ == "__main__":
    sys.exit(main())
