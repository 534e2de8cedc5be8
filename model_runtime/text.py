"""Text encoders. The prior is text-conditioned; everything else in the runtime is text-agnostic.

`TextEncoder` is a protocol: anything with `dim` and `encode(list[str]) -> (B, dim)` tensor works, so a
training setup can plug in a sentence-transformer. The shipped default, `HashedNgramEncoder`, needs no
file and no download: each word is the mean of fixed pseudo-random vectors of its character 3- to
5-grams (and of the whole word), the prompt is the mean of its words. Unseen words still share n-grams
with seen ones ("walking" ~ "walk"), unrelated prompts stay far apart, and the table is rebuilt
bit-identically from the seed, so a checkpoint only stores (dim, buckets, seed).
"""
from __future__ import annotations

import re
import zlib
from collections import OrderedDict
from typing import Protocol

import torch


class TextEncoder(Protocol):
    dim: int

    def encode(self, texts: list[str]) -> torch.Tensor: ...


_WORD = re.compile(r"[a-z0-9]+")
# Words that carry no motion meaning and appear in most captions ("a person ...").
_STOP = frozenset("a an the to of is in on at his her their its and then person human someone s".split())
# Prompts kept encoded (least recently used dropped first): a live rig re-encodes its few prompts every
# change, while a script feeding many distinct prompts must not grow memory without bound.
CACHE_SIZE = 512


class HashedNgramEncoder:
    """Deterministic subword-hashing sentence encoder (no weights on disk)."""

    name = "hashed_ngram"

    def __init__(self, dim: int = 128, buckets: int = 8192, seed: int = 1234) -> None:
        self.dim, self.buckets, self.seed = dim, buckets, seed
        gen = torch.Generator().manual_seed(seed)
        self._table = torch.randn(buckets, dim, generator=gen) / dim ** 0.5
        self._cache: OrderedDict[str, torch.Tensor] = OrderedDict()

    def config(self) -> dict:
        return {"name": self.name, "dim": self.dim, "buckets": self.buckets, "seed": self.seed}

    def _word_vector(self, word: str) -> torch.Tensor:
        marked = f"<{word}>"
        grams = [marked] + [marked[i:i + n] for n in (3, 4, 5) for i in range(len(marked) - n + 1)]
        idx = torch.tensor([zlib.crc32(g.encode()) % self.buckets for g in grams])
        return self._table[idx].mean(0)

    def encode_one(self, text: str) -> torch.Tensor:
        vec = self._cache.get(text)
        if vec is not None:
            self._cache.move_to_end(text)
            return vec
        words = [w for w in _WORD.findall(text.lower()) if w not in _STOP]
        if not words:
            vec = torch.zeros(self.dim)
        else:
            vec = torch.nn.functional.normalize(torch.stack([self._word_vector(w) for w in words]).mean(0), dim=0)
        self._cache[text] = vec
        if len(self._cache) > CACHE_SIZE:
            self._cache.popitem(last=False)
        return vec

    def encode(self, texts: list[str]) -> torch.Tensor:
        return torch.stack([self.encode_one(t) for t in texts])


def build_text_encoder(cfg: dict) -> TextEncoder:
    """Rebuild the encoder a checkpoint was trained with from its stored config."""
    if cfg.get("name") == HashedNgramEncoder.name:
        return HashedNgramEncoder(dim=int(cfg["dim"]), buckets=int(cfg["buckets"]), seed=int(cfg["seed"]))
    from .errors import ModelFileError
    raise ModelFileError(f"unknown text encoder {cfg.get('name')!r} in the model file; "
                         "use a model trained with this version of model_runtime")
