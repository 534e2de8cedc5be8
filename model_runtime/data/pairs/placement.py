"""Placing partner bodies taken from other real clips: moved rigidly to stand at a point facing a direction,
scaled, time-shifted, and checked for clearance from the ego."""
from __future__ import annotations

import numpy as np

from ..library import ClipLibrary, is_derived
from .clips import STANDING_RANGE, ClipCache, facing_xy


def _rot2(c: float, s: float) -> np.ndarray:
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _yaw_between(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """3x3 rotation about +Z taking 2-D direction src to dst."""
    a = np.arctan2(dst[1], dst[0]) - np.arctan2(src[1], src[0])
    return _rot2(np.cos(a), np.sin(a))


def _scale_body(j: np.ndarray, scale: float) -> np.ndarray:
    """Scale each frame's body about the floor point under its pelvis (shape changes, path does not)."""
    anchor = j[:, :1, :].copy()
    anchor[..., 2] = 0.0
    return anchor + scale * (j - anchor)


def place_standing(src: np.ndarray, frames: np.ndarray, ref: int, target_xy: np.ndarray,
                   target_facing: np.ndarray, scale: float) -> np.ndarray:
    """Move a source clip rigidly so that at its frame `ref` the pelvis is at target_xy facing target_facing.

    src (Ts, 22, 3) world joints; frames (T,) source frame per ego frame. Returns (T, 22, 3).
    """
    r = _yaw_between(facing_xy(src[ref]), target_facing)
    pel = np.array([src[ref, 0, 0], src[ref, 0, 1], 0.0])
    t = np.array([target_xy[0], target_xy[1], 0.0]) - r @ pel
    out = src[frames].astype(np.float64) @ r.T + t
    return _scale_body(out, scale)


def min_clearance(a: np.ndarray, b: np.ndarray) -> float:
    """Smallest distance between any joint of a and any joint of b over all frames: (T, J, 3) each."""
    d = np.linalg.norm(a[:, :, None, :] - b[:, None, :, :], axis=-1)
    return float(d.min())


def standing_partners(lib: ClipLibrary) -> list[int]:
    """The library's standing clips (PathInfo.standing, read off the pelvis without FK): the sources of waiting
    partners."""
    return [i for i in range(len(lib)) if not is_derived(lib.names[i])     # turned copies are no source
            and np.ptp(lib.pelvis[lib.offsets[i]:lib.offsets[i + 1], :2].astype(np.float64), axis=0).max()
            <= STANDING_RANGE]


def _pick(rng: np.random.Generator, pool: list[int], ego: int) -> int | None:
    others = [i for i in pool if i != ego]
    if not others:
        return None
    return int(others[rng.integers(len(others))])


def standing_source(clips: ClipCache, rng: np.random.Generator, pool: list[int], ego: int
                    ) -> tuple[np.ndarray, np.ndarray]:
    """(joints (Ts,22,3), frame indices to use) of a standing partner. Without a standing clip in the
    library, the quietest frame of another clip is held still (a body from a real clip, not moving)."""
    k = _pick(rng, pool, ego)
    if k is not None:
        return clips.joints(k), np.arange(clips.lib.frames(k))
    k = _pick(rng, list(range(len(clips.lib))), ego)
    k = ego if k is None else k
    j = clips.joints(k)
    speed = np.r_[0.0, np.linalg.norm(np.diff(j[:, 0, :2], axis=0), axis=1)]
    feet = np.abs(j[:, 10, 2] - j[:, 11, 2])
    f = int(np.argmin(speed + feet))
    return j[f:f + 1], np.zeros(1, np.int64)


def standing_frames(src_frames: np.ndarray, t: int, shift: int) -> np.ndarray:
    """Source frames shown at ego frames 0..t-1 with a timing offset; short sources hold their ends."""
    return src_frames[np.clip(np.arange(t) + shift, 0, len(src_frames) - 1)]
