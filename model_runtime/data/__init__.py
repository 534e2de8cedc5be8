"""Motion data: readers (BVH, Acclaim ASF/AMC, AMASS .npz), retargeting to SMPL-X, captions, the clip library.

    python -m model_runtime.data.prepare --data MOTION_FOLDER --out runs/clips.npz

builds the clip library from a folder (clip_files says which files and captions, prepare reads them); pairs
generates the interaction training data from it; research loads the paper's datasets in their own layouts.

The readers need PyTorch; `bone_maps` does not, so this package imports its torch parts only when asked.
"""
from __future__ import annotations

__all__ = ["Motion", "load_motion"]


def __getattr__(name: str):
    if name in __all__:
        from . import motion
        return getattr(motion, name)
    raise AttributeError(name)
