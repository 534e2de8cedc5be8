"""ReMoGen runtime: a PyTorch implementation of ReMoGen (CVPR 2026) for online reaction generation.

Public API:
    from model_runtime import load_model, ReactionSession, ReactionGroup, EgoSettings, EgoFrame, OccupancyGrid
    model = load_model()                       # shipped weights; load_model(path) or load_model(config=...)
    s = ReactionSession(model, text="walk to the person and wave", seed=0,
                        alpha={"hhi": 1.0, "hsi": 1.0}, guidance=6.0, fwsr=True, scene=None)
    s.reset(root_position=(0, 0, 0), yaw=0.0)
    f = s.step(partner=joints_22x3_or_None, goal=xyz_or_None)
    s.text_warning                             # one line when the text cannot be read (prompt_warning(text))

    # several egos stepped as one batch, each reacting to the nearest other character (partner or ego)
    g = ReactionGroup(model, [EgoSettings(text="walk forward", seed=0), EgoSettings(text="wave", seed=1)])
    g.reset(root_positions=[(0, 0, 0), (2, 0, 0)], yaws=[0.0, 0.0])
    frames = g.step(partner=joints_22x3_or_None, goals=[None, xyz_or_None])   # one EgoFrame per ego

Importing this package does not import PyTorch: the skeleton description (JOINT_NAMES, PARENTS,
rest_joints_np), the bone maps, the NumPy quaternion maths, the error types and prompt_warning work
without it, so a host application can show and check rigs and prompts before PyTorch is installed. The model, the session and the
motion readers import PyTorch when first used. This package never imports bpy.
"""
from __future__ import annotations

import os
from importlib import import_module
from pathlib import Path

# Intel MKL's strict reproducibility mode: its matrix products (all of PyTorch's float32 linear layers on x86
# CPUs) give the same bits at any thread count, so a seed gives the same motion with 1 or 8 threads. Without
# it, MKL picks kernels by the per-thread share of a product, and the paper-size model drifted 3e-5 m in
# 200 frames between 1 and 2 threads. MKL reads this once, at its first product, so it is set on import,
# before this package runs any PyTorch op. A value already set (by the user) is kept.
os.environ.setdefault("MKL_CBWR", "AUTO,STRICT")

from .config import ModelConfig
from .data.bone_maps import BoneMapGuess, guess_bone_map, normalise_name, validate_bone_map
from .errors import (DEFAULT_FINAL_GUIDANCE_MIN_SPEED, DEFAULT_FINAL_GUIDANCE_SHARE, DEFAULT_GUIDANCE, MAX_COORD,
                     MAX_GUIDANCE, InputError, ModelFileError, ModelOutputError, RemogenError)
from .joints import JOINT_NAMES, NUM_JOINTS, PARENTS, rest_joints_np, standing_pelvis_height
from .prompt import prompt_warning
from .quat import continuous_quaternions, matrix_to_quat_np, qconj, qmul, qslerp, rigid_rotation

# name -> module for the parts that need PyTorch (or are heavy), imported on first use
_LAZY = {
    "load_model": ".checkpoint", "save_model": ".checkpoint",
    "ReactionSession": ".session", "EgoFrame": ".session",
    "ReactionGroup": ".group", "EgoSettings": ".ego",
    "OccupancyGrid": ".voxel", "ControlConfig": ".control",
    "Motion": ".data.motion", "load_motion": ".data.motion",
    "toe_roll": ".footlock",
}

__all__ = ["load_model", "save_model", "ReactionSession", "ReactionGroup", "EgoSettings", "EgoFrame", "OccupancyGrid", "ModelConfig", "ControlConfig",
           "RemogenError", "InputError", "ModelFileError", "ModelOutputError", "MAX_COORD", "MAX_GUIDANCE",
           "DEFAULT_GUIDANCE", "DEFAULT_FINAL_GUIDANCE_SHARE", "DEFAULT_FINAL_GUIDANCE_MIN_SPEED",
           "Motion", "load_motion", "prompt_warning",
           "WALK_CLIP", "JOINT_NAMES", "NUM_JOINTS", "PARENTS", "rest_joints_np", "standing_pelvis_height",
           "BoneMapGuess", "guess_bone_map", "normalise_name", "validate_bone_map",
           "qmul", "qconj", "qslerp", "matrix_to_quat_np", "rigid_rotation", "continuous_quaternions",
           "toe_roll"]
__version__ = "0.1.0"

# A real walk (CMU trial 05_01, retargeted to the SMPL-X body, 10 fps pose channels): the partner of the demo
# scene and of the behaviour suite's scenarios.
WALK_CLIP = Path(__file__).resolve().parent / "data" / "clips" / "cmu_05_01_walk.npz"


def __getattr__(name: str):
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'model_runtime' has no attribute {name!r}")
    value = getattr(import_module(module, __name__), name)
    globals()[name] = value
    return value
