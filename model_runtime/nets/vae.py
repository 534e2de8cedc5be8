"""Motion VAE: one latent per segment, decoder D(history, z) -> future (DART-style)."""
from __future__ import annotations

import torch
from torch import nn

from .common import encoder_layer


class MotionVAE(nn.Module):
    def __init__(self, cfg) -> None:
        super().__init__()
        d, self.h, self.f = cfg.vae_dim, cfg.history, cfg.future
        self.lt, self.dz = cfg.latent_tokens, cfg.latent_dim
        self.in_proj = nn.Linear(cfg.feature_dim, d)
        # encoder: [latent queries (L), history (H), future (F)]
        self.enc_queries = nn.Parameter(torch.randn(self.lt, d) * 0.02)
        self.enc_pos = nn.Parameter(torch.randn(self.lt + self.h + self.f, d) * 0.02)
        self.encoder = nn.ModuleList(encoder_layer(d, cfg.vae_heads, cfg.vae_ff, cfg.dropout)
                                     for _ in range(cfg.vae_layers))
        self.enc_norm = nn.LayerNorm(d)
        self.to_dist = nn.Linear(d, 2 * self.dz)
        # decoder: [z (L), history (H), future queries (F)]
        self.z_proj = nn.Linear(self.dz, d)
        self.dec_hist_proj = nn.Linear(cfg.feature_dim, d)
        self.dec_queries = nn.Parameter(torch.randn(self.f, d) * 0.02)
        self.dec_pos = nn.Parameter(torch.randn(self.lt + self.h + self.f, d) * 0.02)
        self.decoder = nn.ModuleList(encoder_layer(d, cfg.vae_heads, cfg.vae_ff, cfg.dropout)
                                     for _ in range(cfg.vae_layers))
        self.dec_norm = nn.LayerNorm(d)
        self.out = nn.Linear(d, cfg.feature_dim)

    def decoder_parts(self) -> nn.Module:
        """The decoder's weights as one module sharing them with this VAE (to train the decoder alone)."""
        parts = nn.Module()
        parts.z_proj, parts.hist_proj, parts.queries, parts.pos = self.z_proj, self.dec_hist_proj, self.dec_queries, \
            self.dec_pos
        parts.layers, parts.norm, parts.out = self.decoder, self.dec_norm, self.out
        return parts

    def encode(self, hist: torch.Tensor, fut: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """hist (B,H,D), fut (B,F,D) normalised -> mu, logvar (B, L, dz)."""
        b = hist.shape[0]
        x = torch.cat((self.enc_queries.expand(b, -1, -1), self.in_proj(torch.cat((hist, fut), 1))), 1)
        x = x + self.enc_pos
        for layer in self.encoder:
            x = layer(x)
        mu, logvar = self.to_dist(self.enc_norm(x[:, :self.lt])).chunk(2, dim=-1)
        return mu, logvar.clamp(-10, 10)

    def decode(self, hist: torch.Tensor, z: torch.Tensor) -> torch.Tensor:
        """hist (B,H,D) normalised, z (B,L,dz) -> normalised future (B,F,D)."""
        b = hist.shape[0]
        x = torch.cat((self.z_proj(z), self.dec_hist_proj(hist), self.dec_queries.expand(b, -1, -1)), 1)
        x = x + self.dec_pos
        for layer in self.decoder:
            x = layer(x)
        return self.out(self.dec_norm(x[:, self.lt + self.h:]))
