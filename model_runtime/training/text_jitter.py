"""Caption embeddings turned by a random angle, so the prior reads a prompt by its nearest captions.

The prior trains on a few thousand caption phrasings, each one point on the unit sphere of sentence vectors. A
prompt in other words ("someone sprints across the room") lands off those points, at a cosine of about 0.65-0.8
to its nearest phrasing, in directions no caption ever took; what the prior does there was never trained. A
share of the training captions is therefore turned away from its own vector by a random angle, in a random
direction orthogonal to it: in 256 dimensions such a direction is almost orthogonal to every other caption too,
so the turned vector keeps its nearest caption and the prior learns that the off-caption part means nothing.
(Conditioning augmentation in the manner of StackGAN's; isotropic noise of the same size would also shrink the
vector, which a unit-norm encoder never gives.)
"""
from __future__ import annotations

import torch


def jitter_text(emb: torch.Tensor, min_cos: float, share: float, gen: torch.Generator) -> torch.Tensor:
    """Unit vectors (B, D) -> the same with `share` of the rows turned to a cosine drawn uniformly in
    [min_cos, 1] with their old direction (rows of zeros, the unknown prompt, stay). min_cos >= 1: unchanged."""
    if min_cos >= 1.0 or share <= 0.0 or emb.shape[0] == 0:
        return emb
    b, d = emb.shape
    pick = torch.rand(b, generator=gen) < share
    cos = min_cos + (1.0 - min_cos) * torch.rand(b, generator=gen)
    rand = torch.randn(b, d, generator=gen).to(emb)
    unit = torch.nn.functional.normalize(emb, dim=-1)
    ortho = torch.nn.functional.normalize(rand - (rand * unit).sum(-1, keepdim=True) * unit, dim=-1)
    cos = cos.to(emb).unsqueeze(-1)
    turned = cos * unit + torch.sqrt(1.0 - cos * cos) * ortho
    keep = ~pick.to(emb.device) | (emb.norm(dim=-1) == 0)
    return torch.where(keep.unsqueeze(-1), emb, turned)
