"""Synthetic in-place turns: the one reaction the HHI stage needs that the open data does not hold.

Turning on the spot to face someone who walks up is what the partner scenario (evaluation) asks for, and no clip in
CMU or Bandai Namco shows it (their turns happen mid-walk). Measured without this: an ego standing side-on to
an approaching partner ended 102-103 deg off with or without the HHI module. So the HHI stage also trains on
turned copies of real standing clips: from a frame near the start, the whole body turns rigidly about the
vertical through the pelvis, by 45-180 degrees over about 0.1 s per 15 degrees (smoothstep), then keeps the
clip's own motion in the new direction. Everything but the root's yaw is the real clip; the cost is that the
feet pivot instead of stepping (the copies teach *that* and *where* to turn, not footwork), which rollouts show
as foot sliding during a turn. The copies only feed the interaction stages (`model_runtime.train`); the VAE and
the prior never see them.

Copies are named `<source name>#turn<k>` and keep the source's caption (prefixed with the turn), licence and
held-out split (`library.source_name`).
"""
from __future__ import annotations

import numpy as np
import torch

from ..quat import matrix_to_quat_np
from ..skeleton import quat_to_matrix, yaw_matrix
from .library import DERIVED, ClipLibrary, is_derived
from .pairs import FPS, STANDING_RANGE

TURN_SPEED = np.radians(150.0)         # rad/s: 90 degrees in 0.6 s, a brisk turn toward someone
TURN_RANGE = (np.radians(45.0), np.pi)  # |turn angle|
ONSET_FRAMES = (2, 4)                   # the turn starts this many frames into the copy (inclusive)
AFTER_FRAMES = 12                       # frames kept after the turn ends (the copy is cut there)
MIN_FRAMES = 20                         # shorter standing clips are not copied


def smoothstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def turn_duration(angle: float, fps: float = FPS) -> float:
    """Frames (fractional, at least 2) a turn by `angle` radians takes at TURN_SPEED."""
    return max(2.0, abs(angle) / TURN_SPEED * fps)


def turn_profile(frames: int, onset: int, angle: float, fps: float = FPS) -> np.ndarray:
    """(frames,) yaw added at each frame: 0 before onset, `angle` once the turn is over."""
    return angle * smoothstep((np.arange(frames) - onset) / turn_duration(angle, fps))


def turn_roots(rotations: np.ndarray, yaw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The clip's rotations with each frame's world orientation (joint 0) turned by yaw[t] about +Z; every
    other joint's local rotation is unchanged. Also returns the (T, 3, 3) yaw matrices.

    rotations (T, 22, 4) local quaternions w-first."""
    r = yaw_matrix(torch.as_tensor(yaw, dtype=torch.float64)).numpy()                     # (T, 3, 3)
    root = quat_to_matrix(torch.as_tensor(rotations[:, 0], dtype=torch.float64)).numpy()  # (T, 3, 3)
    rot = rotations.copy()
    rot[:, 0] = matrix_to_quat_np(r @ root).astype(rotations.dtype)
    return rot, r


def pivot_turn(rotations: np.ndarray, pelvis: np.ndarray, yaw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotate a clip's body by a per-frame yaw about the vertical through its pelvis at the first frame.

    rotations (T, 22, 4) local quaternions w-first (joint 0 is the world orientation), pelvis (T, 3)."""
    rot, r = turn_roots(rotations, yaw)
    pivot = pelvis[0].astype(np.float64)
    pel = pelvis.copy()
    pel[:, :2] = (pivot[:2] + np.einsum("tij,tj->ti", r[:, :2, :2], pelvis[:, :2] - pivot[:2])).astype(pel.dtype)
    return rot, pel


def _caption(caption: str, angle: float) -> str:
    side = "left" if angle > 0 else "right"   # positive yaw is counter-clockwise seen from above: to the left
    rest = caption[len("a person "):] if caption.startswith("a person ") else caption
    return f"a person turns {side} to face someone" + (f" and {rest}" if rest else "")


def add_pivot_turns(lib: ClipLibrary, clip_ids: list[int], seed: int = 0, per_clip: int = 1
                    ) -> tuple[ClipLibrary, list[int]]:
    """A new library: `lib` plus `per_clip` turned copies of every standing clip of `clip_ids`.

    Returns (library, indices of the copies). Deterministic for a seed; a clip's copies do not depend on the
    other clips. `lib`'s own clips keep their indices."""
    names, caps, srcs = list(lib.names), list(lib.captions), list(lib.sources)
    rots, pels, off = [lib.rotations], [lib.pelvis], list(lib.offsets)
    errors = list(lib.fit_error_mm) if lib.fit_error_mm else []
    new: list[int] = []
    for i in clip_ids:
        a, b = int(lib.offsets[i]), int(lib.offsets[i + 1])
        pel = lib.pelvis[a:b]
        if b - a < MIN_FRAMES or is_derived(lib.names[i]) or np.ptp(pel[:, :2], axis=0).max() > STANDING_RANGE:
            continue
        rng = np.random.default_rng([seed, int(i), 7])
        for k in range(per_clip):
            angle = float(rng.uniform(*TURN_RANGE)) * (1.0 if rng.random() < 0.5 else -1.0)
            onset = int(rng.integers(ONSET_FRAMES[0], ONSET_FRAMES[1] + 1))
            start = int(rng.integers(0, max(1, (b - a) - MIN_FRAMES)))   # a random stretch of the clip
            length = min(b - a - start, onset + int(np.ceil(abs(angle) / TURN_SPEED * FPS)) + AFTER_FRAMES)
            if length < MIN_FRAMES // 2:
                continue
            yaw = turn_profile(length, onset, angle)
            rot, p = pivot_turn(lib.rotations[a + start:a + start + length], lib.pelvis[a + start:a + start + length],
                                yaw)
            names.append(f"{lib.names[i]}{DERIVED}turn{k}")
            caps.append(_caption(lib.captions[i], angle))
            srcs.append(lib.sources[i])
            if errors:
                errors.append(lib.fit_error_mm[i])
            rots.append(rot)
            pels.append(p)
            off.append(off[-1] + length)
            new.append(len(names) - 1)
    out = ClipLibrary(names, caps, srcs, np.concatenate(rots), np.concatenate(pels), np.asarray(off, np.int64), errors)
    return out, new
