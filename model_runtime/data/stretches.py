"""Pieces of real clips that the interaction copies are built from: straight stretches of walks (re-timed to a
walking speed by resampling, moved rigidly) and calm standing clips, with their joints for clearance checks.

The joints of a re-timed stretch are interpolated between the source's FK frames (within ~1 cm of the FK of
the resampled pose at 10 fps); the pair builder checks clearance again on the FK of the finished clips.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..skeleton import JOINT_INDEX
from .detours import resample, straight_starts
from .geometry import normalized
from .library import ClipLibrary, is_derived
from .pairs import FPS, ClipCache
from .phrasings import STYLE_SYNONYMS
from .turns import pivot_turn

WALKER_SPEED = (0.8, 1.6)     # m/s: a walking partner is re-timed into this range
RETIME = (0.75, 1.34)         # a stretch is played at most this much slower / faster than captured
CALM_HEIGHT_RANGE = 0.15      # m: a calm standing clip's pelvis and ankles move less than this up and down
ANKLES = (JOINT_INDEX["left_ankle"], JOINT_INDEX["right_ankle"])


@dataclass
class Stretch:
    """Consecutive frames of a real clip, possibly re-timed and moved: pose and (interpolated) joints."""
    source: int                  # library index of the real clip
    rotations: np.ndarray        # (T, 22, 4) local quaternions w-first
    pelvis: np.ndarray           # (T, 3)
    joints: np.ndarray           # (T, 22, 3) world joints

    @property
    def heading(self) -> np.ndarray:
        """(2,) direction from the first to the last pelvis position."""
        return normalized(self.pelvis[-1, :2].astype(np.float64) - self.pelvis[0, :2])

    @property
    def speed(self) -> float:
        """m/s along the chord from the first to the last frame."""
        d = np.linalg.norm(self.pelvis[-1, :2].astype(np.float64) - self.pelvis[0, :2])
        return float(d * FPS / max(1, len(self.pelvis) - 1))


def yaw_of(v: np.ndarray) -> float:
    return float(np.arctan2(v[1], v[0]))


def rotate_xy(xy: np.ndarray, yaw: float) -> np.ndarray:
    """(..., 2) points turned by yaw about the origin."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.stack((c * xy[..., 0] - s * xy[..., 1], s * xy[..., 0] + c * xy[..., 1]), -1)


def split_style(caption: str) -> tuple[str, str]:
    """'a person walks forward, actively' -> ('a person walks forward', 'actively'); no style -> (caption, '')."""
    head, sep, tail = caption.rpartition(", ")
    return (head, tail) if sep and tail in STYLE_SYNONYMS else (caption, "")


def straight_caption(caption: str) -> str:
    """The caption of a straight stretch of a clip: a stretch of a walk-and-turn clip does not turn, it walks
    forward (in the clip's style)."""
    head, style = split_style(caption)
    if "turn" not in head:
        return caption
    return "a person walks forward" + (f", {style}" if style else "")


def clip_stretch(lib: ClipLibrary, clips: ClipCache, i: int, times: np.ndarray) -> Stretch:
    """Clip i at (fractional, increasing) frame times: poses slerped, joints interpolated."""
    a, b = int(lib.offsets[i]), int(lib.offsets[i + 1])
    if np.allclose(times, np.round(times)):
        idx = np.round(times).astype(np.int64)
        return Stretch(i, lib.rotations[a + idx].copy(), lib.pelvis[a + idx].copy(), clips.joints(i)[idx].copy())
    rot, pel = resample(lib.rotations[a:b], lib.pelvis[a:b], times)
    j = clips.joints(i)
    lo = np.clip(np.floor(times).astype(np.int64), 0, b - a - 1)
    hi = np.minimum(lo + 1, b - a - 1)
    w = (times - lo)[:, None, None]
    return Stretch(i, rot, pel, ((1 - w) * j[lo] + w * j[hi]).astype(np.float32))


def walk_stretch(lib: ClipLibrary, clips: ClipCache, i: int, frames: int, rng: np.random.Generator,
                 speed: float | None = None, speeds: tuple[float, float] = WALKER_SPEED) -> Stretch | None:
    """`frames` frames of a random straight stretch of walk i (detours.straight_starts), re-timed to walk at
    `speed` m/s (default: its own speed brought into `speeds`). None when the clip has no straight stretch
    long enough, or the speed needs a re-timing beyond RETIME."""
    xy = clips.path(i).xy
    starts = straight_starts(xy, frames)
    if not len(starts):
        return None
    start = int(starts[rng.integers(len(starts))])
    own = float(np.linalg.norm(xy[start + frames - 1] - xy[start]) * FPS / (frames - 1))
    target = float(np.clip(own, *speeds)) if speed is None else speed
    rate = target / own
    if not RETIME[0] <= rate <= RETIME[1]:
        return None
    if rate > 1.0:     # played faster: needs a longer straight stretch of the source
        need = int(np.ceil((frames - 1) * rate)) + 1
        starts = straight_starts(xy, need) if need <= len(xy) else np.zeros(0, np.int64)
        if not len(starts):
            return None
        start = int(starts[rng.integers(len(starts))])
        own = float(np.linalg.norm(xy[start + need - 1] - xy[start]) * FPS / (need - 1))
        rate = min(target / own, (need - 1) / (frames - 1))
    return clip_stretch(lib, clips, i, start + np.arange(frames) * rate)


def moved(s: Stretch, yaw: float, frame: int, to_xy: np.ndarray) -> Stretch:
    """The stretch turned by `yaw` about the vertical and shifted so that its pelvis at `frame` is at to_xy."""
    rot, pel = pivot_turn(s.rotations, s.pelvis, np.full(len(s.pelvis), yaw))
    pivot = s.pelvis[0, :2].astype(np.float64)
    j = s.joints.astype(np.float64)
    j[..., :2] = pivot + rotate_xy(j[..., :2] - pivot, yaw)
    shift = np.asarray(to_xy, np.float64) - pel[frame, :2]
    pel[:, :2] = (pel[:, :2] + shift).astype(pel.dtype)
    j[..., :2] += shift
    return replace(s, rotations=rot, pelvis=pel, joints=j.astype(np.float32))


def walks(lib: ClipLibrary, clips: ClipCache, ids: list[int]) -> list[int]:
    """The real forward walks among ids."""
    return [i for i in ids if not is_derived(lib.names[i]) and clips.path(i).moving
            and clips.path(i).forwardness >= 0.8]


def calm_standing(lib: ClipLibrary, clips: ClipCache, ids: list[int], min_frames: int) -> list[int]:
    """Real standing clips among ids with at least `min_frames` frames whose feet stay on the floor and whose
    pelvis does not bob (no jumps, kicks or crouches): gestures, bows and idle standing."""
    out = []
    for i in ids:
        if is_derived(lib.names[i]) or lib.frames(i) < min_frames or not clips.path(i).standing:
            continue
        j = clips.joints(i)
        if np.ptp(j[:, 0, 2]) < CALM_HEIGHT_RANGE and np.ptp(j[:, ANKLES, 2], axis=0).max() < CALM_HEIGHT_RANGE:
            out.append(i)
    return out


def longest_straight(xy: np.ndarray) -> int:
    """Frames of the longest straight stretch at a walking pace of a smoothed pelvis path (0: none); a binary
    search over lengths, taking a straight stretch to contain shorter ones."""
    lo, hi = 1, len(xy)
    while lo < hi:
        mid = (lo + hi + 1) // 2
        lo, hi = (mid, hi) if len(straight_starts(xy, mid)) else (lo, mid - 1)
    return lo if lo >= 2 else 0


@dataclass
class WalkPool:
    """Real walks to take partners (or egos) from, with the length of their longest straight stretch."""
    lib: ClipLibrary
    ids: np.ndarray              # (n,) clip indices
    longest: np.ndarray          # (n,) frames of each one's longest straight stretch

    @classmethod
    def of(cls, clips: ClipCache, ids: list[int]) -> "WalkPool":
        return cls(clips.lib, np.asarray(ids, np.int64),
                   np.asarray([longest_straight(clips.path(int(i)).xy) for i in ids], np.int64))

    def pick(self, rng: np.random.Generator, frames: int, not_source: int = -1) -> int | None:
        """A random walk with a straight stretch of at least `frames` frames, other than clip `not_source`."""
        ok = self.ids[(self.longest >= frames) & (self.ids != not_source)]
        return int(ok[rng.integers(len(ok))]) if len(ok) else None

    def split(self, held_out: bool) -> "WalkPool":
        """The walks of one side of the held-out split."""
        return self._keep([self.lib.is_held_out(int(i)) == held_out for i in self.ids])

    def subset(self, ids: set[int]) -> "WalkPool":
        """The walks among `ids`."""
        return self._keep([int(i) in ids for i in self.ids])

    def _keep(self, keep: list[bool]) -> "WalkPool":
        mask = np.asarray(keep, bool).reshape(-1)
        return WalkPool(self.lib, self.ids[mask], self.longest[mask])


def partner_walk(lib: ClipLibrary, clips: ClipCache, pool: WalkPool, frames: int, not_source: int,
                 rng: np.random.Generator) -> Stretch | None:
    """A straight stretch of a random walk of pool (not clip `not_source`), re-timed to a walking speed."""
    for _ in range(3):
        src = pool.pick(rng, frames, not_source)
        part = walk_stretch(lib, clips, src, frames, rng) if src is not None else None
        if part is not None:
            return part
    return None


def by_split(lib: ClipLibrary, ids: list[int]) -> dict[bool, list[int]]:
    """ids grouped by held-out (True) or training (False) side."""
    return {side: [i for i in ids if lib.is_held_out(i) == side] for side in (False, True)}


def min_distance_per_frame(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(T,) smallest distance between any joint of a and any joint of b at each frame: (T, J, 3) each."""
    diff = a[:, :, None, :] - b[:, None, :, :]
    return np.sqrt(np.einsum("tijk,tijk->tij", diff, diff).min(axis=(1, 2)))


def clearance(a: np.ndarray, b: np.ndarray) -> float:
    """Smallest joint-to-joint distance between a and b over all frames ((T, J, 3) each, joint 0 the pelvis),
    computed exactly only on the frames where the pelvis distance minus both bodies' reach could beat it."""
    pelvis = np.linalg.norm(a[:, 0] - b[:, 0], axis=-1)
    reach = float(np.linalg.norm(a - a[:, :1], axis=-1).max() + np.linalg.norm(b - b[:, :1], axis=-1).max())
    t = int(np.argmin(pelvis))
    best = float(min_distance_per_frame(a[t:t + 1], b[t:t + 1])[0])
    near = np.flatnonzero(pelvis - reach < best)
    return min(best, float(min_distance_per_frame(a[near], b[near]).min())) if len(near) else best
