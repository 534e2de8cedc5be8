"""Motion data: readers (BVH, Acclaim ASF/AMC, AMASS .npz), retargeting to SMPL-X, captions, the clip library."""
from .motion import Motion, load_motion

__all__ = ["Motion", "load_motion"]
