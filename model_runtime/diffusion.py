"""DDPM with a cosine schedule and x0 prediction (few steps: 10 in the paper).

The denoiser predicts the clean latent x0; sampling walks the posterior q(x_{t-1} | x_t, x0).
Classifier-free guidance mixes the conditional and unconditional x0 predictions, which the model
computes as one batch of two (see `ReMoGenModel.predict_x0`).
"""
from __future__ import annotations

import math

import torch


class CosineSchedule(torch.nn.Module):
    def __init__(self, steps: int = 10, s: float = 0.008) -> None:
        super().__init__()
        self.steps = steps
        t = torch.arange(steps + 1, dtype=torch.float64) / steps
        f = torch.cos((t + s) / (1 + s) * math.pi / 2) ** 2
        abar = f / f[0]
        betas = (1 - abar[1:] / abar[:-1]).clamp(max=0.999)
        alphas = 1 - betas
        abar = torch.cumprod(alphas, 0)
        abar_prev = torch.cat((torch.ones(1, dtype=torch.float64), abar[:-1]))
        var = betas * (1 - abar_prev) / (1 - abar)
        for name, v in {
            "sqrt_abar": abar.sqrt(), "sqrt_one_minus_abar": (1 - abar).sqrt(),
            "coef_x0": betas * abar_prev.sqrt() / (1 - abar),
            "coef_xt": (1 - abar_prev) * alphas.sqrt() / (1 - abar),
            "post_std": var.clamp_min(1e-20).sqrt(),
        }.items():
            self.register_buffer(name, v.float(), persistent=False)

    def q_sample(self, x0: torch.Tensor, t: torch.Tensor, noise: torch.Tensor) -> torch.Tensor:
        """Noise clean latents x0 (B, ...) to integer steps t (B,)."""
        shape = (-1,) + (1,) * (x0.dim() - 1)
        return self.sqrt_abar[t].view(shape) * x0 + self.sqrt_one_minus_abar[t].view(shape) * noise

    def step(self, x_t: torch.Tensor, t: int, x0: torch.Tensor, noise: torch.Tensor | None) -> torch.Tensor:
        """One reverse step from integer t to t-1 given the predicted x0; at t == 0 returns x0."""
        if t == 0:
            return x0
        mean = self.coef_x0[t] * x0 + self.coef_xt[t] * x_t
        return mean + self.post_std[t] * noise
