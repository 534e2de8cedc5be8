"""Average one stage of model files: python -m model_runtime.training.average FILE[:WEIGHT] ... --out FILE
[--stage prior|decoder|hhi|hsi|fwsr|vae].

A prior trained further on a narrow set of windows learns what they teach and, from one snapshot to the next,
wanders in what it already knew (standing still, walking straight, turning toward a partner). Averaging the
weights of several snapshots of one run keeps what they share and evens out the wandering, and averaging that
with the prior the run started from keeps a share of the new learning on top of the old (weight-space ensembling:
Wortsman et al., "Model soups", ICML 2022; "Robust fine-tuning of zero-shot models", CVPR 2022).

Only the chosen stage is averaged (the prior by default; the decoder, for instance, between the shipped decoder and
one fine-tuned on new copies). Every other part of the files must be identical, as it is in the snapshots of a
one-stage run and the file it started from: the interaction modules read the prior's activations, so they stay
close to the prior they were trained with only while the averaged prior stays close to it. The written file keeps
the first file's meta, with the sources and weights recorded in meta["stages"][STAGE]["averaged_from"].
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import torch

from ..checkpoint import load_model, save_model
from ..errors import RemogenError
from ..model import ReMoGenModel
from .stages import STAGES, trainable_module

# Buffers other stages derive from a stage's weights: they may differ between the files and are measured again
# on the averaged weights (FWSR damps its refinement by the decoder's sensitivity to each latent entry).
DERIVED = {"decoder": ("fwsr.sensitivity",)}


def stage_keys(model: ReMoGenModel, stage: str) -> set[str]:
    """The model's state-dict names of the stage's own tensors (the decoder's lie inside the VAE's module)."""
    own = {t.data_ptr() for t in trainable_module(model, stage).state_dict().values()}
    return {k for k, v in model.state_dict().items() if v.data_ptr() in own}


def parse_source(text: str) -> tuple[str, float]:
    """'FILE' -> (FILE, 1.0); 'FILE:0.35' -> (FILE, 0.35). A weight must be a positive number."""
    path, sep, weight = text.rpartition(":")
    if not sep or not path:
        return text, 1.0
    try:
        w = float(weight)
    except ValueError:
        return text, 1.0   # a ':' inside the path, no weight
    if not w > 0.0:
        raise RemogenError(f"{text}: a file's weight must be a positive number, like FILE:0.5")
    return path, w


def average_stage(models: list[ReMoGenModel], weights: list[float], stage: str = "prior") -> ReMoGenModel:
    """The first model with the stage's weights replaced by their weighted mean over all the models (weights are
    normalised to sum to 1). Refuses models that differ anywhere but in that stage. What DERIVED lists for the
    stage is left as the first model's: the caller measures it again (`remeasure_derived`)."""
    if stage not in STAGES:
        raise RemogenError(f"unknown stage {stage!r}: choose one of {', '.join(STAGES)}")
    if len(models) < 2 or len(models) != len(weights):
        raise RemogenError("give at least two model files to average, each with at most one weight")
    if any(m.cfg.to_dict() != models[0].cfg.to_dict() for m in models):
        raise RemogenError("the files hold models of different presets: average only files of one training run")
    keys = stage_keys(models[0], stage)
    states = [m.state_dict() for m in models]
    for k, v in states[0].items():
        if k not in keys and k not in DERIVED.get(stage, ()) and any(not torch.equal(s[k], v) for s in states[1:]):
            raise RemogenError(f"the files differ in {k.split('.')[0]} weights ({k}) outside the {stage}: average "
                               f"only snapshots of one {stage}-only run and the file it started from")
    total = float(sum(weights))
    mean = {k: sum((w / total) * s[k].double() for s, w in zip(states, weights)).to(states[0][k].dtype)
            for k in keys}
    base = models[0]
    base.load_state_dict(mean, strict=False)
    return base


def check_library_given(stage: str, library: str | Path | None) -> None:
    """Refuses to average a stage that others derive buffers from without the library to measure them on."""
    if stage in DERIVED and library is None:
        raise RemogenError(f"averaging the {stage} measures FWSR's decoder sensitivity again: give --library "
                           "CLIPS.npz (the clip library the decoder was trained on)")


def remeasure_derived(model: ReMoGenModel, stage: str, library: str | Path | None) -> None:
    """Measure what other stages derive from the averaged stage (the decoder's sensitivity, on the library's
    training clips as the decoder stage measures it)."""
    check_library_given(stage, library)
    if stage not in DERIVED:
        return
    from ..data.library import ClipLibrary
    from .setup import decoder_sensitivity
    decoder_sensitivity(model, ClipLibrary.load(library), seed=0)


def _source_record(path: str, weight: float, model: ReMoGenModel, stage: str = "prior") -> dict:
    """What the averaged file records of one source: its name, weight and the stage's training (steps, windows),
    and, for a source that was itself an average, what it was averaged from (so a chain of averages stays on
    record)."""
    trained = model.meta.get("stages", {}).get(stage, {})
    windows = trained.get("windows")
    record = {"file": Path(path).name, "weight": round(weight, 6), "steps": trained.get("steps"),
              "windows": windows.get("name") if isinstance(windows, dict) else windows}
    if trained.get("averaged_from"):
        record["averaged_from"] = trained["averaged_from"]
    return record


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m model_runtime.training.average", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("files", nargs="+", help="model files, each optionally FILE:WEIGHT (default weight 1)")
    ap.add_argument("--out", required=True, help="model file to write")
    ap.add_argument("--stage", default="prior", help=f"the stage to average ({', '.join(STAGES)}; default prior)")
    ap.add_argument("--library", default=None,
                    help="clip library .npz, needed with --stage decoder (FWSR's decoder sensitivity is measured "
                         "on it)")
    args = ap.parse_args(argv)
    try:
        check_library_given(args.stage, args.library)    # before the files are read
        sources = [parse_source(f) for f in args.files]
        models = [load_model(p, warn_untrained=False) for p, _ in sources]
        total = sum(w for _, w in sources)
        records = [_source_record(p, w / total, m, args.stage) for (p, w), m in zip(sources, models)]
        out = average_stage(models, [w for _, w in sources], args.stage)
        remeasure_derived(out, args.stage, args.library)
        stages = dict(out.meta.get("stages", {}))
        stages[args.stage] = dict(stages.get(args.stage, {}), averaged_from=records)
        out.meta = dict(out.meta, stages=stages)
        save_model(out, Path(args.out))
    except RemogenError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {args.out}: the {args.stage} averaged over {len(sources)} files", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
