"""Join stages trained side by side: python -m model_runtime.training.merge BASE OTHER --take hsi --out FILE.

HHI and HSI each train on the frozen prior alone, so both can start from the same prior file and train at the same
time in two folders (on one GPU, or two machines). This writes BASE with OTHER's module for each --take stage and its
training record. It refuses files whose VAE, statistics or prior differ: a module only fits the prior it was
trained on. The decoder stage trains the VAE's decoder on the frozen encoder, which is all the prior reads, so a
decoder trained beside the prior joins it with --take decoder (the two files must share statistics and encoder, and
the first must hold no trained FWSR, which stores its decoder's sensitivity).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import torch

from ..checkpoint import load_model, save_model
from ..errors import RemogenError
from ..model import ReMoGenModel
from .stages import trainable_module

MERGEABLE = ("hhi", "hsi", "decoder")
SHARED = ("stats", "vae", "denoiser")   # what both files must hold identically to join an interaction module
SHARED_FOR_DECODER = ("stats", "encoder")   # ... and to join a decoder


def _weights(model: ReMoGenModel, part: str) -> dict[str, torch.Tensor]:
    if part != "encoder":
        return getattr(model, part).state_dict()
    decoder = {id(p) for p in model.vae.decoder_parts().parameters()}
    return {name: p.detach() for name, p in model.vae.named_parameters() if id(p) not in decoder}


def merge_stages(base: ReMoGenModel, other: ReMoGenModel, take: tuple[str, ...]) -> ReMoGenModel:
    """`base` with `other`'s modules of the stages in `take` (and their meta["stages"] entries); base is changed."""
    for stage in take:
        if stage not in MERGEABLE:
            raise RemogenError(f"--take {stage}: only {', '.join(MERGEABLE)} train beside another stage")
    if "decoder" in take and len(set(take)) > 1:
        raise RemogenError("--take decoder changes the VAE the interaction modules were trained with: join the decoder "
                           "on its own, then the modules from files that hold it")
    if "decoder" in take and "fwsr" in base.meta.get("stages", {}):
        raise RemogenError("the first file's FWSR stage holds the sensitivity of the decoder it was trained with: join "
                           "the decoder to a file without FWSR, then train FWSR on the result")
    shared = SHARED if set(take) - {"decoder"} else SHARED_FOR_DECODER
    for part in shared:
        mine, theirs = _weights(base, part), _weights(other, part)
        if mine.keys() != theirs.keys() or any(not torch.equal(mine[k], theirs[k]) for k in mine):
            raise RemogenError(f"the two files hold different {part} weights: merge only stages trained from the "
                               "same model file")
    stages = dict(base.meta.get("stages", {}))
    for stage in take:
        record = other.meta.get("stages", {}).get(stage)
        if record is None:
            raise RemogenError(f"the second file has no trained {stage} stage; train it first")
        trainable_module(base, stage).load_state_dict(trainable_module(other, stage).state_dict())
        stages[stage] = dict(record)
    base.meta = dict(base.meta, stages=stages)
    return base


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m model_runtime.training.merge", description=__doc__)
    ap.add_argument("base", help="model file whose modules are kept")
    ap.add_argument("other", help="model file the --take stages come from")
    ap.add_argument("--take", nargs="+", required=True, choices=MERGEABLE)
    ap.add_argument("--out", required=True, help="model file to write")
    args = ap.parse_args(argv)
    try:
        base, other = load_model(args.base, warn_untrained=False), load_model(args.other, warn_untrained=False)
        merged = merge_stages(base, other, tuple(args.take))
        save_model(merged, Path(args.out))
    except RemogenError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {args.out}: {args.base} with {', '.join(args.take)} from {args.other}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
