"""Set a model file's FWSR damping: a run-time setting stored in the file's config.

    python -m model_runtime.damping IN.pt --fwsr-beta 8 --out OUT.pt

The refiner's correction to each latent entry is divided by 1 + beta x the decoder's sensitivity to that entry
(nets/fwsr.py). Its training runs at the beta of the config it was trained with (1); a larger beta at run time
trades less foot sliding for a refiner that corrects less. The shipped weights run at the beta chosen on the
behaviour suite's val split (README, "Shipped weights"). Writes a new file; the input is never changed.
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

from .cli_help import HelpFormatter


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m model_runtime.damping", description=__doc__.split("\n\n")[0],
                                 formatter_class=HelpFormatter)
    ap.add_argument("model", help="model file to read")
    ap.add_argument("--fwsr-beta", type=float, required=True, help="FWSR damping (>= 0; training uses 1)")
    ap.add_argument("--out", required=True, help="new model file to write (must not exist yet)")
    args = ap.parse_args(argv)
    from .checkpoint import load_model, save_model
    from .errors import RemogenError
    from .model import ReMoGenModel
    out = Path(args.out)
    if out.exists():
        print(f"error: {out} exists; give a new file name (the input and other files are never overwritten)",
              file=sys.stderr)
        return 2
    try:
        model = load_model(args.model)
        cfg = dataclasses.replace(model.cfg, fwsr_beta=float(args.fwsr_beta))   # checked like any config
        damped = ReMoGenModel(cfg)
        damped.load_state_dict(model.state_dict())
        damped.meta = dict(model.meta, fwsr_beta_from=model.cfg.fwsr_beta)
        save_model(damped, out)
    except (RemogenError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"wrote {out}: fwsr_beta {model.cfg.fwsr_beta:g} -> {cfg.fwsr_beta:g}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
