"""Average the priors of model files: python -m model_runtime.training.average FILE[:WEIGHT] ... --out FILE.

A prior trained further on a narrow set of windows learns what they teach and, from one snapshot to the next,
wanders in what it already knew (standing still, walking straight, turning toward a partner). Averaging the
weights of several snapshots of one run keeps what they share and evens out the wandering, and averaging that
with the prior the run started from keeps a share of the new learning on top of the old (weight-space ensembling:
Wortsman et al., "Model soups", ICML 2022; "Robust fine-tuning of zero-shot models", CVPR 2022).

Only the prior (the latent denoiser) is averaged. Every other part of the files (statistics, VAE, HHI, HSI, FWSR)
must be identical, as it is in the snapshots of a prior-only run and the file it started from: the interaction
modules read the prior's activations, so they stay close to the prior they were trained with only while the
averaged prior stays close to it. The written file keeps the first file's meta, with the sources and weights
recorded in meta["stages"]["prior"]["averaged_from"].
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import torch

from ..checkpoint import load_model, save_model
from ..errors import RemogenError
from ..model import ReMoGenModel

PRIOR = "denoiser."


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


def average_priors(models: list[ReMoGenModel], weights: list[float]) -> ReMoGenModel:
    """The first model with its prior replaced by the weighted mean of all the models' priors (weights are
    normalised to sum to 1). Refuses models that differ anywhere but in the prior."""
    if len(models) < 2 or len(models) != len(weights):
        raise RemogenError("give at least two model files to average, each with at most one weight")
    if any(m.cfg.to_dict() != models[0].cfg.to_dict() for m in models):
        raise RemogenError("the files hold models of different presets: average only files of one training run")
    states = [m.state_dict() for m in models]
    for k, v in states[0].items():
        if not k.startswith(PRIOR) and any(not torch.equal(s[k], v) for s in states[1:]):
            raise RemogenError(f"the files differ in {k.split('.')[0]} weights ({k}): average only snapshots of one "
                               "prior-only run and the file it started from")
    total = float(sum(weights))
    mean = {k: sum((w / total) * s[k].double() for s, w in zip(states, weights)).to(v.dtype)
            for k, v in states[0].items() if k.startswith(PRIOR)}
    base = models[0]
    base.denoiser.load_state_dict({k[len(PRIOR):]: v for k, v in mean.items()})
    return base


def _source_record(path: str, weight: float, model: ReMoGenModel) -> dict:
    """What the averaged file records of one source: its name, weight and prior training (steps, windows)."""
    prior = model.meta.get("stages", {}).get("prior", {})
    windows = prior.get("windows")
    return {"file": Path(path).name, "weight": round(weight, 6), "steps": prior.get("steps"),
            "windows": windows.get("name") if isinstance(windows, dict) else windows}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m model_runtime.training.average", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("files", nargs="+", help="model files, each optionally FILE:WEIGHT (default weight 1)")
    ap.add_argument("--out", required=True, help="model file to write")
    args = ap.parse_args(argv)
    try:
        sources = [parse_source(f) for f in args.files]
        models = [load_model(p, warn_untrained=False) for p, _ in sources]
        total = sum(w for _, w in sources)
        out = average_priors(models, [w for _, w in sources])
        stages = dict(out.meta.get("stages", {}))
        stages["prior"] = dict(stages.get("prior", {}),
                               averaged_from=[_source_record(p, w / total, m) for (p, w), m in zip(sources, models)])
        out.meta = dict(out.meta, stages=stages)
        save_model(out, Path(args.out))
    except RemogenError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {args.out}: the prior averaged over {len(sources)} files", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
