"""Arrive-at-a-partner copies for the HHI stage (`<source>#arriveface<k>`): walking up to someone and stopping
in front of them.

The real walks all end mid-stride, so the approach_face pairs on them never show the stop. Each copy is a
straight stretch of a real walk (1.5-4.5 s) slowed to rest and cross-faded into the start of a calm real
standing clip of the same split (`detours.arrive`), preferably one of the walk's own style; the pair builder
(pairs.hhi, kind arrive_face) puts a standing partner about 1 m ahead of where the copy stops, facing it.
Bandai's standing clips are gestures that begin with the arms down, so most copies walk up, stop and then
raise a hand, wave or bow: the caption says so ("a person walks up to someone and waves the right hand");
a copy that ends in a gesture-free clip is captioned "a person walks up to someone and stops". Copies keep
the walk's licence and held-out split.
"""
from __future__ import annotations

import numpy as np

from .detours import BLEND_FRAMES, WALK_FRAMES, arrive, stop_frame, straight_starts
from .library import ClipLibrary
from .new_clips import NewClip, copy_name, new_clip
from .pairs import ClipCache, is_gesture
from .stretches import WalkPool, split_style

STAND_FRAMES = (20, 40)     # frames of the standing clip kept after the stop (from its start), inclusive
MIN_STAND = BLEND_FRAMES + 10
ARRIVE_COPIES = 1           # per straight walk


def arrive_caption(walk_caption: str, stand_caption: str) -> str:
    if is_gesture(stand_caption):
        rest = stand_caption[len("a person "):] if stand_caption.startswith("a person ") else stand_caption
        return f"a person walks up to someone and {rest}"
    style = split_style(walk_caption)[1]
    return "a person walks up to someone and stops" + (f", {style}" if style else "")


def _stand_for(lib: ClipLibrary, i: int, pool: list[int], rng: np.random.Generator) -> int:
    """A standing clip of pool, of walk i's style when the pool has one."""
    style = split_style(lib.captions[i])[1]
    same = [s for s in pool if split_style(lib.captions[s])[1] == style]
    pick = same or pool
    return int(pick[rng.integers(len(pick))])


def arrive_face_copies(lib: ClipLibrary, clips: ClipCache, egos: WalkPool, stands: dict[bool, list[int]], seed: int
                       ) -> list[NewClip]:
    """ARRIVE_COPIES stop copies of each walk of `egos` with a straight stretch of more than WALK_FRAMES[0]
    frames, each ending in a standing clip of `stands` on the walk's side of the split."""
    out: list[NewClip] = []
    for i, longest in zip(egos.ids.tolist(), egos.longest.tolist()):
        pool = stands[lib.is_held_out(i)]
        if not pool or longest <= WALK_FRAMES[0] + 1:
            continue
        rng = np.random.default_rng([seed, i, 24])
        a = int(lib.offsets[i])
        for k in range(ARRIVE_COPIES):
            walk = min(longest - 2, int(rng.integers(WALK_FRAMES[0], WALK_FRAMES[1] + 1)))
            starts = straight_starts(clips.path(i).xy[:-1], walk + 1)   # the stop may fall up to one frame late
            if not len(starts):
                continue
            start = int(starts[rng.integers(len(starts))])
            stop = stop_frame(clips.joints(i), start + walk - 6, start + walk + 1) + 1   # exclusive end
            s = _stand_for(lib, i, pool, rng)
            sa = int(lib.offsets[s])
            sn = min(lib.frames(s), int(rng.integers(STAND_FRAMES[0], STAND_FRAMES[1] + 1)))
            rot, pel = arrive(lib.rotations[a + start:a + stop], lib.pelvis[a + start:a + stop],
                              lib.rotations[sa:sa + sn], lib.pelvis[sa:sa + sn], clips.joints(s)[0])
            out.append(new_clip(lib, i, copy_name(lib, i, "arriveface", k),
                                arrive_caption(lib.captions[i], lib.captions[s]), rot, pel))
    return out
