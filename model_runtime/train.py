"""Staged training: python -m model_runtime.train STAGE [options]

    python -m model_runtime.train vae   --library runs/clips.npz --out runs/train
    python -m model_runtime.train prior ...; hhi; hsi; fwsr
    python -m model_runtime.train decoder ...   (optional: the decoder alone, on the motion as shown)

Each stage starts from OUT/model.pt (written by the stage before; `vae` starts from a fresh model),
freezes everything but its own module, trains with AdamW, gradient clipping 1.0 and an EMA (0.999,
with warm-up) of its weights, validates on held-out clips, and writes OUT/model.pt with the EMA weights.
A resumable state (weights, EMA, optimiser, step, RNG) goes to OUT/STAGE.state.pt every few minutes;
rerunning the same command continues from it. Losses go to OUT/STAGE.log.jsonl.

    python -m model_runtime.train all --library runs/clips.npz --out runs/train --minutes 30

runs the five stages of a model in order within one time budget, skips stages already done, stops after a stage that
ran out of time, and ends with a summary: steps per stage, best held-out loss, files written and the
command that continues the run.

GPU: with a CUDA GPU present the model trains on it (--device auto, the default; --device cpu forces the CPU)
and background processes draw the batches (--workers, default 8 on a GPU, 0 on the CPU): drawing a batch in
Python is slower than a GPU step of the default model. The model files hold CPU tensors either way.

Multi-process / multi-machine: `torchrun --nproc_per_node N -m model_runtime.train STAGE ...` runs
DistributedDataParallel, over nccl with one GPU per rank (rank r on cuda:LOCAL_RANK) or over gloo on CPU
cores; each rank draws its own batches (so --batch is per rank: 8 ranks at --batch 16 train with the
recipe's 128 per step).
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import torch
import torch.distributed as dist

from .cli_help import HelpFormatter
from .data.library import ClipLibrary
from .devices import resolve_device as training_device
from .errors import RemogenError
from .training.ema import EMA
from .training.loop import past_deadline, rank_and_world, train_stage
from .training.recipe import DEFAULT_STEPS, RECIPE, WINDOW_RECIPES
from .training.init_from import start_from_vae
from .training.report import StageRun, say, summary
from .training.stages import REQUIRED_STAGES, STAGES

__all__ = ["EMA", "RECIPE", "DEFAULT_STEPS", "STAGES", "StageRun", "main", "train_stage"]


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    ap = argparse.ArgumentParser(prog="python -m model_runtime.train", description=__doc__.split("\n\n")[0],
                                 formatter_class=HelpFormatter)
    ap.add_argument("stage", choices=STAGES + ("all",), help="the stage to train, or all (the five a model needs, in order; decoder, a refinement, runs only by name)")
    ap.add_argument("--library", default="runs/clips.npz", help="clip cache (built from --data if missing)")
    ap.add_argument("--data", default=None, help="motion folder to build a missing clip cache from "
                    "(as python -m model_runtime.data.prepare --data does)")
    ap.add_argument("--cmu-only", action="store_true", help="train on CMU clips only (commercial-use weights)")
    ap.add_argument("--out", default="runs/train", help="folder for model.pt, STAGE.state.pt and STAGE.log.jsonl")
    ap.add_argument("--config", default="default", help="model size preset: tiny, default or paper")
    ap.add_argument("--init-vae", default=None, metavar="FILE",
                    help="copy FILE's VAE and feature statistics and train the stages after it (for a new text "
                         "encoder or new captions: the VAE does not depend on text)")
    ap.add_argument("--no-mirror", action="store_true",
                    help="train without the mirrored copies of the clips (data/mirror.py)")
    ap.add_argument("--windows", default="captured", choices=sorted(WINDOW_RECIPES),
                    help="how training windows are drawn and captioned: captured (as the data holds them) or "
                         "balanced (slow-walk and still captions, caption balance, start-up copies for the prior: "
                         "what the shipped prior's last steps trained on); kicks: the balanced windows with kicks at 6 %% "
                         "of the prior's and the decoder stage's windows, the decoder on reconstruction alone; the "
                         "others: training/recipe.py WINDOW_RECIPES")
    ap.add_argument("--anchor", type=float, default=None, metavar="W",
                    help="for a fine-tune of the prior or decoder: weight of the loss that holds the output on the "
                         "real clips' windows to the starting file's (default: the window recipe's; 0: none)")
    ap.add_argument("--steps", type=int, default=None, help="steps per stage (default: the stage's RECIPE entry)")
    ap.add_argument("--batch", type=int, default=None, help="batch per rank (default: the stage's RECIPE entry)")
    ap.add_argument("--lr", type=float, default=None, help="learning rate (default: the stage's RECIPE entry)")
    ap.add_argument("--seed", type=int, default=0, help="seed of weights, batches and generated pairs")
    ap.add_argument("--minutes", type=float, default=None,
                    help="stop this run after so many minutes (rerun the same command to continue)")
    ap.add_argument("--threads", type=int, default=0, help="torch threads (0: PyTorch's default)")
    ap.add_argument("--device", default="auto", help="auto (a CUDA GPU when there is one, else the CPU), cpu, "
                    "cuda or cuda:N")
    ap.add_argument("--workers", type=int, default=None,
                    help="background processes drawing batches (default: 8 on a GPU, 0 on the CPU)")
    ap.add_argument("--snapshot-every", type=int, default=0, metavar="STEPS",
                    help="also save the EMA model to OUT/snapshots/STAGE_STEP.pt every STEPS steps, to choose a "
                         "checkpoint on the val split (python -m model_runtime.behaviour --split val --model FILE)")
    ap.add_argument("--keep-module", action="store_true",
                    help="an hhi, hsi or fwsr stage continues from the module in OUT/model.pt (a fine-tune) instead "
                         "of starting over")
    ap.add_argument("--partner-line-cues", action="store_true", default=None,
                    help="an hhi stage starting over gives its partner encoder the line cues (where the partner's "
                         "line passes the ego and when; ModelConfig.partner_line_cues)")
    ap.add_argument("--no-progress", action="store_true", help="no progress bars or status lines")
    args = ap.parse_args(argv)
    if args.threads:
        torch.set_num_threads(args.threads)
    try:
        device = training_device(args.device)
    except RemogenError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    workers = args.workers if args.workers is not None else (8 if device.type == "cuda" else 0)
    if int(os.environ.get("WORLD_SIZE", "1")) > 1 and not dist.is_initialized():
        dist.init_process_group("nccl" if device.type == "cuda" else "gloo")   # nccl moves CUDA tensors only
    rank, world = rank_and_world()
    progress = not args.no_progress and rank == 0
    runs: list[StageRun] = []
    try:
        lib = _load_library(args, progress)
        out = Path(args.out)
        if args.init_vae:
            if args.stage == "vae":
                raise RemogenError("--init-vae copies a trained VAE, so there is no vae stage to train; name a later "
                                   "stage or all")
            if start_from_vae(Path(args.init_vae), out, args.config) and progress:
                say(f"vae: copied from {args.init_vae} into {out / 'model.pt'}")
        deadline = time.time() + args.minutes * 60 if args.minutes else None
        for st in REQUIRED_STAGES if args.stage == "all" else (args.stage,):
            if _stage_done(out, st, args.steps):
                if progress:
                    say(f"{st}: already done ({out / (st + '.state.pt')}); skipped")
                continue
            if runs and past_deadline(deadline, world):   # the time is up before this stage starts
                break
            left = None if deadline is None else max((deadline - time.time()) / 60, 1e-3)
            runs.append(train_stage(st, out, lib, config=args.config, steps=args.steps, batch=args.batch,
                                    lr=args.lr, seed=args.seed, minutes=left, progress=progress,
                                    mirror=not args.no_mirror, device=device, workers=workers,
                                    snapshot_every=args.snapshot_every, windows=args.windows,
                                    keep_module=args.keep_module, partner_line_cues=args.partner_line_cues,
                                    anchor=args.anchor))
            if not runs[-1].finished:
                break
    except RemogenError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted: the last saved state is kept; rerun the same command to continue", file=sys.stderr)
        return 130
    finally:
        if dist.is_initialized():
            dist.destroy_process_group()
    if rank == 0:
        print(summary(runs, REQUIRED_STAGES, argv, world), file=sys.stderr)
    return 0


def _load_library(args: argparse.Namespace, progress: bool) -> ClipLibrary:
    lib_path = Path(args.library)
    if not lib_path.exists():
        if not args.data:
            raise RemogenError(f"clip cache {lib_path} not found; build it with python -m model_runtime.data.prepare "
                               f"--data MOTION_FOLDER --out {lib_path} (or pass --data MOTION_FOLDER here)")
        from .data.prepare import build_library
        build_library(args.data, progress=progress, skip=(lib_path,)).save(lib_path)
    if progress:
        say(f"loading clip library {lib_path} ...")
    lib = ClipLibrary.load(lib_path)
    if args.cmu_only:
        if "cmu" not in lib.sources:
            raise RemogenError(f"{lib_path} has no CMU clip to keep with --cmu-only; leave --cmu-only out")
        lib = lib.subset({"cmu"})
    if progress:
        say(f"{len(lib)} clips ({int(lib.offsets[-1]) / 36000:.2f} h at 10 fps), {len(lib.split('val'))} held out "
            "for validation")
    return lib


def _stage_done(out: Path, stage: str, steps: int | None) -> bool:
    """Whether OUT/STAGE.state.pt holds a finished stage (of `steps` steps when given)."""
    path = out / f"{stage}.state.pt"
    if not path.exists():
        return False
    st = torch.load(path, map_location="cpu", weights_only=True)
    return int(st["step"]) >= (steps or int(st.get("total", DEFAULT_STEPS[stage])))


if __name__ == "__main__":
    raise SystemExit(main())
