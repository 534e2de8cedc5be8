"""Model configuration (a plain dataclass stored in every checkpoint) and its size presets.

Every field is checked against sane bounds when a config is built, so a typo or a damaged file gives a
one-line error instead of a model that tries to allocate hundreds of gigabytes.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields, replace

from .errors import InputError, ModelFileError

FEATURE_DIM = 276   # the per-frame motion features (features.py); fixed by the skeleton and the layout

# Integer fields: (smallest, largest) allowed. Generous for research, small enough to stay in memory.
_INT_BOUNDS = {
    "history": (1, 32), "future": (1, 64), "latent_tokens": (1, 16), "latent_dim": (1, 2048),
    "vae_dim": (1, 2048), "vae_layers": (1, 32), "vae_heads": (1, 64), "vae_ff": (1, 8192),
    "den_dim": (1, 2048), "den_layers": (1, 32), "den_heads": (1, 64), "den_ff": (1, 8192),
    "diffusion_steps": (1, 1000), "mim_dim": (1, 2048), "mim_heads": (1, 64), "mim_ff_mult": (1, 8),
    "partner_window": (1, 100), "voxel_resolution": (1, 128), "voxel_patch": (1, 128), "scene_layers": (0, 32),
    "fwsr_dim": (1, 2048), "fwsr_heads": (1, 64),
}
# Text encoder fields per encoder name (text.py): integer bounds, and for the static table its id.
_TEXT_BOUNDS = {"hashed_ngram": {"dim": (1, 2048), "buckets": (1, 65536), "seed": (0, 2 ** 63 - 1)},
                "minilm_static": {"dim": (1, 2048)}}
_TEXT_TABLE_KEY = {"minilm_static": "table"}
# The id of the static text table that ships in model_runtime/text_tables/ (python -m model_runtime.text_build
# prints it; a test checks that the two agree).
TEXT_TABLE_ID = "4602821ace6dbfdb"
STATIC_TEXT = {"name": "minilm_static", "dim": 128, "table": TEXT_TABLE_ID}
# (width, heads) pairs: attention splits the width evenly over the heads
_HEADS = (("vae_dim", "vae_heads"), ("den_dim", "den_heads"), ("mim_dim", "mim_heads"), ("fwsr_dim", "fwsr_heads"))
_MAX_SCENE_EXTENT = 10.0   # metres from the ego, per axis


def _int_problem(name: str, value, lo: int, hi: int) -> str | None:
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        return f"{name} = {value!r} must be an integer in {lo}..{hi}"
    return None


def _config_problem(c: "ModelConfig") -> str | None:
    """What is wrong with a config, in a few words, or None."""
    for name, (lo, hi) in _INT_BOUNDS.items():
        problem = _int_problem(name, getattr(c, name), lo, hi)
        if problem:
            return problem
    if c.feature_dim != FEATURE_DIM:
        return f"feature_dim = {c.feature_dim!r} must be {FEATURE_DIM}"
    if not isinstance(c.preset, str) or len(c.preset) > 64:
        return f"preset = {c.preset!r} must be a short name"
    for name in ("dropout", "rel_omega", "fwsr_beta"):
        v = getattr(c, name)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            return f"{name} = {v!r} must be a finite number"
    if not 0.0 <= c.dropout < 1.0 or c.fwsr_beta < 0.0 or not 0.0 < c.rel_omega <= 10.0:
        return (f"dropout {c.dropout!r}, fwsr_beta {c.fwsr_beta!r} or rel_omega {c.rel_omega!r} is out of range "
                "(dropout in [0, 1), fwsr_beta >= 0, rel_omega in (0, 10])")
    for width, heads in _HEADS:
        if getattr(c, width) % getattr(c, heads):
            return f"{width} = {getattr(c, width)} must be a multiple of {heads} = {getattr(c, heads)}"
    if c.future < c.history or c.partner_window < c.history:
        return f"future ({c.future}) and partner_window ({c.partner_window}) must be >= history ({c.history})"
    if c.voxel_patch > c.voxel_resolution or c.voxel_resolution % c.voxel_patch:
        return f"voxel_resolution = {c.voxel_resolution} must be a multiple of voxel_patch = {c.voxel_patch}"
    layers = c.inject_layers
    if (not isinstance(layers, tuple) or len(set(layers)) != len(layers)
            or any(_int_problem("", i, 0, c.den_layers - 1) for i in layers)):
        return f"inject_layers = {layers!r} must be distinct denoiser layers in 0..{c.den_layers - 1}"
    b = c.scene_bounds
    if (not isinstance(b, tuple) or len(b) != 3
            or not all(isinstance(ax, tuple) and len(ax) == 2 and all(_is_number(v) for v in ax) for ax in b)
            or not all(-_MAX_SCENE_EXTENT <= lo < hi <= _MAX_SCENE_EXTENT for lo, hi in b)):
        return f"scene_bounds = {b!r} must be three (low, high) pairs in metres within +-{_MAX_SCENE_EXTENT:g}"
    return _text_problem(c.text)


def _text_problem(t) -> str | None:
    """What is wrong with a text encoder config, or None: the fields its encoder name needs, and no others."""
    if not isinstance(t, dict) or not isinstance(t.get("name"), str):
        return f"text = {t!r} must be a dict with a text encoder 'name'"
    bounds = _TEXT_BOUNDS.get(t["name"])
    if bounds is None:
        return f"text['name'] = {t['name']!r} must be one of {', '.join(_TEXT_BOUNDS)}"
    table_key = _TEXT_TABLE_KEY.get(t["name"])
    expected = {"name", *bounds, *([table_key] if table_key else [])}
    if set(t) != expected:
        return f"text = {t!r} must have exactly the fields {', '.join(sorted(expected))}"
    for key, (lo, hi) in bounds.items():
        problem = _int_problem(f"text[{key!r}]", t.get(key), lo, hi)
        if problem:
            return problem
    if table_key and not (isinstance(t[table_key], str) and 1 <= len(t[table_key]) <= 64
                          and t[table_key].isalnum()):
        return f"text[{table_key!r}] = {t[table_key]!r} must be a text table id (letters and digits)"
    return None


# The Meta-Interaction Modules by name: the keys of alpha and of a model's modules (here so the input checks need
# not import the networks).
MODULE_NAMES = ("hhi", "hsi")


def _is_number(v) -> bool:
    return not isinstance(v, bool) and isinstance(v, (int, float)) and math.isfinite(v)


@dataclass(frozen=True)
class ModelConfig:
    preset: str = "default"
    feature_dim: int = 276
    history: int = 2            # H frames of history (paper)
    future: int = 8             # F frames per segment (paper)
    latent_tokens: int = 1
    latent_dim: int = 64
    dropout: float = 0.1
    # motion VAE (encoder and decoder each have vae_layers)
    vae_dim: int = 128
    vae_layers: int = 2
    vae_heads: int = 4
    vae_ff: int = 256
    # latent denoiser
    den_dim: int = 128
    den_layers: int = 4
    den_heads: int = 4
    den_ff: int = 256
    diffusion_steps: int = 10
    text: dict = field(default_factory=lambda: dict(STATIC_TEXT))   # a file's stored text config wins
    # Meta-Interaction Modules
    mim_dim: int = 64
    mim_heads: int = 4
    mim_ff_mult: int = 1         # FFN width of a Meta-Interaction block, times den_dim
    inject_layers: tuple = (1,)          # one injection point keeps the default under 5 ms a frame
    partner_window: int = 10    # partner frames the HHI encoder sees (1 s)
    partner_line_cues: bool = False   # the HHI encoder also reads where the partner's line passes (OthersEncoder)
    voxel_resolution: int = 32
    voxel_patch: int = 8
    scene_layers: int = 1
    # ego-local box (x right, y forward, z up; metres). Forward-looking so obstacles are seen in time.
    scene_bounds: tuple = ((-1.2, 1.2), (-0.6, 1.8), (0.1, 1.2))
    rel_omega: float = 0.25
    # FWSR
    fwsr_dim: int = 64
    fwsr_heads: int = 4
    fwsr_beta: float = 1.0

    def __post_init__(self) -> None:
        problem = _config_problem(self)
        if problem:
            err = InputError(f"model config: {problem}; change that field")
            err.problem = problem   # read by from_dict to word the model-file error
            raise err

    @property
    def text_dim(self) -> int:
        return int(self.text["dim"])

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> "ModelConfig":
        """The config stored in a model file; ModelFileError when it is not a valid one."""
        if not isinstance(d, dict):
            raise ModelFileError(f"the model file's config is a {type(d).__name__}, not a dict; the file is damaged: "
                                 "re-train or re-download it")
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(map(str, d)) - known)
        if unknown:
            raise ModelFileError(f"model file has config fields this runtime does not know ({', '.join(unknown)}); "
                                 "update model_runtime or use a matching model file")
        problem = None
        try:
            d = dict(d)
            if "inject_layers" in d:
                d["inject_layers"] = tuple(d["inject_layers"])
            if "scene_bounds" in d:
                d["scene_bounds"] = tuple(tuple(b) for b in d["scene_bounds"])
            return cls(**d)
        except InputError as exc:
            problem = getattr(exc, "problem", str(exc))
        except TypeError:   # inject_layers or scene_bounds not a list, a field name not a string
            problem = "a field has the wrong type"
        raise ModelFileError(f"the model file's config is invalid ({problem}); the file is damaged or from another "
                             "version: re-train or re-download it")


PRESETS: dict[str, ModelConfig] = {
    # tiny: for unit tests and smoke runs only
    "tiny": ModelConfig(preset="tiny", latent_dim=16, vae_dim=32, vae_layers=1, vae_heads=2, vae_ff=64,
                        den_dim=32, den_layers=2, den_heads=2, den_ff=64, mim_dim=32, mim_heads=2,
                        inject_layers=(0, 1), fwsr_dim=32, fwsr_heads=2,
                        text={"name": "hashed_ngram", "dim": 32, "buckets": 1024, "seed": 1234}),
    # default: what we ship; small enough to run far ahead of real time on a laptop CPU
    "default": ModelConfig(),
    # paper: the paper's sizes (VAE d=256 x 7 layers, denoiser d=512 x 8 layers), for comparison
    "paper": ModelConfig(preset="paper", latent_dim=128, vae_dim=256, vae_layers=7, vae_heads=4, vae_ff=1024,
                         den_dim=512, den_layers=8, den_heads=8, den_ff=1024, mim_dim=256, mim_heads=4, mim_ff_mult=1,
                         inject_layers=(3,), fwsr_dim=128, scene_layers=2,
                         scene_bounds=((-0.6, 0.6), (-0.6, 0.6), (0.1, 1.2)),
                         text=dict(STATIC_TEXT)),
}


def resolve_config(config: "str | ModelConfig") -> ModelConfig:
    if isinstance(config, ModelConfig):
        return config
    if config not in PRESETS:
        raise InputError(f"unknown model config {config!r}; use one of {', '.join(PRESETS)} or a ModelConfig")
    return replace(PRESETS[config])
