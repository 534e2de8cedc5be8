"""Slowed copies of forward walks: a real walk played at 0.6-0.75 of its pace is a person walking slowly.

Why: captions name a walk's pace in 4 clips of the 4 h library ("walks slowly", and those go 1.0 m/s, faster than
the 0.4-0.9 m/s a slow walk is judged by). Told "a person walks slowly", the shipped prior walks at 1.0-1.1 m/s
(val split).

Played slower, a walk keeps its contacts (a planted foot stays planted for longer), its pose sequence and its
balance; the cadence drops with the speed, where a real slow walk also shortens its steps. SLOW_RATES keeps the
slow-down mild so that no copy looks like slow motion: a walk of about 110 steps a minute played at 0.6 takes about
66.

Copies are named `<source>#slowed0` (`#slowed1` from the mirrored copy, data/mirror.py), keep the source's
licence and held-out split (`library.source_name`), and are captioned "a person walks slowly" with the source's
style ("a person walks forward, tired" -> "a person walks slowly, tired").
"""
from __future__ import annotations

import numpy as np

from .detours import resample
from .library import DERIVED, ClipLibrary, source_name
from .new_clips import NewClip, extend_library, new_clip
from .reversals import forward_walk_recaptioned, forward_walk_sources, mean_speed

SLOWED_CAPTION = "a person walks slowly"
SLOW_RATES = (0.6, 0.75)         # the copy plays at this share of the source's pace (drawn per clip)
SLOWED_SPEED = (0.45, 0.85)      # m/s a copy's pelvis must travel (else no copy): a slow walk, not a shuffle


def slowed_caption(caption: str) -> str | None:
    """SLOWED_CAPTION with the caption's style, or None when the caption is not a plain forward walk."""
    return forward_walk_recaptioned(caption, SLOWED_CAPTION)


def slow_down(rotations: np.ndarray, pelvis: np.ndarray, rate: float) -> tuple[np.ndarray, np.ndarray]:
    """The clip played at `rate` of its pace (frame times 0, rate, 2 rate, ... up to its last frame)."""
    times = np.arange(0.0, len(pelvis) - 1 + 1e-9, rate)
    return resample(rotations, pelvis, times)


def add_slowed_walks(lib: ClipLibrary, clip_ids: list[int], seed: int = 0) -> tuple[ClipLibrary, list[int]]:
    """A new library: `lib` plus a slowed copy of every plain forward walk among `clip_ids` (real or mirrored)
    that lands at SLOWED_SPEED m/s when played at a rate drawn in SLOW_RATES. Returns (library, indices of the
    copies); `lib`'s own clips keep their indices. Deterministic for a seed."""
    copies: list[NewClip] = []
    for i, number, caption, a, b in forward_walk_sources(lib, clip_ids, SLOWED_CAPTION):
        rate = float(np.random.default_rng([seed, int(i), 31]).uniform(*SLOW_RATES))
        if not SLOWED_SPEED[0] <= mean_speed(lib.pelvis[a:b]) * rate <= SLOWED_SPEED[1]:
            continue
        rot, pel = slow_down(lib.rotations[a:b], lib.pelvis[a:b], rate)
        copies.append(new_clip(lib, i, f"{source_name(lib.names[i])}{DERIVED}slowed{number}", caption, rot, pel))
    return extend_library(lib, copies)
