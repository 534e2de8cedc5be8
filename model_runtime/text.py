"""Text encoders. The prior is text-conditioned; everything else in the runtime is text-agnostic.

`TextEncoder` is a protocol: anything with `dim` and `encode(list[str]) -> (B, dim)` tensor works, so a
training setup can plug in a sentence-transformer. Two ship, both offline:

- `StaticSubwordEncoder` ("minilm_static", the presets' default): a static sub-word table distilled from the
  sentence encoder all-MiniLM-L6-v2 (model_runtime/text_tables/, built by `python -m model_runtime.text_build`).
  A prompt is BERT-tokenised (wordpiece.py) and its token vectors averaged and normalised, as model2vec does,
  so words carry meaning: "sprint" is close to "run", "leap" to "jump". A checkpoint stores the table's id and
  refuses another table.
- `HashedNgramEncoder` ("hashed_ngram", older checkpoints): each word is the mean of fixed pseudo-random
  vectors of its character 3- to 5-grams, rebuilt bit-identically from (dim, buckets, seed). It knows
  spelling, not meaning.

Each prompt is encoded once and kept (least recently used dropped first).
"""
from __future__ import annotations

import hashlib
import json
import re
import zlib
from collections import OrderedDict
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Protocol

import numpy as np
import torch

from .errors import ModelFileError
from .wordpiece import token_ids

TABLES = Path(__file__).resolve().parent / "text_tables"
STATIC_TABLE = TABLES / "minilm_static.npz"


class TextEncoder(Protocol):
    dim: int

    def encode(self, texts: list[str]) -> torch.Tensor: ...


_WORD = re.compile(r"[a-z0-9]+")
# Words that carry no motion meaning and appear in most captions ("a person ...").
_STOP = frozenset("a an the to of is in on at his her their its and then person human someone s".split())
# Prompts kept encoded (least recently used dropped first): a live rig re-encodes its few prompts every
# change, training draws a few thousand distinct phrasings a stage, and a script feeding many distinct prompts
# must not grow memory without bound (4,096 x 128 floats: 2 MB).
CACHE_SIZE = 4096


class CachedEncoder:
    """Encodes each distinct prompt once: subclasses give `dim` and `_embed(text) -> (dim,)`."""

    dim: int

    def __init__(self) -> None:
        self._cache: OrderedDict[str, torch.Tensor] = OrderedDict()

    def _embed(self, text: str) -> torch.Tensor:
        raise NotImplementedError

    def encode_one(self, text: str) -> torch.Tensor:
        vec = self._cache.get(text)
        if vec is not None:
            self._cache.move_to_end(text)
            return vec
        vec = self._embed(text)
        self._cache[text] = vec
        if len(self._cache) > CACHE_SIZE:
            self._cache.popitem(last=False)
        return vec

    def encode(self, texts: list[str]) -> torch.Tensor:
        return torch.stack([self.encode_one(t) for t in texts])

    def encode_uncached(self, texts: list[str]) -> torch.Tensor:
        """The same vectors, leaving the cache as it was (for a one-off batch of thousands of sentences)."""
        return torch.stack([self._embed(t) for t in texts])


class HashedNgramEncoder(CachedEncoder):
    """Deterministic subword-hashing sentence encoder (no weights on disk)."""

    name = "hashed_ngram"

    def __init__(self, dim: int = 128, buckets: int = 8192, seed: int = 1234) -> None:
        super().__init__()
        self.dim, self.buckets, self.seed = dim, buckets, seed
        gen = torch.Generator().manual_seed(seed)
        self._table = torch.randn(buckets, dim, generator=gen) / dim ** 0.5

    def config(self) -> dict:
        return {"name": self.name, "dim": self.dim, "buckets": self.buckets, "seed": self.seed}

    def _word_vector(self, word: str) -> torch.Tensor:
        marked = f"<{word}>"
        grams = [marked] + [marked[i:i + n] for n in (3, 4, 5) for i in range(len(marked) - n + 1)]
        idx = torch.tensor([zlib.crc32(g.encode()) % self.buckets for g in grams])
        return self._table[idx].mean(0)

    def _embed(self, text: str) -> torch.Tensor:
        words = [w for w in _WORD.findall(text.lower()) if w not in _STOP]
        if not words:
            return torch.zeros(self.dim)
        return torch.nn.functional.normalize(torch.stack([self._word_vector(w) for w in words]).mean(0), dim=0)


@dataclass(frozen=True)
class StaticTable:
    """A static sub-word table: one float16 vector per vocabulary token."""
    vectors: torch.Tensor          # (V, dim) float16
    vocab: dict[str, int]          # token -> row
    id: str                        # content hash: a checkpoint names the table it was trained with
    meta: dict

    @property
    def dim(self) -> int:
        return int(self.vectors.shape[1])


def table_id(vectors: np.ndarray, vocab_bytes: bytes) -> str:
    """16 hex digits of the SHA-256 of the table's vectors and vocabulary."""
    return hashlib.sha256(np.ascontiguousarray(vectors).tobytes() + b"\0" + vocab_bytes).hexdigest()[:16]


def write_table(path: Path, vectors: np.ndarray, tokens: list[str], meta: dict) -> str:
    """Write a table file (float16 vectors, newline-joined vocabulary, JSON meta); returns its id."""
    vectors = np.asarray(vectors, np.float16)
    vocab_bytes = "\n".join(tokens).encode()
    meta = dict(meta, id=table_id(vectors, vocab_bytes))
    tmp = path.with_name(path.name + ".tmp.npz")
    np.savez_compressed(tmp, vectors=vectors, vocab=np.frombuffer(vocab_bytes, np.uint8),
                        meta=np.frombuffer(json.dumps(meta).encode(), np.uint8))
    tmp.replace(path)
    return meta["id"]


@lru_cache(maxsize=4)
def load_table(path: Path = STATIC_TABLE) -> StaticTable:
    """The table at `path`, read once per process (encoders share it)."""
    try:
        with np.load(path, allow_pickle=False) as z:
            vectors, vocab_bytes = z["vectors"], z["vocab"].tobytes()
            meta = json.loads(z["meta"].tobytes())
    except FileNotFoundError:
        raise ModelFileError(f"text table {path} not found; reinstall model_runtime (the table ships with it) "
                             "or rebuild it with python -m model_runtime.text_build") from None
    except (OSError, ValueError, KeyError) as exc:
        raise ModelFileError(f"text table {path} is damaged ({type(exc).__name__}); reinstall model_runtime or "
                             "rebuild it with python -m model_runtime.text_build") from None
    tokens = vocab_bytes.decode().split("\n")
    if vectors.ndim != 2 or vectors.dtype != np.float16 or len(tokens) != vectors.shape[0]:
        raise ModelFileError(f"text table {path} is damaged (vectors {vectors.shape} {vectors.dtype} for "
                             f"{len(tokens)} tokens); reinstall model_runtime")
    return StaticTable(torch.from_numpy(vectors), {t: i for i, t in enumerate(tokens)},
                       table_id(vectors, vocab_bytes), meta)


class StaticSubwordEncoder(CachedEncoder):
    """Sentence vectors from a static sub-word table: the normalised mean of the prompt's token vectors
    (words the vocabulary cannot piece together are left out; no known token gives the zero vector)."""

    name = "minilm_static"

    def __init__(self, table: StaticTable) -> None:
        super().__init__()
        self.table, self.dim = table, table.dim

    def config(self) -> dict:
        return {"name": self.name, "dim": self.dim, "table": self.table.id}

    def _embed(self, text: str) -> torch.Tensor:
        ids = token_ids(text, self.table.vocab)
        if not ids:
            return torch.zeros(self.dim)
        return torch.nn.functional.normalize(self.table.vectors[ids].float().mean(0), dim=0)


def build_text_encoder(cfg: dict) -> TextEncoder:
    """Rebuild the encoder a checkpoint was trained with from its stored config."""
    name = cfg.get("name")
    if name == HashedNgramEncoder.name:
        return HashedNgramEncoder(dim=int(cfg["dim"]), buckets=int(cfg["buckets"]), seed=int(cfg["seed"]))
    if name == StaticSubwordEncoder.name:
        table = load_table()
        if cfg.get("table") != table.id or int(cfg["dim"]) != table.dim:
            raise ModelFileError(f"the model was trained with text table {cfg.get('table')} ({cfg.get('dim')} dims) "
                                 f"but this runtime ships table {table.id} ({table.dim} dims); use a model trained "
                                 "with this version of model_runtime, or retrain it")
        return StaticSubwordEncoder(table)
    raise ModelFileError(f"unknown text encoder {name!r} in the model file; "
                         "use a model trained with this version of model_runtime")
