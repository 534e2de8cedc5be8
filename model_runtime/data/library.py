"""ClipLibrary: every training clip at 10 fps on the SMPL-X skeleton, in one compact .npz.

Reading ~500 BVH files and retargeting them takes minutes, so `prepare` does it once and training
reloads the cache. Clips keep their source and licence so a CMU-only (commercial-use) recipe can
always be rebuilt, and a deterministic held-out split by clip name so evaluation never sees training
clips: about 10 % of the clips, and never none or all of them when there are two or more.
"""
from __future__ import annotations

import hashlib
import os
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from ..errors import InputError
from ..features import features_from_pose
from ..skeleton import quat_to_matrix

LICENCES = {"cmu": "CMU Graphics Lab Motion Capture Database (commercial use allowed)",
            "bandai": "Bandai-Namco-Research-Motiondataset, CC BY-NC 4.0 (non-commercial)"}


def non_commercial(sources, meta: dict | None = None) -> bool:
    """Whether weights trained on these dataset tags (and on what a model file's meta records) are non-commercial."""
    return "bandai" in set(sources) | set((meta or {}).get("sources", [])) or bool((meta or {}).get("non_commercial"))


DERIVED = "#"   # a clip made from another is named `<source name>#<variant>` (data/turns.py)


def source_name(name: str) -> str:
    """The real clip a (possibly derived) clip name comes from."""
    return name.split(DERIVED, 1)[0]


def is_derived(name: str) -> bool:
    return DERIVED in name


def derived_kind(name: str) -> str:
    """"turn", "detour", "arrive", ... for a derived clip name (`<source>#<kind><k>`); "" for a real clip."""
    return name.split(DERIVED, 1)[1].rstrip("0123456789") if is_derived(name) else ""


def _split_key(name: str) -> int:
    """0..999 from the hash of the source clip's name: below 1000 * fraction is held out."""
    return int(hashlib.sha1(source_name(name).encode()).hexdigest()[:8], 16) % 1000


def held_out(name: str, fraction: float = 0.1) -> bool:
    """Deterministic split by clip name (stable across machines and runs). A derived clip falls on its
    source's side, so no source leaks across the split. ClipLibrary.split adds the guarantee of at least one
    held-out and one training clip."""
    return _split_key(name) < fraction * 1000


def held_out_sources(names: list[str]) -> set[str]:
    """The source clip names held out for validation: those `held_out` picks and, among two or more sources,
    never none or all of them (the source nearest the cut moves across)."""
    sources = sorted({source_name(n) for n in names})
    val = {s for s in sources if held_out(s)}
    if len(sources) >= 2 and not val:
        val = {min(sources, key=_split_key)}
    elif len(sources) >= 2 and len(val) == len(sources):
        val.discard(max(sources, key=_split_key))
    return val


@dataclass
class ClipLibrary:
    names: list[str]
    captions: list[str]
    sources: list[str]                 # "cmu" | "bandai" | other dataset tags
    rotations: np.ndarray              # (N, 22, 4) float32 local quaternions w-first, all clips concatenated
    pelvis: np.ndarray                 # (N, 3) float32 world pelvis
    offsets: np.ndarray                # (n_clips + 1,) int64 clip i is frames offsets[i]:offsets[i+1]
    fit_error_mm: list[float] = field(default_factory=list)
    _features: dict = field(default_factory=dict, repr=False)
    _held_out: tuple[int, set[str]] = field(default=(-1, set()), repr=False)   # (len(names), held_out_sources)

    def __len__(self) -> int:
        return len(self.names)

    def frames(self, i: int) -> int:
        return int(self.offsets[i + 1] - self.offsets[i])

    def is_held_out(self, i: int) -> bool:
        if self._held_out[0] != len(self.names):
            self._held_out = (len(self.names), held_out_sources(self.names))
        return source_name(self.names[i]) in self._held_out[1]

    def split(self, which: str, min_frames: int = 0) -> list[int]:
        """Indices of 'train' or 'val' clips with at least min_frames frames."""
        want = which == "val"
        return [i for i in range(len(self)) if self.is_held_out(i) == want and self.frames(i) >= min_frames]

    def pose(self, i: int) -> tuple[torch.Tensor, torch.Tensor]:
        a, b = self.offsets[i], self.offsets[i + 1]
        return quat_to_matrix(torch.from_numpy(self.rotations[a:b])), torch.from_numpy(self.pelvis[a:b])

    def features(self, i: int) -> torch.Tensor:
        """(T - 1, 276) world-frame features of clip i (the last frame only supplies deltas). Cached."""
        if i not in self._features:
            rot, pel = self.pose(i)
            self._features[i] = features_from_pose(rot, pel)
        return self._features[i]

    def subset(self, sources: set[str]) -> "ClipLibrary":
        keep = [i for i in range(len(self)) if self.sources[i] in sources]
        rot, pel, off = [], [], [0]
        for i in keep:
            a, b = self.offsets[i], self.offsets[i + 1]
            rot.append(self.rotations[a:b])
            pel.append(self.pelvis[a:b])
            off.append(off[-1] + b - a)
        return ClipLibrary([self.names[i] for i in keep], [self.captions[i] for i in keep],
                           [self.sources[i] for i in keep], np.concatenate(rot), np.concatenate(pel),
                           np.asarray(off, np.int64),
                           [self.fit_error_mm[i] for i in keep] if self.fit_error_mm else [])

    # ---------------------------------------------------------------- persistence
    def save(self, path: str | os.PathLike) -> Path:
        """Write the library to exactly `path` (through a temporary file, so an interrupted write leaves no
        half file)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(path.name + ".part")
        with tmp.open("wb") as fh:
            np.savez_compressed(fh, names=np.asarray(self.names), captions=np.asarray(self.captions),
                                sources=np.asarray(self.sources), rotations=self.rotations, pelvis=self.pelvis,
                                offsets=self.offsets, fit_error_mm=np.asarray(self.fit_error_mm, np.float32))
        os.replace(tmp, path)
        return path

    @classmethod
    def load(cls, path: str | os.PathLike) -> "ClipLibrary":
        path = Path(path)
        if not path.exists():
            raise InputError(f"clip library {path} not found; build it with "
                             f"python -m model_runtime.data.prepare --data MOTION_FOLDER --out {path}")
        try:
            with np.load(path, allow_pickle=False) as z:
                return cls([str(s) for s in z["names"]], [str(s) for s in z["captions"]],
                           [str(s) for s in z["sources"]], z["rotations"].astype(np.float32),
                           z["pelvis"].astype(np.float32), z["offsets"].astype(np.int64),
                           [float(x) for x in z["fit_error_mm"]])
        except (KeyError, ValueError, OSError, zipfile.BadZipFile) as exc:
            why = " ".join(str(exc).split())[:80]
            raise InputError(f"{path} is not a clip library ({type(exc).__name__}: {why}); "
                             "build one with python -m model_runtime.data.prepare") from None

    @classmethod
    def from_motions(cls, motions: list, names: list[str], sources: list[str]) -> "ClipLibrary":
        """motions: objects with local_rotations (T,22,4), root (T,4,4), caption (see data.motion.Motion)."""
        rot, pel, off = [], [], [0]
        for m in motions:
            rot.append(np.asarray(m.local_rotations, np.float32))
            pel.append(np.asarray(m.root, np.float32)[:, :3, 3])
            off.append(off[-1] + len(rot[-1]))
        errors = [float((getattr(m, "fit_error_mm", None) or {}).get("mean", float("nan"))) for m in motions]
        return cls(list(names), [m.caption or "" for m in motions], list(sources), np.concatenate(rot),
                   np.concatenate(pel), np.asarray(off, np.int64), errors)
