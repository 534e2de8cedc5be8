"""The exponential moving average of the trained weights that a stage ships."""
from __future__ import annotations

import torch


class EMA:
    """Exponential moving average of the trained weights with the usual warm-up: the decay is
    min(decay, (1 + n) / (10 + n)) after n updates. Without it a short stage (the interaction modules and
    FWSR train for a few hundred to a few thousand steps here) ships weights still pulled toward their
    zero initialisation: at 0.999 after 1000 steps, 37 % of the average is the starting point."""

    def __init__(self, params: list[torch.nn.Parameter], decay: float = 0.999) -> None:
        self.params, self.decay = params, decay
        self.shadow = [p.detach().clone() for p in params]
        self.updates = 0

    def current_decay(self) -> float:
        return min(self.decay, (1 + self.updates) / (10 + self.updates))

    @torch.no_grad()
    def update(self) -> None:
        w = 1 - self.current_decay()
        for s, p in zip(self.shadow, self.params):
            s.lerp_(p.detach(), w)
        self.updates += 1

    @torch.no_grad()
    def swap(self) -> None:
        """Exchange live and EMA weights (call twice to restore)."""
        for s, p in zip(self.shadow, self.params):
            tmp = p.detach().clone()
            p.copy_(s)
            s.copy_(tmp)
