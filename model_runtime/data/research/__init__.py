"""Loaders for the research datasets the paper trains on, in their published layouts.

A user who has HumanML3D (+ AMASS), Inter-X, LINGO or EgoBody on disk can turn each into our types:
`Motion` (10 fps, SMPL-X 22 joints, world Z-up metres, betas = 0 for the ego), partner joints (T, 22, 3)
in the same world frame, and `OccupancyGrid` scenes. Nothing here downloads anything; the tests run on
tiny synthetic fixtures written in the same layouts (no licensed data in the repository).

Every SMPL-X/H parameter set goes through `amass.load_amass` (the one place that maps the body model's
Y-up rest onto our Z-up skeleton and resamples to 10 fps by slerp); these loaders only move parameters
into a Z-up world first (Inter-X and LINGO are Y-up, EgoBody is in Kinect camera coordinates) and cuts
clips. Body shape is never used: the ego has betas = 0 as in the paper, and so does the partner here (the
paper keeps the partner's betas, which needs the SMPL-X model this runtime does not ship). Moving a body
rigidly uses the betas = 0 rest pelvis as the rotation centre; for a real subject the centre differs by a
few centimetres, which shifts that body by at most that much.

`DATASETS` describes each layout, what was confirmed and from where, and what was assumed; each dataset has
its own module (humanml3d, interx, lingo, egobody) on shared helpers (common, scenes).
"""
from __future__ import annotations

from . import egobody, humanml3d, interx, lingo
from .egobody import load_egobody
from .humanml3d import load_humanml3d
from .interx import load_interx_pairs
from .lingo import lingo_grid, load_lingo
from .scenes import LINGO_BOUNDS, LINGO_VOXEL, read_obj

__all__ = ["DATASETS", "LINGO_BOUNDS", "LINGO_VOXEL", "load_humanml3d", "load_interx_pairs", "load_lingo",
           "load_egobody", "lingo_grid", "read_obj"]

DATASETS: dict[str, str] = {"humanml3d": humanml3d.LAYOUT, "interx": interx.LAYOUT, "lingo": lingo.LAYOUT,
                            "egobody": egobody.LAYOUT}
