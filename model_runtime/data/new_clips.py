"""Derived clips collected by the copy builders and appended to a library in one step, and the naming of a
copy's partner clip.

A copy is named `<source>#<kind><k>` (library.DERIVED). A copy that comes with its own moving partner (a real
walk moved and re-timed for it) stores that partner as one more clip named `<source>#<kind>partner<k>`: it falls
on the copy's side of the held-out split (its motion is taken from a clip of that side too), keeps its own
dataset tag (licence), and is never an ego (only the pair builder reads it, `partner_clip_name`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .library import DERIVED, ClipLibrary

PARTNER = "partner"


@dataclass(eq=False)
class NewClip:
    """A derived clip waiting to be appended: pose, caption, dataset tag and the fit error it inherits."""
    name: str
    caption: str
    source: str                  # dataset tag of the motion ("cmu", "bandai", ...): its licence
    rotations: np.ndarray        # (T, 22, 4) local quaternions w-first
    pelvis: np.ndarray           # (T, 3)
    fit_error_mm: float = 0.0
    ego: bool = True             # False for a partner clip


def copy_name(lib: ClipLibrary, i: int, kind: str, k: int) -> str:
    """`<source>#<kind><k>` for a copy of clip i."""
    return f"{lib.names[i]}{DERIVED}{kind}{k}"


def partner_clip_name(copy: str) -> str:
    """The name of a copy's partner clip: `<source>#<kind><k>` -> `<source>#<kind>partner<k>`."""
    stem = copy.rstrip("0123456789")
    return f"{stem}{PARTNER}{copy[len(stem):]}"


def new_clip(lib: ClipLibrary, i: int, name: str, caption: str, rotations: np.ndarray, pelvis: np.ndarray,
             ego: bool = True) -> NewClip:
    """A NewClip whose motion comes from library clip i (its dataset tag and fit error)."""
    err = lib.fit_error_mm[i] if lib.fit_error_mm else 0.0
    return NewClip(name, caption, lib.sources[i], rotations.astype(np.float32), pelvis.astype(np.float32), err, ego)


def extend_library(lib: ClipLibrary, clips: list[NewClip]) -> tuple[ClipLibrary, list[int]]:
    """A new library: `lib` plus `clips` in order. Returns (library, indices of the ego clips among them);
    `lib`'s own clips keep their indices."""
    if not clips:
        return lib, []
    off = np.cumsum([int(lib.offsets[-1])] + [len(c.pelvis) for c in clips])
    errors = list(lib.fit_error_mm) + [c.fit_error_mm for c in clips] if lib.fit_error_mm else []
    out = ClipLibrary(list(lib.names) + [c.name for c in clips], list(lib.captions) + [c.caption for c in clips],
                      list(lib.sources) + [c.source for c in clips],
                      np.concatenate([lib.rotations] + [c.rotations for c in clips]),
                      np.concatenate([lib.pelvis] + [c.pelvis for c in clips]),
                      np.concatenate((lib.offsets, off[1:])).astype(np.int64), errors)
    return out, [len(lib) + n for n, c in enumerate(clips) if c.ego]
