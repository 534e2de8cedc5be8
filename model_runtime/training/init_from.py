"""Start a run from another model file's VAE: the stages after it retrain on top of a VAE already trained.

Why: the VAE and the feature statistics do not depend on text, so changing the text encoder (or the captions, or
the prior's data) needs the prior and everything after it retrained, not the VAE, which is the longest stage on a
CPU. `python -m model_runtime.train all --init-vae FILE` copies FILE's VAE and statistics into OUT/model.pt, marks
the vae stage done, and trains prior, hhi, hsi and fwsr with the preset's text encoder.
"""
from __future__ import annotations

from pathlib import Path

import torch

from ..checkpoint import load_model, save_model
from ..config import resolve_config
from ..errors import RemogenError
from ..model import ReMoGenModel
from .recipe import DEFAULT_STEPS


def start_from_vae(init: Path, out: Path, config: str) -> bool:
    """Write OUT/model.pt (FILE's VAE and statistics, the rest fresh) and OUT/vae.state.pt marking the vae stage
    done. Returns False (writes nothing) when OUT already holds a model: the run then continues as it was."""
    model_path, state_path = out / "model.pt", out / "vae.state.pt"
    if model_path.exists() or state_path.exists():
        return False
    source = load_model(init, warn_untrained=False)
    model = ReMoGenModel(resolve_config(config))
    for part in ("stats", "vae"):
        theirs, ours = getattr(source, part).state_dict(), getattr(model, part).state_dict()
        bad = [k for k in ours if k not in theirs or theirs[k].shape != ours[k].shape]
        if bad:
            raise RemogenError(f"{init}'s {part} does not fit the '{config}' preset ({bad[0]} differs); pass a model "
                               f"file of the same preset to --init-vae, or leave --init-vae out")
        getattr(model, part).load_state_dict(theirs)
    vae_meta = dict(source.meta.get("stages", {}).get("vae", {}), copied_from=str(init))
    model.meta = {"trained": False, "stages": {"vae": vae_meta}, "sources": source.meta.get("sources", []),
                  "non_commercial": bool(source.meta.get("non_commercial", False))}
    out.mkdir(parents=True, exist_ok=True)
    save_model(model, model_path)
    steps = int(vae_meta.get("steps", DEFAULT_STEPS["vae"]))
    torch.save({"step": steps, "total": steps, "copied_from": str(init)}, state_path)
    return True
