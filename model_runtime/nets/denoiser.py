"""Latent denoiser G(z_t, t, history, text) -> x0, with hooks where Meta-Interaction residuals enter."""
from __future__ import annotations

from typing import Callable

import torch
from torch import nn

from .common import encoder_layer, sinusoidal_embedding

# inject(layer_index, hidden (B, T, d)) -> residual to add, or None
InjectFn = Callable[[int, torch.Tensor], "torch.Tensor | None"]


class LatentDenoiser(nn.Module):
    """Tokens: [step, text, history (H), z_t (L)] -> x0 prediction read at the z tokens."""

    def __init__(self, cfg) -> None:
        super().__init__()
        d = cfg.den_dim
        self.lt, self.h = cfg.latent_tokens, cfg.history
        self.time_mlp = nn.Sequential(nn.Linear(d, d), nn.GELU(), nn.Linear(d, d))
        self.text_proj = nn.Linear(cfg.text_dim, d)
        self.null_text = nn.Parameter(torch.zeros(d))  # the "no text" token used by CFG
        self.hist_proj = nn.Linear(cfg.feature_dim, d)
        self.z_proj = nn.Linear(cfg.latent_dim, d)
        self.pos = nn.Parameter(torch.randn(2 + self.h + self.lt, d) * 0.02)
        self.layers = nn.ModuleList(encoder_layer(d, cfg.den_heads, cfg.den_ff, cfg.dropout)
                                    for _ in range(cfg.den_layers))
        self.norm = nn.LayerNorm(d)
        self.out = nn.Linear(d, cfg.latent_dim)
        self.d = d

    @property
    def num_tokens(self) -> int:
        return 2 + self.h + self.lt

    def text_tokens(self, text_emb: torch.Tensor, drop: torch.Tensor) -> torch.Tensor:
        """(B, text_dim) and a (B,) bool 'use the null token' mask -> (B, 1, d)."""
        tok = self.text_proj(text_emb)
        return torch.where(drop.unsqueeze(-1), self.null_text.expand_as(tok), tok).unsqueeze(1)

    def time_tokens(self, t: torch.Tensor) -> torch.Tensor:
        """(B,) integer steps -> (B, 1, d)."""
        return self.time_mlp(sinusoidal_embedding(t, self.d, self.pos.dtype)).unsqueeze(1)

    def condition_tokens(self, hist: torch.Tensor, text_tok: torch.Tensor) -> torch.Tensor:
        """[text, history] tokens (B, 1 + H, d); constant over a segment's denoising steps."""
        return torch.cat((text_tok, self.hist_proj(hist)), 1)

    def forward(self, z_t: torch.Tensor, t: torch.Tensor, hist: torch.Tensor, text_tok: torch.Tensor,
                inject: InjectFn | None = None) -> torch.Tensor:
        return self.forward_tokens(z_t, self.time_tokens(t), self.condition_tokens(hist, text_tok), inject)

    def forward_tokens(self, z_t: torch.Tensor, temb: torch.Tensor, cond: torch.Tensor,
                       inject: InjectFn | None = None) -> torch.Tensor:
        x = torch.cat((temb, cond, self.z_proj(z_t)), 1) + self.pos
        for i, layer in enumerate(self.layers):
            x = layer(x)
            if inject is not None:
                delta = inject(i, x)
                if delta is not None:
                    x = x + delta
        return self.out(self.norm(x[:, -self.lt:]))
