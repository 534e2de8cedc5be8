"""Real-clip references for the text family: what real motion of each kind gives, from a clip library.

A kind's reference is its statistic (text_targets.KINDS) on the real clips whose caption matches the kind:
the library's held-out clips when at least MIN_HELD_OUT_CLIPS match, else every matching clip. Each clip is
cut to the text episodes' length (from its start, as a rollout starts), and stands on its own floor
(metrics.rolling_floor): some captures' floors slope, which would read as feet leaving the ground.
"""
from __future__ import annotations

import numpy as np

from ..data.library import ClipLibrary
from ..data.pairs import clip_joints
from . import metrics as M
from .scenarios import TEXT_EPISODE_FRAMES
from .text_targets import KINDS

MIN_HELD_OUT_CLIPS = 3


def clip_takes(lib: ClipLibrary, ids: list[int], frames: int = TEXT_EPISODE_FRAMES) -> list[np.ndarray]:
    """(T <= frames, 22, 3) world joints of each clip, from its first frame."""
    return [clip_joints(lib, i)[:frames].astype(np.float64) for i in ids]


def kind_clips(lib: ClipLibrary, kind: str) -> tuple[list[int], str]:
    """(clip indices, "val" or "all"): the clips whose caption matches the kind, held-out ones preferred."""
    ids = [i for i, c in enumerate(lib.captions) if KINDS[kind].matches(c)]
    val = [i for i in ids if lib.is_held_out(i)]
    return (val, "val") if len(val) >= MIN_HELD_OUT_CLIPS else (ids, "all")


def text_reference(lib: ClipLibrary, frames: int = TEXT_EPISODE_FRAMES) -> dict:
    """{kind: {"statistic", "clips", "split", "mean"}}: the kind's statistic averaged over its real clips
    ("clips": 0 and "mean": None when no caption matches)."""
    out = {}
    for kind, target in KINDS.items():
        ids, split = kind_clips(lib, kind)
        values = [M.text_measures(j, M.rolling_floor(j))[target.statistic] for j in clip_takes(lib, ids, frames)]
        out[kind] = {"statistic": target.statistic, "clips": len(ids), "split": split if ids else None,
                     "mean": float(np.mean(values)) if values else None}
    return out
