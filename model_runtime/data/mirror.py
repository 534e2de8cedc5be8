"""Mirrored copies of clips: the same motion reflected left-right, so the denoising stages see every turn both ways.

Why: the prior trained without them turned clockwise in every measured "walks forward" rollout (about 58 deg per
20 s, test split) although the clips themselves are balanced (140 walking clips: +0.2 deg/s mean, 46 % turning
clockwise). A reflection cannot carry a preference for either way, so training on clip + mirror leaves no
direction to learn.

The reflection is x -> -x in the world (any vertical plane works: the features are canonicalised by yaw). SMPL-X
local rotations are expressed in world-aligned rest frames, so reflecting a rotation R is S R S with
S = diag(-1, 1, 1) (the quaternion (w, x, y, z) becomes (w, x, -y, -z)), and every left joint takes its right
twin's rotation and back. Captions swap "left" and "right" ("turns left" becomes "turns right").

Known limit, measured: the SMPL-X rest skeleton is not quite left-right symmetric (its left hip sits 1.1 cm
higher than its right, its ankle offsets differ by up to 3 cm), so reflected rotations on it tilt the pelvis
(hips 2.3 cm apart in height) and put joints up to 5 cm from the exact reflection. And the VAE, trained on real
clips only, reconstructs mirrored segments poorly (158 mm mean joint error against 100 mm on real ones, held-out
clips of the data-folder library) and with a yaw error of about 20 degrees a segment. A per-joint correction
(each joint's reflected rotation followed by the fixed rotation that turns its bone offsets onto its reflected
twins') levels the hips and brings the joints within 1.2 cm of the reflection, but the VAE's error on such
segments stays (231 mm, -10 degrees a segment): mirrored copies need a VAE trained on them too.

Copies are named `<source name>#mirror0` and keep the source's licence and held-out split (`library.source_name`).
"""
from __future__ import annotations

import re

import numpy as np

from ..joints import JOINT_NAMES
from .library import DERIVED, ClipLibrary, is_derived

# joint i of a mirrored pose takes joint MIRROR_JOINTS[i]'s rotation (left <-> right twins; the spine maps to itself)
MIRROR_JOINTS: tuple[int, ...] = tuple(
    JOINT_NAMES.index(n.replace("left_", "@").replace("right_", "left_").replace("@", "right_"))
    for n in JOINT_NAMES)

_SIDE_WORDS = {"left": "right", "right": "left", "clockwise": "counterclockwise",
               "counterclockwise": "clockwise", "anticlockwise": "clockwise", "counter-clockwise": "clockwise"}
_SIDE_RE = re.compile(r"\b(" + "|".join(sorted(map(re.escape, _SIDE_WORDS), key=len, reverse=True)) + r")\b",
                      re.IGNORECASE)


def mirror_caption(caption: str) -> str:
    """The caption of the mirrored clip: "left" <-> "right", clockwise <-> counterclockwise (case kept)."""
    def swap(m: re.Match) -> str:
        word = _SIDE_WORDS[m.group(0).lower()]
        return word.capitalize() if m.group(0)[0].isupper() else word
    return _SIDE_RE.sub(swap, caption)


def mirror_pose(rotations: np.ndarray, pelvis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Reflect a clip x -> -x. rotations (T, 22, 4) local quaternions w-first (joint 0 world), pelvis (T, 3)."""
    rot = rotations[:, MIRROR_JOINTS].copy()
    rot[..., 2:] *= -1.0          # (w, x, y, z) -> (w, x, -y, -z): S R S for S = diag(-1, 1, 1)
    pel = pelvis.copy()
    pel[:, 0] *= -1.0
    return rot, pel


def add_mirrors(lib: ClipLibrary, clip_ids: list[int], seed: int = 0) -> tuple[ClipLibrary, list[int]]:
    """A new library: `lib` plus a mirrored copy of every real (not derived) clip of `clip_ids`.

    Returns (library, indices of the copies); `lib`'s own clips keep their indices. `seed` is unused (the
    reflection is exact) and kept so that every derivation has the same signature."""
    del seed
    names, caps, srcs = list(lib.names), list(lib.captions), list(lib.sources)
    rots, pels, off = [lib.rotations], [lib.pelvis], list(lib.offsets)
    errors = list(lib.fit_error_mm) if lib.fit_error_mm else []
    new: list[int] = []
    for i in clip_ids:
        if is_derived(lib.names[i]):
            continue
        a, b = int(lib.offsets[i]), int(lib.offsets[i + 1])
        rot, pel = mirror_pose(lib.rotations[a:b], lib.pelvis[a:b])
        names.append(f"{lib.names[i]}{DERIVED}mirror0")
        caps.append(mirror_caption(lib.captions[i]))
        srcs.append(lib.sources[i])
        if errors:
            errors.append(lib.fit_error_mm[i])
        rots.append(rot)
        pels.append(pel)
        off.append(off[-1] + (b - a))
        new.append(len(names) - 1)
    out = ClipLibrary(names, caps, srcs, np.concatenate(rots), np.concatenate(pels), np.asarray(off, np.int64), errors)
    return out, new
