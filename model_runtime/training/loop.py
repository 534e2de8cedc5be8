"""One stage's training loop: run or resume, validate with the EMA weights, save a resumable state every few
minutes and the EMA model at the end (and, when asked, every N steps, so a checkpoint can be chosen on the
behaviour suite's val split); under torchrun the ranks train data-parallel and stop together."""
from __future__ import annotations

import copy
import dataclasses

import gc
import json
import math
import os
import time
from pathlib import Path

import torch
import torch.distributed as dist

from ..checkpoint import load_model, save_model
from ..config import ModelConfig, resolve_config
from ..data.library import ClipLibrary, non_commercial
from ..devices import device_name
from ..errors import RemogenError
from ..model import ReMoGenModel
from ..text_blend import PROMPT_BLEND_KEEP, library_blend_meta
from .ema import EMA
from .recipe import DEFAULT_STEPS, RECIPE, TEXT_DROP, WINDOW_RECIPES
from .report import StageRun, say, validation_history
from .prefetch import batch_stream
from .samples import SegmentSampler
from .setup import build_samplers, check_library, decoder_sensitivity, fit_stats
from .stages import ANCHOR_STAGES, STAGES, TEXT_STAGES, StageLoss, check_hhi_anchor, freeze_for, trainable_module


def rank_and_world() -> tuple[int, int]:
    if dist.is_available() and dist.is_initialized():
        return dist.get_rank(), dist.get_world_size()
    return 0, 1


def train_stage(stage: str, out: Path, lib: ClipLibrary, *, config: str = "default", steps: int | None = None,
                batch: int | None = None, lr: float | None = None, seed: int = 0, minutes: float | None = None,
                ckpt_minutes: float = 3.0, val_every: int = 250, val_batches: int = 4,
                progress: bool = True, mirror: bool = True, device: str | torch.device = "cpu",
                workers: int = 0, snapshot_every: int = 0, windows: str = "captured",
                keep_module: bool = False, partner_line_cues: bool | None = None,
                anchor: float | None = None) -> StageRun:
    """Run (or resume) one stage: what was written and how far it got.

    device: where the model trains ("cpu", "cuda", "cuda:1"); the checkpoint files hold CPU tensors either way.
    workers: background processes that draw the batches (training/prefetch.py); 0 draws them in this one.
    snapshot_every: also write the EMA model to OUT/snapshots/STAGE_STEP.pt every this many steps (0: never).
    windows: the name of the training windows' recipe (recipe.WINDOW_RECIPES), recorded with the stage.
    keep_module: an adapter stage (hhi, hsi, fwsr) started afresh continues from model.pt's module (a fine-tune)
    instead of starting over.
    partner_line_cues: an hhi stage started afresh builds its partner encoder with (True) or without (False) the
    line cues (ModelConfig.partner_line_cues); None keeps model.pt's setting.
    anchor: the window recipe's anchor weight replaced (WindowRecipe.anchor; recorded with the recipe); None keeps it.
    """
    device = torch.device(device)
    if stage not in STAGES:
        raise RemogenError(f"unknown stage {stage!r}; use one of {', '.join(STAGES)}")
    if windows not in WINDOW_RECIPES:
        raise RemogenError(f"unknown window recipe {windows!r}; use one of {', '.join(WINDOW_RECIPES)}")
    if anchor is not None and not (anchor >= 0.0 and math.isfinite(anchor)):
        raise RemogenError(f"--anchor {anchor}: the weight must be a number >= 0 (0 trains without holding to the "
                           "start)")
    recipe = WINDOW_RECIPES[windows] if anchor is None else dataclasses.replace(WINDOW_RECIPES[windows], anchor=anchor)
    check_hhi_anchor(stage, recipe.anchor, recipe.hhi_rollout)    # before the library is read
    check_library(lib, resolve_config(config))
    rank, world = rank_and_world()
    note = (lambda msg: say(f"{stage}: {msg}")) if progress and rank == 0 else (lambda msg: None)
    batch = batch or RECIPE[stage][1]
    lr = lr or RECIPE[stage][2]
    out.mkdir(parents=True, exist_ok=True)
    model_path, state_path, log_path = out / "model.pt", out / f"{stage}.state.pt", out / f"{stage}.log.jsonl"
    torch.manual_seed(seed + rank)
    st = torch.load(state_path, map_location="cpu", weights_only=True) if state_path.exists() else None
    if st is not None:  # resume: the whole model as it was, stats included
        note(f"resuming at step {int(st['step']):,} from {state_path}")
        model = ReMoGenModel(ModelConfig.from_dict(st["config"]))
        model.load_state_dict(st["model"])
        model.meta = dict(st["meta"])
    elif stage == "vae":
        model = ReMoGenModel(resolve_config(config))
        note(f"fitting feature statistics on {len(lib.split('train'))} training clips ...")
        fit_stats(model, lib, lib.split("train"), seed=seed)
    else:
        if not model_path.exists():
            raise RemogenError(f"{model_path} not found: train the stages before '{stage}' first "
                               f"({' -> '.join(STAGES)})")
        note(f"starting from {model_path}")
        model = load_model(model_path, warn_untrained=False)   # its later stages are untrained by design
        if stage == "hhi" and partner_line_cues is not None and partner_line_cues != model.cfg.partner_line_cues:
            if keep_module:
                raise RemogenError("--partner-line-cues changes the HHI module's inputs, so it cannot be kept: "
                                   "leave out --keep-module")
            model = with_partner_line_cues(model, partner_line_cues)
    params = freeze_for(model, stage)
    module = trainable_module(model, stage)
    # a run of a prior or decoder stage that model.pt already holds continues from those weights (a fine-tune): the
    # file then records what it started from (the adapters start over, below, unless keep_module; the meta is
    # updated at the end)
    fine_tune = ("prior", "decoder") + (("hhi", "hsi", "fwsr") if keep_module else ())
    started_from = model.meta.get("stages", {}).get(stage) if stage in fine_tune else None
    if keep_module and st is None and not started_from:
        raise RemogenError(f"--keep-module: {model_path} has no trained {stage} module to continue from; train the "
                           f"stage without --keep-module first")
    if st is None and stage in ("hhi", "hsi", "fwsr") and not keep_module:
        # A fresh start of an adapter stage re-initialises the whole module (seeded), so the result does not
        # depend on an earlier run's weights left in model.pt (measured: HHI warm-started from a run with
        # other pair kinds kept that run's behaviour), then zero-inits it into an exact no-op.
        fresh = trainable_module(ReMoGenModel(model.cfg), stage)
        module.load_state_dict(fresh.state_dict())
        module.zero_init()
    if st is None and stage == "fwsr":
        note("measuring the decoder's sensitivity ...")
        decoder_sensitivity(model, lib, seed)
    tr, va = build_samplers(stage, model, lib, seed, rank, note, mirror=mirror, windows=recipe)
    model.to(device)
    anchor_weight = recipe.anchor if stage in ANCHOR_STAGES else 0.0
    start = None
    if anchor_weight > 0.0:
        if st is not None and "anchor_start" not in st:
            raise RemogenError(f"{state_path} began without an anchor, so it has no start to hold to: resume it as it "
                               f"began, or fine-tune into a new folder")
        if not started_from:
            raise RemogenError(f"--windows {windows} holds the {stage} to the file it starts from, and {model_path} "
                               f"has no trained {stage}: train it first, or pick a recipe without an anchor")
        start = copy.deepcopy(model)
        if st is not None:   # a resumed run holds to the module it first started from (model.pt may be newer)
            trainable_module(start, stage).load_state_dict(st["anchor_start"])
        start.to(device)
    loss_mod = StageLoss(model, stage, shown_weight=recipe.decoder_shown_weight, hhi_guidance=recipe.hhi_guidance,
                         anchor=start, anchor_weight=anchor_weight, hhi_rollout=recipe.hhi_rollout,
                         rollout_costs=(recipe.rollout_seam, recipe.rollout_skate, recipe.rollout_glide),
                         rollout_arms=recipe.rollout_arms, text_jitter_cos=recipe.text_jitter_cos)
    ddp = (torch.nn.parallel.DistributedDataParallel(loss_mod, device_ids=[device] if device.type == "cuda" else None)
           if world > 1 else loss_mod)
    opt = torch.optim.AdamW(params, lr=lr, weight_decay=0.01)
    ema = EMA(params)
    gen = torch.Generator().manual_seed(seed * 7919 + rank)
    step, wall = 0, 0.0
    total = steps or DEFAULT_STEPS[stage]
    if st is not None:
        opt.load_state_dict(st["optim"])
        for s, v in zip(ema.shadow, st["ema"]):
            s.copy_(v)
        ema.updates = int(st.get("ema_updates", st["step"]))
        gen.set_state(st["gen"])
        step, wall = int(st["step"]), float(st["wall"])
        total = int(st.get("total", total)) if steps is None else total
    # the batches of a resumed run continue the stream rather than replay its start
    batches = batch_stream(tr, batch, fwsr=(stage == "fwsr"), workers=workers, seed=seed * 7919 + rank + step,
                           device=device)
    bar = None
    if progress and rank == 0:
        from tqdm import tqdm
        bar = tqdm(total=total, initial=step, desc=f"train {stage}", unit="step", dynamic_ncols=True)
    t_start, last_ckpt = time.time(), time.time()
    deadline = t_start + minutes * 60 if minutes else None

    def stage_meta(at_step: int, wall_s: float) -> dict:
        """The model file's meta after this stage: its steps, hardware and held-out loss, data and licence."""
        meta = dict(model.meta)
        stages = dict(meta.get("stages", {}))
        stages[stage] = {"steps": at_step, "wall_s": round(wall_s, 1), "batch": batch,
                         "lr": lr, "world_size": world, "clips": len(lib.split("train")),
                         "device": device_name(device), "workers": workers,
                         "val_loss": ([None] + [v for _, v in validation_history(log_path)])[-1]}
        if stage in TEXT_STAGES:
            stages[stage]["text_drop"] = TEXT_DROP
        stages[stage]["windows"] = {"name": windows, **recipe.as_meta()}
        if started_from:
            stages[stage]["started_from"] = {k: v for k, v in started_from.items() if k != "started_from"}
        # a VAE copied from another file (--init-vae) brings its own data: its licence carries over
        sources = set(lib.sources) | set(meta.get("sources", []))
        meta.update({"trained": True, "stages": stages, "sources": sorted(sources),
                     "non_commercial": non_commercial(sources, meta)})
        if stage == "prior":   # the runtime reads prompts partly by the phrasings this prior trained on
            keep = meta.get("prompt_blend", {}).get("keep", PROMPT_BLEND_KEEP)
            meta["prompt_blend"] = library_blend_meta(lib, keep)
        return meta

    def with_own_sensitivity(m: ReMoGenModel) -> ReMoGenModel:
        """FWSR's damping reads the decoder's sensitivity: a decoder-stage file (snapshot or final) measures its own
        decoder's instead of keeping the starting file's. `m` on the CPU."""
        if stage == "decoder":
            decoder_sensitivity(m, lib, seed)
        return m

    def save_snapshot() -> None:
        ema.swap()
        try:
            snap = copy.deepcopy(model).cpu() if stage == "decoder" else model   # training goes on where it runs
            save_model(with_own_sensitivity(snap), out / "snapshots" / f"{stage}_{step:06d}.pt",
                       meta=stage_meta(step, wall + time.time() - t_start))
        finally:
            ema.swap()

    def save_state() -> None:
        if rank != 0:
            return
        anchor_state = {"anchor_start": trainable_module(start, stage).state_dict()} if start is not None else {}
        tmp = state_path.with_suffix(".tmp")
        torch.save({"config": model.cfg.to_dict(), "model": model.state_dict(), "meta": model.meta,
                    "optim": opt.state_dict(), "ema": ema.shadow, "ema_updates": ema.updates,
                    "gen": gen.get_state(), "step": step, "wall": wall + time.time() - t_start,
                    "total": total, **anchor_state}, tmp)
        os.replace(tmp, state_path)

    try:
        with log_path.open("a") as log:
            while step < total:
                b = next(batches)
                loss, parts = ddp(b, gen)
                opt.zero_grad(set_to_none=True)
                loss.backward()
                torch.nn.utils.clip_grad_norm_(params, 1.0)
                opt.step()
                ema.update()
                step += 1
                last = step == total or past_deadline(deadline, world)   # a run cut short still validates
                row = {"stage": stage, "step": step, "loss": float(loss.detach()), **parts}
                if va is not None and (step % val_every == 0 or last):
                    row["val_loss"] = validate(loss_mod, module, ema, va, val_batches, batch, stage, device)
                if rank == 0:
                    log.write(json.dumps(row) + "\n")
                    if bar is not None:
                        bar.update(1)
                        bar.set_postfix(loss=f"{row['loss']:.4f}", **({"val": f"{row['val_loss']:.4f}"}
                                                                      if "val_loss" in row else {}))
                if snapshot_every and step % snapshot_every == 0 and not last and rank == 0:
                    log.flush()   # the snapshot's held-out loss is read back from the log
                    save_snapshot()
                if time.time() - last_ckpt > ckpt_minutes * 60:
                    log.flush()
                    save_state()
                    last_ckpt = time.time()
                if last:
                    break
    except KeyboardInterrupt:
        if bar is not None:
            bar.close()
        if world == 1:
            save_state()   # Ctrl-C keeps the steps done so far: rerunning the command resumes here
        raise
    if bar is not None:
        bar.close()
    save_state()
    if rank == 0:
        ema.swap()
        model.eval()
        with_own_sensitivity(model.cpu())   # the model file holds CPU tensors whatever trained it
        model.meta = stage_meta(step, wall + time.time() - t_start)
        save_model(model, model_path)
        model.to(device)
        ema.swap()
    if world > 1:
        # every rank leaves together: the next stage of `all` loads the model.pt rank 0 just wrote, and a rank
        # that tore down the process group while rank 0 was still saving was seen to abort (SIGABRT) in CI
        dist.barrier()
        # release the DDP wrapper (its reducer holds gloo work objects) while the process group is still alive,
        # not at interpreter exit after destroy_process_group: a late free there is a known gloo abort path
        del ddp
        gc.collect()
    return StageRun(stage, model_path, state_path, log_path, step, total, time.time() - t_start)


@torch.no_grad()
def validate(loss_mod: StageLoss, module: torch.nn.Module, ema: EMA, va: SegmentSampler, batches: int,
             batch: int, stage: str, device: torch.device = torch.device("cpu")) -> float:
    """Held-out loss with the EMA weights, in eval mode, with a fixed validation RNG."""
    ema.swap()
    module.eval()
    try:   # the live weights come back even when Ctrl-C lands here (the state saved then must hold them)
        gen = torch.Generator().manual_seed(1234)
        va.gen.manual_seed(4321)
        total = 0.0
        for _ in range(batches):
            total += float(loss_mod(va.sample(batch, fwsr=(stage == "fwsr")).to(device), gen)[0])
    finally:
        module.train()
        ema.swap()
    return total / batches


def past_deadline(deadline: float | None, world: int) -> bool:
    """Whether --minutes is up. Under DDP rank 0's clock decides for all ranks (one tiny broadcast per step):
    ranks that stopped on their own clocks would leave the others waiting in an all-reduce forever."""
    if deadline is None:
        return False
    done = torch.tensor([float(time.time() >= deadline)])
    if world > 1:
        if dist.get_backend() == "nccl":   # nccl moves CUDA tensors only
            done = done.cuda()
        dist.broadcast(done, 0)
    return bool(done.item())


def with_partner_line_cues(model: ReMoGenModel, on: bool) -> ReMoGenModel:
    """The same model with its HHI partner encoder built with or without the line cues: every weight whose shape
    stays is copied (the HHI module starts over anyway)."""
    cued = ReMoGenModel(dataclasses.replace(model.cfg, partner_line_cues=on))
    ours = cued.state_dict()
    cued.load_state_dict({k: v for k, v in model.state_dict().items() if k in ours and ours[k].shape == v.shape},
                         strict=False)
    cued.meta = dict(model.meta)
    return cued
