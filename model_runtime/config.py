"""Model configuration (a plain dataclass stored in every checkpoint) and its size presets."""
from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields, replace

from .errors import ModelFileError


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
    text: dict = field(default_factory=lambda: {"name": "hashed_ngram", "dim": 128, "buckets": 8192, "seed": 1234})
    # Meta-Interaction Modules
    mim_dim: int = 64
    mim_heads: int = 4
    mim_ff_mult: int = 1         # FFN width of a Meta-Interaction block, times den_dim
    inject_layers: tuple = (1,)          # one injection point keeps the default under 5 ms a frame
    partner_window: int = 10    # partner frames the HHI encoder sees (1 s)
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

    @property
    def text_dim(self) -> int:
        return int(self.text["dim"])

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> "ModelConfig":
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(d) - known)
        if unknown:
            raise ModelFileError(f"model file has config fields this runtime does not know ({', '.join(unknown)}); "
                                 "update model_runtime or use a matching model file")
        d = dict(d)
        if "inject_layers" in d:
            d["inject_layers"] = tuple(d["inject_layers"])
        if "scene_bounds" in d:
            d["scene_bounds"] = tuple(tuple(b) for b in d["scene_bounds"])
        return cls(**d)


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
                         text={"name": "hashed_ngram", "dim": 256, "buckets": 16384, "seed": 1234}),
}


def resolve_config(config: "str | ModelConfig") -> ModelConfig:
    if isinstance(config, ModelConfig):
        return config
    if config not in PRESETS:
        from .errors import InputError
        raise InputError(f"unknown model config {config!r}; use one of {', '.join(PRESETS)} or a ModelConfig")
    return replace(PRESETS[config])
