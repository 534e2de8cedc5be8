"""Meta-Interaction Modules: context encoders, Meta-Interaction blocks, and their composition.

A module = one context encoder (partner TCN or scene ViT) + one block per injection layer of the
denoiser. A block returns the residual Delta = h_ffn - h (paper supplement, "Meta-Interaction Block");
`compose_residuals` sums alpha_i * Delta_i and clamps the sum's per-sample L2 norm to the largest
branch norm.
"""
from __future__ import annotations

import torch
from torch import nn

from ..skeleton import NUM_JOINTS
from .common import (FastEval, RelativeBiasCrossAttention, SelfAttention, encoder_layer, norm_attention,
                     norm_attention_weights, plain_linears)

PARTNER_FRAME_DIM = NUM_JOINTS * 3 * 2 + 1  # positions, velocities, "present" flag


LINE_CUES = 3          # per frame: the partner's line offset from the ego, time to its closest point, speed
MAX_ARRIVAL_S = 5.0   # s: the time to the closest point is clipped to +-this


def line_cues(partner: torch.Tensor, present: torch.Tensor) -> torch.Tensor:
    """(B, W, 3) per frame, from the partner's pelvis in the ego's canonical frame and its velocity: the signed
    distance from the ego's origin to the partner's line of travel (m, + where the ego is on its right), the time until it
    is closest (s, clipped), its speed (m/s); zero where it or the frame before is absent.

    Why: which side to step to depends on a line 0-0.3 m off the ego seen from 2-4 m (a few degrees); the raw
    joints carry it only as the product of position and velocity, which the encoder learned poorly."""
    p = partner[..., 0, :2]
    v = torch.zeros_like(p)
    v[:, 1:] = (p[:, 1:] - p[:, :-1]) * 10.0             # the model runs at 10 fps
    both = torch.zeros_like(present)
    both[:, 1:] = present[:, 1:] & present[:, :-1]
    speed = v.norm(dim=-1)
    unit = v / speed.clamp_min(1e-3).unsqueeze(-1)
    offset = -(p[..., 0] * unit[..., 1] - p[..., 1] * unit[..., 0])   # + : the origin is on the partner's right
    arrival = (-(p * v).sum(-1) / speed.pow(2).clamp_min(1e-2)).clamp(-MAX_ARRIVAL_S, MAX_ARRIVAL_S)
    moving = both & (speed > 0.2)
    cues = torch.stack((offset, arrival / MAX_ARRIVAL_S, speed), -1)
    return cues * moving.unsqueeze(-1).to(cues.dtype)


class OthersEncoder(nn.Module):
    """TCN over the partner's recent joints in the ego's canonical frame -> one token per frame."""

    def __init__(self, window: int, d: int, with_line_cues: bool = False) -> None:
        super().__init__()
        self.with_line_cues = with_line_cues
        self.inp = nn.Conv1d(PARTNER_FRAME_DIM + (LINE_CUES if with_line_cues else 0), d, 1)
        self.convs = nn.ModuleList(nn.Conv1d(d, d, 3, padding=dil, dilation=dil) for dil in (1, 2, 4))
        self.pos = nn.Parameter(torch.randn(window, d) * 0.02)
        self.norm = nn.LayerNorm(d)

    def forward(self, partner: torch.Tensor, present: torch.Tensor) -> torch.Tensor:
        """partner (B, W, 22, 3) canonical joints, present (B, W) bool -> tokens (B, W, d)."""
        b, w = partner.shape[:2]
        pos = partner.reshape(b, w, -1) * present.unsqueeze(-1)
        vel = torch.cat((torch.zeros_like(pos[:, :1]), pos[:, 1:] - pos[:, :-1]), 1)
        both = present[:, 1:] & present[:, :-1]
        vel[:, 1:] = vel[:, 1:] * both.unsqueeze(-1)
        parts = [pos, vel * 10.0, present.unsqueeze(-1).to(pos.dtype)]
        if self.with_line_cues:
            parts.append(line_cues(partner, present).to(pos.dtype))
        x = torch.cat(parts, -1).transpose(1, 2)
        x = self.inp(x)
        for conv in self.convs:
            x = x + nn.functional.gelu(conv(x))
        return self.norm(x.transpose(1, 2) + self.pos)


class SceneEncoder(nn.Module):
    """ViT over the ego-local occupancy grid, plus one goal token -> (B, 1 + N_patches, d)."""

    def __init__(self, resolution: int, patch: int, d: int, heads: int, layers: int, dropout: float) -> None:
        super().__init__()
        self.patch, self.n = patch, resolution // patch
        self.patch_proj = nn.Linear(patch ** 3, d)
        self.pos = nn.Parameter(torch.randn(self.n ** 3, d) * 0.02)
        self.goal_mlp = nn.Sequential(nn.Linear(5, d), nn.GELU(), nn.Linear(d, d))
        self.layers = nn.ModuleList(encoder_layer(d, heads, 2 * d, dropout) for _ in range(layers))
        self.norm = nn.LayerNorm(d)

    def forward(self, occupancy: torch.Tensor, goal: torch.Tensor, has_goal: torch.Tensor) -> torch.Tensor:
        """occupancy (B, R, R, R) in [0, 1]; goal (B, 3) canonical; has_goal (B,) bool."""
        b, p, n = occupancy.shape[0], self.patch, self.n
        patches = occupancy.reshape(b, n, p, n, p, n, p).permute(0, 1, 3, 5, 2, 4, 6).reshape(b, n ** 3, p ** 3)
        tokens = self.patch_proj(patches) + self.pos
        g = goal * has_goal.unsqueeze(-1)
        dist = g[:, :2].norm(dim=-1, keepdim=True)
        goal_tok = self.goal_mlp(torch.cat((g, dist, has_goal.unsqueeze(-1).to(g.dtype)), -1)).unsqueeze(1)
        x = torch.cat((goal_tok, tokens), 1)
        for layer in self.layers:
            x = layer(x)
        return self.norm(x)


class MetaInteractionBlock(FastEval):
    """Self-attn -> relation-aware cross-attn -> FiLM (tanh) -> FFN; returns the residual Delta."""

    def __init__(self, d: int, d_ctx: int, heads: int, omega: float, dropout: float, ff_mult: int = 2) -> None:
        super().__init__()
        self.norm1 = nn.LayerNorm(d)
        self.self_attn = SelfAttention(d, heads, dropout)
        self.norm2 = nn.LayerNorm(d)
        self.cross = RelativeBiasCrossAttention(d, d_ctx, d_ctx, heads, omega)
        self.film = nn.Linear(d_ctx, 2 * d)
        self.norm3 = nn.LayerNorm(d)
        self.ffn = nn.Sequential(nn.Linear(d, ff_mult * d), nn.GELU(), nn.Linear(ff_mult * d, d))

    def zero_init(self) -> None:
        """Start training as an exact no-op so the frozen prior is the starting point."""
        for lin in (self.self_attn.out, self.film, self.ffn[-1]):
            nn.init.zeros_(lin.weight)
            nn.init.zeros_(lin.bias)

    def collect_weights(self) -> tuple | None:
        sa, ffn = self.self_attn, self.ffn
        if not plain_linears(sa.qkv, sa.out, self.film, ffn[0], ffn[2]):
            return None
        return (norm_attention_weights(self.norm1, sa), self.norm2.weight, self.norm2.bias, self.norm2.eps,
                self.cross, self.film.weight, self.film.bias, self.norm3.weight, self.norm3.bias, self.norm3.eps,
                ffn[0].weight, ffn[0].bias, ffn[2].weight, ffn[2].bias)

    def forward(self, h: torch.Tensor, ctx: torch.Tensor, ctx_mask: torch.Tensor | None = None,
                kv: tuple[torch.Tensor, torch.Tensor] | None = None) -> torch.Tensor:
        w = self.eval_weights()
        if w is None:
            h1 = h + self.self_attn(self.norm1(h))
            r = self.cross(self.norm2(h1), ctx, ctx_mask, kv)
            gamma, beta = self.film(r).chunk(2, dim=-1)
            h_mod = (1 + torch.tanh(gamma)) * h1 + torch.tanh(beta)
            h_ffn = h_mod + self.ffn(self.norm3(h_mod))
            return h_ffn - h
        # the same maths with the weights from the cached tuple (FastEval)
        attn, n2w, n2b, e2, cross, fw, fb, n3w, n3b, e3, f1w, f1b, f2w, f2b = w
        f = nn.functional
        d = h.shape[-1]
        h1 = h + norm_attention(h, attn)
        r = cross(f.layer_norm(h1, (d,), n2w, n2b, e2), ctx, ctx_mask, kv)
        gamma, beta = f.linear(r, fw, fb).chunk(2, dim=-1)
        h_mod = (1 + torch.tanh(gamma)) * h1 + torch.tanh(beta)
        return h_mod + f.linear(f.gelu(f.linear(f.layer_norm(h_mod, (d,), n3w, n3b, e3), f1w, f1b)), f2w, f2b) - h


class MetaInteractionModule(nn.Module):
    """One domain's adapter: its context encoder and a block per injection layer."""

    def __init__(self, encoder: nn.Module, inject_layers: tuple[int, ...], d: int, d_ctx: int, heads: int,
                 omega: float, dropout: float, ff_mult: int = 2) -> None:
        super().__init__()
        self.encoder = encoder
        self.inject_layers = tuple(inject_layers)
        self.blocks = nn.ModuleList(MetaInteractionBlock(d, d_ctx, heads, omega, dropout, ff_mult)
                                    for _ in self.inject_layers)

    def zero_init(self) -> None:
        for blk in self.blocks:
            blk.zero_init()

    def block_at(self, layer: int) -> MetaInteractionBlock | None:
        """The block injected after denoiser layer `layer`, or None."""
        return self.blocks[self.inject_layers.index(layer)] if layer in self.inject_layers else None


def compose_residuals(deltas: list[torch.Tensor], alphas: list[float | torch.Tensor]) -> torch.Tensor | None:
    """Delta_final = s * sum_i alpha_i Delta_i, s = min(1, max_i ||Delta_i|| / ||sum||).

    Norms are per sample over all (T x d) entries. s is exactly 1 whenever the sum is within the
    largest branch norm: besides "unchanged when under", this keeps the gradient alive at Delta = 0,
    where zero-initialised modules start (a ratio with an epsilon would give s = 0 there and no
    gradient at all). Branches with alpha == 0 should not be passed in (the caller skips them, so
    all-zero alphas give exactly the prior).
    """
    if not deltas:
        return None
    total = sum(a * d for a, d in zip(alphas, deltas))
    norms = torch.stack([d.flatten(1).norm(dim=1) for d in deltas], 0)  # (n, B)
    largest = norms.max(0).values
    total_norm = total.flatten(1).norm(dim=1)
    over = total_norm > largest
    scale = torch.where(over, largest / torch.where(over, total_norm, torch.ones_like(total_norm)), 1.0)
    return total * scale.view(-1, *([1] * (total.dim() - 1)))
