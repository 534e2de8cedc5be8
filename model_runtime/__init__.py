"""ReMoGen runtime: a PyTorch implementation of ReMoGen (CVPR 2026) for online reaction generation.

Public API:
    from model_runtime import load_model, ReactionSession, EgoFrame, OccupancyGrid
    model = load_model()                       # shipped weights; load_model(path) or load_model(config=...)
    s = ReactionSession(model, text="walk to the person and wave", seed=0,
                        alpha={"hhi": 1.0, "hsi": 1.0}, guidance=5.0, fwsr=True, scene=None)
    s.reset(root_position=(0, 0, 0), yaw=0.0)
    f = s.step(partner=joints_22x3_or_None, goal=xyz_or_None)

This package never imports bpy.
"""
from __future__ import annotations

from .checkpoint import load_model, save_model
from .config import ModelConfig
from .errors import InputError, ModelFileError, RemogenError
from .session import EgoFrame, ReactionSession

__all__ = ["load_model", "save_model", "ReactionSession", "EgoFrame", "OccupancyGrid", "ModelConfig",
           "RemogenError", "InputError", "ModelFileError"]
__version__ = "0.1.0"


def __getattr__(name: str):
    # voxel.py is NumPy-only and optional for most uses; import it when asked for.
    if name == "OccupancyGrid":
        from .voxel import OccupancyGrid
        return OccupancyGrid
    raise AttributeError(name)
