"""ClipLibrary: every training clip at 10 fps on the SMPL-X skeleton, in one compact .npz.

Reading ~500 BVH files and retargeting them takes minutes, so `prepare` does it once and training
reloads the cache. Clips keep their source and licence so a CMU-only (commercial-use) recipe can
always be rebuilt, and a deterministic held-out split by clip name so evaluation never sees training
clips.
"""
from __future__ import annotations

import csv
import hashlib
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from ..errors import InputError
from ..features import features_from_pose
from ..skeleton import quat_to_matrix

LICENCES = {"cmu": "CMU Graphics Lab Motion Capture Database (commercial use allowed)",
            "bandai": "Bandai-Namco-Research-Motiondataset, CC BY-NC 4.0 (non-commercial)"}


DERIVED = "#"   # a clip made from another is named `<source name>#<variant>` (data/turns.py)


def source_name(name: str) -> str:
    """The real clip a (possibly derived) clip name comes from."""
    return name.split(DERIVED, 1)[0]


def is_derived(name: str) -> bool:
    return DERIVED in name


def derived_kind(name: str) -> str:
    """"turn", "detour", "arrive", ... for a derived clip name (`<source>#<kind><k>`); "" for a real clip."""
    return name.split(DERIVED, 1)[1].rstrip("0123456789") if is_derived(name) else ""


def held_out(name: str, fraction: float = 0.1) -> bool:
    """Deterministic split by clip name (stable across machines and runs). A derived clip falls on its
    source's side, so no source leaks across the split."""
    h = int(hashlib.sha1(source_name(name).encode()).hexdigest()[:8], 16)
    return (h % 1000) < fraction * 1000


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

    def __len__(self) -> int:
        return len(self.names)

    def frames(self, i: int) -> int:
        return int(self.offsets[i + 1] - self.offsets[i])

    def is_held_out(self, i: int) -> bool:
        return held_out(self.names[i])

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
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(path, names=np.asarray(self.names), captions=np.asarray(self.captions),
                            sources=np.asarray(self.sources), rotations=self.rotations, pelvis=self.pelvis,
                            offsets=self.offsets, fit_error_mm=np.asarray(self.fit_error_mm, np.float32))
        return path

    @classmethod
    def load(cls, path: str | os.PathLike) -> "ClipLibrary":
        path = Path(path)
        if not path.exists():
            raise InputError(f"clip library {path} not found; build it with "
                             "python -m model_runtime.data.prepare --data ../shared/data")
        with np.load(path, allow_pickle=False) as z:
            return cls([str(s) for s in z["names"]], [str(s) for s in z["captions"]],
                       [str(s) for s in z["sources"]], z["rotations"].astype(np.float32),
                       z["pelvis"].astype(np.float32), z["offsets"].astype(np.int64),
                       [float(x) for x in z["fit_error_mm"]])

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


def shared_data_files(data_dir: str | os.PathLike, cmu_only: bool = False) -> list[tuple[Path, str, dict]]:
    """(path, source, index row) for every clip of the project's data folder, using its index.csv files."""
    data_dir = Path(data_dir)
    out = []
    for source, sub in (("cmu", "cmu"), ("bandai", "bandai")):
        if cmu_only and source != "cmu":
            continue
        index = data_dir / sub / "index.csv"
        if not index.exists():
            continue
        with index.open(newline="") as fh:
            for row in csv.DictReader(fh):
                rel = row.get("file") or row.get("path") or ""
                p = data_dir / sub / rel
                if p.suffix.lower() == ".bvh" and p.exists():
                    out.append((p, source, row))
    return out


def bandai_repository_files(repo_dir: str | os.PathLike, skip: set[str] = frozenset()) -> list[tuple[Path, str, dict]]:
    """(path, "bandai", row) for every BVH of a checkout of the Bandai Namco repository
    (`dataset/Bandai-Namco-Research-Motiondataset-{1,2}/data/*.bvh`), for a larger training run than the
    project's data folder holds (it keeps 3 takes per content/style of dataset-2; the repository has 2,902).
    Content and style come from the file name `dataset-N_<content>_<style>_<take>.bvh`; stems in `skip`
    (clips already read from the data folder) are left out so no clip is counted twice."""
    root = Path(repo_dir)
    out = []
    for p in sorted(root.glob("dataset/Bandai-Namco-Research-Motiondataset-*/data/*.bvh")):
        parts = p.stem.split("_")
        if len(parts) != 4 or p.stem in skip:
            continue
        out.append((p, "bandai", {"file": p.name, "content": parts[1], "style": parts[2], "take": parts[3]}))
    return out
