"""Saving and loading models.

A model file is a plain dict of primitives and tensors written with `torch.save` and read with
`torch.load(..., weights_only=True)`, so no code from a file is ever executed:
    {"format": "remogen", "format_version": 1, "config": {...}, "state_dict": {...}, "meta": {...}}

meta["stages"] (written by model_runtime.train) maps each trained stage to its steps and losses;
meta["trained"] is False for random weights. Loading a file whose record shows untrained stages warns.
"""
from __future__ import annotations

import os
import warnings
import zipfile
from pathlib import Path

import torch

from .config import ModelConfig, resolve_config
from .errors import ModelFileError
from .model import ReMoGenModel, non_finite_weight
from .text_blend import attach_prompt_blend

FORMAT = "remogen"
FORMAT_VERSION = 1
SUPPORTED_VERSIONS = (1,)
DEFAULT_WEIGHTS = Path(__file__).resolve().parent / "weights" / "default.pt"


def save_model(model: ReMoGenModel, path: str | os.PathLike, meta: dict | None = None) -> Path:
    """Write atomically (temp file + rename) so an interrupted save never leaves a truncated model.

    A model with a NaN or infinite weight is refused (ModelFileError): such a file could only produce NaN poses.
    """
    path = Path(path)
    bad = non_finite_weight(model.state_dict())
    if bad:
        raise ModelFileError(f"not saving {path}: the model's weight {bad} holds NaN or inf values (training "
                             "diverged); resume from an earlier state or lower the learning rate")
    path.parent.mkdir(parents=True, exist_ok=True)
    payload = {"format": FORMAT, "format_version": FORMAT_VERSION, **model_payload(model),
               "meta": dict(model.meta, **(meta or {}))}
    tmp = path.with_suffix(path.suffix + ".tmp")
    torch.save(payload, tmp)
    os.replace(tmp, path)
    return path


def model_payload(model: ReMoGenModel) -> dict:
    """A model's config and weights as plain data (what a model file holds besides its meta)."""
    return {"config": model.cfg.to_dict(),
            "state_dict": {k: v.detach().cpu() for k, v in model.state_dict().items()}}


def model_from_payload(payload: dict) -> ReMoGenModel:
    """The model of a `model_payload` (already read safely), in float32 on the CPU."""
    model = ReMoGenModel(ModelConfig.from_dict(payload["config"]))
    model.load_state_dict(payload["state_dict"], strict=True)
    return model


def _read_payload(path: Path) -> dict:
    if not path.exists():
        raise ModelFileError(f"model file {path} not found; check the path or pass "
                             "load_model(config='default') for an untrained model")
    if path.is_dir():
        raise ModelFileError(f"{path} is a folder; pass the path of a .pt model file")
    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
    except (zipfile.BadZipFile, EOFError, RuntimeError) as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise ModelFileError(f"{path} is truncated or not a PyTorch file ({first}); "
                             "re-download or re-train the model") from None
    except Exception as exc:  # weights_only refuses pickled code: a foreign or unsafe file
        raise ModelFileError(f"{path} is not a ReMoGen model file (it cannot be loaded safely: "
                             f"{type(exc).__name__}); use a file written by model_runtime") from None
    if not isinstance(payload, dict) or payload.get("format") != FORMAT:
        raise ModelFileError(f"{path} is not a ReMoGen model file (no 'remogen' format marker); "
                             "use a file written by model_runtime")
    version = payload.get("format_version")
    if isinstance(version, int) and not isinstance(version, bool) and version > FORMAT_VERSION:
        raise ModelFileError(f"{path} has model format version {version}, this runtime reads up to "
                             f"{FORMAT_VERSION}; update model_runtime")
    if version not in SUPPORTED_VERSIONS or isinstance(version, bool):
        raise ModelFileError(f"{path} has model format version {version!r}, this runtime reads "
                             f"{', '.join(map(str, SUPPORTED_VERSIONS))}; the file is damaged: re-train or "
                             "re-download it")
    for key in ("config", "state_dict"):
        if not isinstance(payload.get(key), dict):
            raise ModelFileError(f"{path} has no '{key}' (or it is not a dict); the file is damaged or incomplete: "
                                 "re-train or re-download it")
    return payload


def untrained_stages(meta: dict) -> list[str] | None:
    """The required training stages a model file's meta shows as not trained; None when the file does not say."""
    from .training.stages import REQUIRED_STAGES
    stages = meta.get("stages")
    if isinstance(stages, dict):
        return [s for s in REQUIRED_STAGES if _stage_steps(stages.get(s)) <= 0]
    if meta.get("trained") is False:
        return list(REQUIRED_STAGES)
    return None


def _stage_steps(record) -> int:
    """Steps a stage record shows; a record without a readable count counts as trained."""
    if not isinstance(record, dict):
        return 0
    try:
        return int(record.get("steps", 1))
    except (TypeError, ValueError):
        return 1


def load_model(path: str | os.PathLike | None = None, *, config: "str | ModelConfig | None" = None,
               seed: int = 0, device: str = "cpu", precision: str = "fp32",
               warn_untrained: bool = True) -> ReMoGenModel:
    """Load a model file, or build a randomly initialised model from a config.

    load_model()                  -> the shipped default weights
    load_model("my.pt")           -> that file
    load_model(config="default")  -> random weights of that preset ("tiny", "default", "paper")
    precision="bf16" / "int8" runs the diffusion networks in bfloat16 / int8 (see ReMoGenModel.set_precision).
    warn_untrained=False: no warning for a file whose later stages are untrained (training reads such files).
    """
    if config is not None and path is not None:
        raise ModelFileError("pass either a model file path or config=..., not both")
    if config is not None:
        return _random_model(resolve_config(config), seed).to(device).eval().set_precision(precision)
    p = Path(path) if path is not None else DEFAULT_WEIGHTS
    if path is None and not p.exists():
        raise ModelFileError(f"no shipped weights at {p}; train them (python -m model_runtime.train) "
                             "or pass load_model(config='default') for an untrained model")
    payload = _read_payload(p)
    try:
        model = model_from_payload(payload)
    except RuntimeError as exc:
        first = str(exc).strip().splitlines()[0]
        raise ModelFileError(f"{p} does not match its own config ({first[:160]}); the file is damaged "
                             "or from another version") from None
    bad = non_finite_weight(payload["state_dict"])
    if bad:
        raise ModelFileError(f"{p} holds NaN or inf values in its weight {bad}, so every pose would be NaN; "
                             "re-train or re-download the model")
    meta = payload.get("meta")
    model.meta = dict(meta) if isinstance(meta, dict) else {}
    attach_prompt_blend(model)
    if warn_untrained:
        _warn_untrained(p, model.meta)
    return model.to(device).eval().set_precision(precision)


def _warn_untrained(path: Path, meta: dict) -> None:
    from .training.stages import REQUIRED_STAGES
    missing = untrained_stages(meta)
    if not missing:
        return
    what = ("holds untrained (random) weights" if len(missing) == len(REQUIRED_STAGES) else
            f"is only partly trained (untrained: {', '.join(missing)})")
    warnings.warn(f"{path} {what}, so its motion will be poor; train the missing stages (python -m "
                  "model_runtime.train STAGE --out FOLDER continues from FOLDER/model.pt)", stacklevel=3)


def _random_model(cfg: ModelConfig, seed: int) -> ReMoGenModel:
    with torch.random.fork_rng():
        torch.manual_seed(seed)
        model = ReMoGenModel(cfg)
        model.eval()
        hist = torch.randn(4, cfg.history, cfg.feature_dim)
        z = torch.randn(4, cfg.latent_tokens, cfg.latent_dim)
        model.compute_decoder_sensitivity(hist, z)
    model.meta = {"trained": False, "note": "random weights"}
    return model
