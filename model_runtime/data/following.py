"""Follow copies for the HHI stage (`<source>#follow<k>`): walking behind someone who keeps walking.

The partner is a straight stretch of another real walk (re-timed to 0.8-1.6 m/s, moved rigidly) on the ego's
own line, 1.2-2.0 m ahead; the ego is a straight stretch of its real walk re-timed (by resampling, at most
RETIME) to within +-8 % of the partner's speed, so that the gap drifts but stays within FOLLOW_GAP (never
under pairs.hhi.FOLLOW_MIN_GAP, checked on the pelvises). The partner walks for the whole copy.

Why a small share (FOLLOW_SHARE of the straight walks): an earlier follow rule put a walking leader ahead on
real walks and taught the module to walk on toward a person ahead, into a partner standing 3 m away. Here the
partner always walks at the ego's own pace, and other kinds (arrive_face, step_aside, avoid_walker) show what
to do about a standing or oncoming person, which outnumber these copies.

Copies keep the source's licence and held-out split; the caption becomes "a person follows someone" (with the
source's style). The partner is stored as a clip (new_clips.partner_clip_name).
"""
from __future__ import annotations

import numpy as np

from .library import ClipLibrary
from .new_clips import NewClip, copy_name, new_clip, partner_clip_name
from .pairs import FPS, ClipCache
from .pairs.hhi import FOLLOW_MIN_GAP
from .stretches import Stretch, WalkPool, moved, partner_walk, rotate_xy, split_style, walk_stretch, yaw_of

FOLLOW_SHARE = 0.25          # share of straight walks that get a follow copy
FOLLOW_FRAMES = (30, 50)     # frames of a copy (inclusive)
FOLLOW_GAP = (1.2, 2.0)      # m pelvis to pelvis, at the start and at the end of the copy
SPEED_SPREAD = 0.08          # the ego walks at the partner's speed times 1 +- this
LATERAL = 0.15               # m: the partner walks at most this far beside the ego's line
ATTEMPTS = 6


def follow_caption(caption: str) -> str:
    style = split_style(caption)[1]
    return "a person follows someone" + (f", {style}" if style else "")


def _follow_one(lib: ClipLibrary, clips: ClipCache, i: int, longest: int, pool: WalkPool, rng: np.random.Generator
                ) -> tuple[Stretch, Stretch] | None:
    """(re-timed ego stretch, placed partner) for walk i, or None."""
    frames = min(longest, int(rng.integers(FOLLOW_FRAMES[0], FOLLOW_FRAMES[1] + 1)))
    part = partner_walk(lib, clips, pool, frames, i, rng)
    if part is None:
        return None
    pace = part.speed * float(1 + rng.uniform(-SPEED_SPREAD, SPEED_SPREAD))
    ego = walk_stretch(lib, clips, i, frames, rng, speed=pace)
    if ego is None:
        return None
    drift = (part.speed - ego.speed) * (frames - 1) / FPS
    lo, hi = max(FOLLOW_GAP[0], FOLLOW_GAP[0] - drift), min(FOLLOW_GAP[1], FOLLOW_GAP[1] - drift)
    if lo > hi:
        return None
    h = ego.heading
    at = ego.pelvis[0, :2] + float(rng.uniform(lo, hi)) * h + float(rng.uniform(-LATERAL, LATERAL)) * rotate_xy(
        h, np.pi / 2)
    partner = moved(part, yaw_of(h) - yaw_of(part.heading), 0, at)
    gap = np.linalg.norm(partner.pelvis[:, :2] - ego.pelvis[:, :2], axis=1)
    if gap.min() < FOLLOW_MIN_GAP or gap.max() > FOLLOW_GAP[1] + 0.3:
        return None
    return ego, partner


def follow_copies(lib: ClipLibrary, clips: ClipCache, egos: WalkPool, partners: dict[bool, WalkPool], seed: int
                  ) -> list[NewClip]:
    """A follow copy (and its partner clip) for FOLLOW_SHARE of the walks of `egos` with a straight stretch of
    FOLLOW_FRAMES[0] frames, drawn per walk; partners are walks of `partners` on the walk's side of the split."""
    out: list[NewClip] = []
    for i, longest in zip(egos.ids.tolist(), egos.longest.tolist()):
        rng = np.random.default_rng([seed, i, 23])
        if longest < FOLLOW_FRAMES[0] or rng.random() >= FOLLOW_SHARE:
            continue
        pool = partners[lib.is_held_out(i)]
        for _ in range(ATTEMPTS):
            got = _follow_one(lib, clips, i, longest, pool, rng)
            if got is not None:
                ego, partner = got
                name = copy_name(lib, i, "follow", 0)
                out += [new_clip(lib, i, name, follow_caption(lib.captions[i]), ego.rotations, ego.pelvis),
                        new_clip(lib, partner.source, partner_clip_name(name), lib.captions[partner.source],
                                 partner.rotations, partner.pelvis, ego=False)]
                break
    return out
