"""Prompts read partly by their nearest training phrasing.

A prompt in words no caption uses lands off every training phrasing on the sentence-vector sphere, where the
prior was never trained: "someone sprints across the room" lies at cosine 0.66 from "someone is running" and,
read as it is, jogs at 0.85 m/s. The runtime therefore reads a prompt as `keep` of its own vector and the rest
the vector of its nearest training phrasing (a softmax over the nearest BLEND_TOP, so sharp that it is all but the
nearest one alone). A prompt that is itself a training phrasing keeps its vector: its nearest phrasings are itself
and near-copies of it ("the person runs"). Training never blends: it encodes its captions as they are.

The phrasings are those of the captions the prior trained on (its library's train split), which the model file
keeps in meta["prompt_blend"]; a file without them reads prompts as they are. How `keep` was chosen, and what
the blend costs (a prompt whose nearest phrasing means something else moves toward that): docs/HISTORY.md,
"Reading a prompt by its nearest training phrasing".

    python -m model_runtime.text_blend --model IN.pt --library CLIPS.npz --out OUT.pt [--keep 0.8]
"""
from __future__ import annotations

import argparse
import gc
import sys

import torch

from .cli_help import HelpFormatter
from .errors import ModelFileError
from .text import CachedEncoder, TextEncoder

BLEND_TOP = 16            # phrasings the softmax weighs
BLEND_TEMPERATURE = 0.01  # of the softmax over their cosines
# The share of a prompt's own vector kept, chosen on the val split's text family (144 episodes): 0.8 met the same 6
# of 7 kinds and 14 of 21 prompts as 1 (no blend), with the run kind at 2.38 m/s against 2.12; 0.7 met 13 prompts
PROMPT_BLEND_KEEP = 0.8


class PhrasingBlend(CachedEncoder):
    """`base`'s vector of a prompt, `keep` of it and the rest the softmax-weighted mean of its nearest
    phrasings' vectors, normalised. A prompt the base encoder knows no word of stays zero (the unknown prompt).
    The phrasings are encoded by warm() (model.warm_text(), as the Blender extension calls at load) or else at the
    first prompt, before any frame of it plays."""

    def __init__(self, base: TextEncoder, phrasings: list[str], keep: float,
                 top: int = BLEND_TOP, temperature: float = BLEND_TEMPERATURE) -> None:
        super().__init__()
        if not 0.0 <= keep <= 1.0:
            raise ValueError(f"keep {keep} is outside 0-1; give the share of the prompt's own vector to keep")
        if not phrasings:
            raise ValueError("no phrasings to blend toward; give the captions the model was trained on")
        self.base, self.dim, self.keep, self.temperature = base, base.dim, keep, temperature
        self.phrasings = sorted(set(phrasings))
        self.top = min(top, len(self.phrasings))
        self._bank: torch.Tensor | None = None

    @property
    def bank(self) -> torch.Tensor:
        if self._bank is None:
            encode = getattr(self.base, "encode_uncached", self.base.encode)   # the prompts' cache stays the prompts'
            self._bank = torch.nn.functional.normalize(encode(self.phrasings).float(), dim=-1)
            # Tokenising thousands of sentences leaves Python's collector owing a full pass, which otherwise falls
            # on a played frame (measured: one 63 ms frame in 300): take it now, with the encoding
            gc.collect()
        return self._bank

    def warm(self) -> None:
        """Encode the phrasings now rather than at the first prompt."""
        _ = self.bank

    def nearest(self, text: str) -> tuple[str, float] | None:
        """The training phrasing nearest the prompt as written, and their cosine; None for the unknown prompt."""
        own = self.base.encode([text])[0].float()
        if float(own.norm()) == 0.0:
            return None
        cos = self.bank @ own
        i = int(cos.argmax())
        return self.phrasings[i], float(cos[i])

    def _embed(self, text: str) -> torch.Tensor:
        own = self.base.encode([text])[0]
        if self.keep >= 1.0 or float(own.norm()) == 0.0:
            return own
        near = (self.bank @ own.float()).topk(self.top)
        weights = torch.softmax(near.values / self.temperature, 0)
        pull = torch.nn.functional.normalize((weights[:, None] * self.bank[near.indices]).sum(0), dim=0)
        mixed = torch.nn.functional.normalize(self.keep * own.float() + (1.0 - self.keep) * pull, dim=0)
        return mixed.to(own.dtype)


def training_phrasings(captions: list[str]) -> list[str]:
    """Every phrasing the prior's training draws for these captions, with the captions its windows are given
    besides their clips' own (standing still, walking slowly, walking backwards)."""
    from .data.phrasings import caption_phrasings
    from .data.reversals import REVERSED_CAPTION
    from .training.recipe import SLOW_WALK_CAPTION, STILL_CAPTION
    heads = set(captions) | {STILL_CAPTION, SLOW_WALK_CAPTION, REVERSED_CAPTION}
    return sorted({p for c in heads for p in caption_phrasings(c)})


def blend_meta(train_captions: list[str], keep: float = PROMPT_BLEND_KEEP) -> dict:
    """What a model file keeps in meta["prompt_blend"]: the share kept and the prior's training captions."""
    return {"keep": float(keep), "captions": sorted(set(train_captions))}


def library_blend_meta(lib, keep: float = PROMPT_BLEND_KEEP) -> dict:
    """blend_meta of a clip library's train split: the captions a prior trained on it has seen."""
    return blend_meta([lib.captions[i] for i in lib.split("train")], keep)


def attach_prompt_blend(model, keep: float | None = None) -> None:
    """Set model.prompt_blend from its meta["prompt_blend"] (None without one); `keep` overrides the file's."""
    record = model.meta.get("prompt_blend") if isinstance(model.meta, dict) else None
    if record is None:
        model.prompt_blend = None
        return
    captions = record.get("captions") if isinstance(record, dict) else None
    share = record.get("keep", PROMPT_BLEND_KEEP) if keep is None and isinstance(record, dict) else keep
    if (not isinstance(captions, list) or not captions or not all(isinstance(c, str) for c in captions)
            or isinstance(share, bool) or not isinstance(share, (int, float)) or not 0.0 <= share <= 1.0):
        raise ModelFileError("the model file's meta['prompt_blend'] is damaged (it needs 'captions', a list of "
                             "strings, and 'keep', 0-1); write it again with python -m model_runtime.text_blend")
    model.prompt_blend = PhrasingBlend(model.text_encoder, training_phrasings(captions), float(share))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m model_runtime.text_blend", formatter_class=HelpFormatter,
                                 description="Write a model file that reads prompts partly by their nearest "
                                             "training phrasing (its weights unchanged).")
    ap.add_argument("--model", required=True, help="model file whose prior trained on --library")
    ap.add_argument("--library", required=True, help="the clip library the prior trained on (its train split)")
    ap.add_argument("--out", required=True, help="model file to write")
    ap.add_argument("--keep", type=float, default=PROMPT_BLEND_KEEP, help="share of a prompt's own vector kept")
    args = ap.parse_args(argv)
    if not 0.0 <= args.keep <= 1.0:
        ap.error(f"--keep {args.keep} is outside 0-1")
    from .checkpoint import load_model, save_model
    from .data.library import ClipLibrary
    from .errors import RemogenError
    try:
        model = load_model(args.model)
        lib = ClipLibrary.load(args.library)
    except RemogenError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    record = library_blend_meta(lib, args.keep)
    save_model(model, args.out, meta={"prompt_blend": record})
    print(f"wrote {args.out}: prompts keep {args.keep:g} of their own vector, blended toward the phrasings of "
          f"{len(record['captions'])} training captions")
    return 0


if __name__ == "__main__":
    sys.exit(main())
