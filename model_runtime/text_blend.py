"""Prompt vectors moved part of the way toward their nearest training phrasing: an evaluation option, not the
runtime's default (docs/HISTORY.md, "Reading a prompt by its nearest training phrasing").

A prompt in words no caption uses lands off every training phrasing on the sentence-vector sphere, and the prior
was never trained there: "someone sprints across the room" lies at cosine 0.66 from "someone is running" and
jogs at 0.85 m/s. Mixing a share of the nearest phrasing's vector into the prompt's pulls it toward what the
prior knows; a prompt that is itself a training phrasing keeps its own vector (its nearest phrasing is itself).
"""
from __future__ import annotations

import torch

from .text import CachedEncoder, TextEncoder

BLEND_TOP = 16            # phrasings the softmax weighs
BLEND_TEMPERATURE = 0.01  # of the softmax over their cosines: 0.01 is all but the nearest one alone


class PhrasingBlend(CachedEncoder):
    """`base`'s vector of a prompt, `keep` of it and the rest the softmax-weighted mean of its nearest
    phrasings' vectors, normalised. Prompts the base encoder knows no word of stay zero (the unknown prompt)."""

    def __init__(self, base: TextEncoder, phrasings: list[str], keep: float,
                 top: int = BLEND_TOP, temperature: float = BLEND_TEMPERATURE) -> None:
        super().__init__()
        if not 0.0 <= keep <= 1.0:
            raise ValueError(f"keep {keep} is outside 0-1; give the share of the prompt's own vector to keep")
        if not phrasings:
            raise ValueError("no phrasings to blend toward; give the captions the model was trained on")
        self.base, self.dim, self.keep, self.temperature = base, base.dim, keep, temperature
        self.bank = torch.nn.functional.normalize(base.encode(sorted(set(phrasings))).float(), dim=-1)
        self.top = min(top, len(self.bank))

    def _embed(self, text: str) -> torch.Tensor:
        own = self.base.encode([text])[0].float()
        if float(own.norm()) == 0.0:
            return own
        near = (self.bank @ own).topk(self.top)
        weights = torch.softmax(near.values / self.temperature, 0)
        pull = torch.nn.functional.normalize((weights[:, None] * self.bank[near.indices]).sum(0), dim=0)
        return torch.nn.functional.normalize(self.keep * own + (1.0 - self.keep) * pull, dim=0)


def training_phrasings(captions: list[str]) -> list[str]:
    """Every phrasing the prior's training draws for these captions, with the captions its windows are given
    besides their clips' own (standing still, walking slowly, walking backwards)."""
    from .data.phrasings import caption_phrasings
    from .data.reversals import REVERSED_CAPTION
    from .training.recipe import SLOW_WALK_CAPTION, STILL_CAPTION
    heads = set(captions) | {STILL_CAPTION, SLOW_WALK_CAPTION, REVERSED_CAPTION}
    return sorted({p for c in heads for p in caption_phrasings(c)})
