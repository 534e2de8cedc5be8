"""Takes that differ: how far apart different seeds' takes of one prompt are, against real takes of it.

Each prompt in DIVERSITY_PROMPTS is a caption of the data, rolled out from the same start with several
seeds. The distance between two takes is metrics.pose_distance_m: joints relative to the pelvis, the first
frame's heading turned to yaw 0, compared frame by frame and averaged over joints and frames (m). The real
reference is the same distance between pairs of real clips with exactly that caption (each pair over the
shorter clip's length, at most the rollout length). The target: between-seed distance at least
DIVERSITY_TARGET times the real between-take distance.
"""
from __future__ import annotations

from typing import Callable

import numpy as np

from ..errors import DEFAULT_GUIDANCE
from ..data.library import ClipLibrary
from . import metrics as M
from .real_clips import clip_takes
from .scenarios import SPLIT_SEEDS, TEXT_EPISODE_FRAMES, Episode

DIVERSITY_PROMPTS = ("a person walks forward", "a person runs forward", "a person waves the right hand",
                     "a person jumps", "a person dances")
DIVERSITY_SEEDS = 6
DIVERSITY_TARGET = 0.5
MIN_REAL_DISTANCE = 1e-3     # m: real takes closer than this are copies, no scale to compare with
MAX_REAL_TAKES = 12          # clips per caption (66 pairs): enough for a mean, cheap to compare
_SEED_STREAM = 7919          # the diversity seeds' generator stream, apart from every family's


def diversity_seeds(split: str, n: int) -> list[int]:
    """The split's n session seeds (val and test draw different ones)."""
    rng = np.random.default_rng([SPLIT_SEEDS[split], _SEED_STREAM])
    return [int(s) for s in rng.integers(2 ** 31, size=n)]


def real_takes(lib: ClipLibrary, caption: str, frames: int = TEXT_EPISODE_FRAMES,
               limit: int = MAX_REAL_TAKES) -> tuple[list[np.ndarray], str]:
    """(up to `limit` real clips of the caption cut to `frames`, how they match): clips whose caption is
    exactly `caption` ("caption"); when fewer than two are, clips whose caption is `caption` followed by
    its details or style, as in "a person dances: small jetes and pirouette" ("caption head"). Evenly
    spread over the library's order, which lists one performer's takes together."""
    ids, match = [i for i, c in enumerate(lib.captions) if c == caption], "caption"
    if len(ids) < 2:
        heads = (caption + ":", caption + ",")
        ids, match = [i for i, c in enumerate(lib.captions) if c == caption or c.startswith(heads)], "caption head"
    if len(ids) > limit:
        ids = [ids[k] for k in np.linspace(0, len(ids) - 1, limit).round().astype(int)]
    return clip_takes(lib, ids, frames), match


def diversity_report(model, split: str, *, seeds: int = DIVERSITY_SEEDS, frames: int = TEXT_EPISODE_FRAMES,
                     prompts: tuple[str, ...] = DIVERSITY_PROMPTS, library: ClipLibrary | None = None,
                     guidance: float = DEFAULT_GUIDANCE,
                     progress: Callable[[str], None] | None = None, **session_options) -> dict:
    """{"prompts": {prompt: row}, "ratio_mean", "pass", ...}. A row: between_seeds_m (mean over seed pairs),
    real_between_takes_m, real_pairs and real_match (None, 0, None without a library or with fewer than two
    clips of the caption), ratio (seeds over real; None without a reference or when the real takes are copies)
    and pass (ratio >= DIVERSITY_TARGET; None without a ratio)."""
    from .suite import roll_out
    if seeds < 2:
        raise ValueError(f"diversity needs at least 2 seeds, got {seeds}")
    rows = {}
    for prompt in prompts:
        takes = [roll_out(model, Episode("diversity", k, s, prompt, frames), 1.0, guidance=guidance,
                          **session_options) for k, s in enumerate(diversity_seeds(split, seeds))]
        between, _ = M.mean_pairwise_distance(takes)
        real, pairs, match = float("nan"), 0, None
        if library is not None:
            takes_real, match = real_takes(library, prompt, frames)
            real, pairs = M.mean_pairwise_distance(takes_real)
        ratio = between / real if pairs and real >= MIN_REAL_DISTANCE else None
        rows[prompt] = {"between_seeds_m": between, "real_between_takes_m": real if pairs else None,
                        "real_pairs": pairs, "real_match": match if pairs else None, "ratio": ratio,
                        "pass": None if ratio is None else bool(ratio >= DIVERSITY_TARGET)}
        if progress is not None:
            progress(f"diversity {prompt!r}: {seeds} seeds, {between:.3f} m apart")
    ratios = [r["ratio"] for r in rows.values() if r["ratio"] is not None]
    out = {"seeds": seeds, "frames": frames, "target_ratio": DIVERSITY_TARGET, "prompts": rows,
           "ratio_mean": float(np.mean(ratios)) if ratios else None,
           "pass": bool(np.mean(ratios) >= DIVERSITY_TARGET) if ratios else None}
    if library is None:
        out["reference"] = "absent: no clip library given (--library PATH)"
    return out
