"""Reversed copies of forward walks: a real walk played backwards in time is a person walking backwards.

Why: the 4 h library holds 45,000 frames of plain forward walks and 1,300 of walking backwards (15 Bandai takes), and
"a person walks backwards" embeds close to "a person walks forward" (cosine 0.90 with the shipped text encoder).
With so few windows of its own the prior walked forwards when told to walk backwards (val split: 72-79 deg between
the pelvis's travel and the first facing, against 175 in the real backward walks).

Played backwards, a walk keeps what makes it real: the feet stay planted where they were planted (contacts do not
change under time reversal), the pelvis bobs as it did, the body faces where it faced, and it travels the other way.
What differs from a captured backward walk is the order of heel and toe (a reversed step lands toe first and rolls
back onto the heel, as real backward steps do) and the arm swing's phase, which reverses with the legs. The 15 real
backward takes stay in the library beside these copies, under the same caption head.

Copies are named `<source>#reversed0` (`#reversed1` from the mirrored copy, data/mirror.py), keep the source's
licence and held-out split (`library.source_name`), and are captioned "a person walks backwards" with the source's
style ("a person walks forward, tired" -> "a person walks backwards, tired").
"""
from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from .library import DERIVED, ClipLibrary, derived_kind, source_name
from .new_clips import NewClip, extend_library, new_clip
from .pairs import FPS
from .stretches import split_style

REVERSED_CAPTION = "a person walks backwards"
# Caption heads of plain forward walks (no turn, no direction other than forward: a reversed "walks to the left"
# is a walk to the right, not a backward one).
FORWARD_WALK_HEADS = ("a person walks", "a person walks forward")
MIN_SPEED = 0.5            # m/s of mean pelvis travel: the clip walks (a standing take labelled "walk" is not reversed)
MAX_SPEED = 2.0            # m/s: faster is a run or a dash captioned as a walk by mistake; a reversed run is no walk
SOURCE_KINDS = ("", "mirror")   # real clips and their mirrored copies


def forward_walk_recaptioned(caption: str, new_head: str) -> str | None:
    """`new_head` with the caption's style ("a person walks forward, tired" -> "<new_head>, tired"), or None when
    the caption is not a plain forward walk (FORWARD_WALK_HEADS)."""
    head, style = split_style(caption)
    if head not in FORWARD_WALK_HEADS:
        return None
    return new_head + (f", {style}" if style else "")


def reversed_caption(caption: str) -> str | None:
    """REVERSED_CAPTION with the caption's style, or None when the caption is not a plain forward walk."""
    return forward_walk_recaptioned(caption, REVERSED_CAPTION)


def mean_speed(pelvis: np.ndarray, fps: float = FPS) -> float:
    """m/s of the pelvis along its floor path (sum of frame steps over the clip's duration)."""
    if len(pelvis) < 2:
        return 0.0
    steps = np.linalg.norm(np.diff(pelvis[:, :2].astype(np.float64), axis=0), axis=-1)
    return float(steps.sum() * fps / (len(pelvis) - 1))


def forward_walk_sources(lib: ClipLibrary, clip_ids: list[int],
                         new_head: str) -> Iterator[tuple[int, int, str, int, int]]:
    """The plain forward walks among `clip_ids` that copies are made from (real or mirrored, SOURCE_KINDS):
    yields (clip index, copy number: 0 from a real clip, 1 from a mirrored one, the copy's caption with `new_head`,
    first frame, end frame)."""
    for i in clip_ids:
        kind = derived_kind(lib.names[i])
        if kind not in SOURCE_KINDS:
            continue
        caption = forward_walk_recaptioned(lib.captions[i], new_head)
        if caption is not None:
            yield i, int(kind == "mirror"), caption, int(lib.offsets[i]), int(lib.offsets[i + 1])


def add_reversals(lib: ClipLibrary, clip_ids: list[int], seed: int = 0) -> tuple[ClipLibrary, list[int]]:
    """A new library: `lib` plus a time-reversed copy of every plain forward walk among `clip_ids` (real or
    mirrored) whose pelvis goes MIN_SPEED-MAX_SPEED m/s. Returns (library, indices of the copies); `lib`'s own
    clips keep their indices. `seed` is unused (the reversal is exact) and kept so that every derivation has the
    same signature."""
    del seed
    copies: list[NewClip] = []
    for i, number, caption, a, b in forward_walk_sources(lib, clip_ids, REVERSED_CAPTION):
        if not MIN_SPEED <= mean_speed(lib.pelvis[a:b]) <= MAX_SPEED:
            continue
        name = f"{source_name(lib.names[i])}{DERIVED}reversed{number}"
        copies.append(new_clip(lib, i, name, caption, lib.rotations[a:b][::-1].copy(), lib.pelvis[a:b][::-1].copy()))
    return extend_library(lib, copies)
