"""Frame-wise Segment Refinement: a per-frame correction of the segment latent z0.

Dynamic tokens (the latest ego history frames and the partner's latest frames) go through a
projection and a self-attention layer; the latent attends to them with relation-aware cross-attention,
a FiLM head turns that into Delta = (1 + tanh g) z0 + tanh b - z0, and Delta is divided per latent
dimension by (1 + beta * s_d), s being the decoder's finite-difference sensitivity (stored buffer).
"""
from __future__ import annotations

import torch
from torch import nn

from ..skeleton import NUM_JOINTS
from .common import RelativeBiasCrossAttention, encoder_layer


class FrameRefiner(nn.Module):
    def __init__(self, cfg) -> None:
        super().__init__()
        d, dz = cfg.fwsr_dim, cfg.latent_dim
        self.beta = cfg.fwsr_beta
        self.hist_proj = nn.Linear(cfg.feature_dim, d)
        self.partner_proj = nn.Linear(NUM_JOINTS * 3 + 1, d)
        self.type_pos = nn.Parameter(torch.randn(2 * cfg.history, d) * 0.02)
        self.frame_emb = nn.Embedding(cfg.future, d)
        self.mixer = encoder_layer(d, cfg.fwsr_heads, 2 * d, cfg.dropout)
        self.z_in = nn.Linear(dz, d)
        self.cross = RelativeBiasCrossAttention(d, d, d, cfg.fwsr_heads, cfg.rel_omega)
        self.film = nn.Linear(d, 2 * dz)
        # decoder sensitivity per latent entry (L * dz), filled by compute_decoder_sensitivity
        self.register_buffer("sensitivity", torch.zeros(cfg.latent_tokens, dz))

    def zero_init(self) -> None:
        nn.init.zeros_(self.film.weight)
        nn.init.zeros_(self.film.bias)

    def forward(self, z0: torch.Tensor, hist: torch.Tensor, partner: torch.Tensor, present: torch.Tensor,
                frame: torch.Tensor) -> torch.Tensor:
        """z0 (B,L,dz); hist (B,H,D) normalised latest history; partner (B,H,22,3) canonical;
        present (B,H) bool; frame (B,) index within the segment. Returns the refined latent."""
        b, h = partner.shape[:2]
        p = torch.cat((partner.reshape(b, h, -1) * present.unsqueeze(-1), present.unsqueeze(-1).float()), -1)
        tokens = torch.cat((self.hist_proj(hist), self.partner_proj(p)), 1) + self.type_pos
        tokens = self.mixer(tokens + self.frame_emb(frame).unsqueeze(1))
        r = self.cross(self.z_in(z0), tokens)
        gamma, beta = self.film(r).chunk(2, dim=-1)
        delta = (1 + torch.tanh(gamma)) * z0 + torch.tanh(beta) - z0
        return z0 + delta / (1 + self.beta * self.sensitivity)
