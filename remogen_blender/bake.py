"""Bake: generate a frame range deterministically for the seed and key it into a new action on the ego.

The session is stepped once per model frame (0.1 s) with the partner evaluated at exactly that time
(sub-frames when the scene fps is not a multiple of 10); every scene frame in the range is then keyed from
the model frames around it. Nothing is written until generation succeeded, and the scene's current frame
and the ego's pose are put back whatever happens, so a failed bake leaves the file as it was.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any, Callable

import bpy
import numpy as np

from . import action as action_mod
from ._runtime import UserError, api
from .frame import FrameDriver, scene_fps

MAX_FRAMES = 100_000


@dataclass
class BakeResult:
    action: bpy.types.Action
    frames: int                  # scene frames keyed
    model_frames: int            # model frames generated
    seconds: float               # generation + keying (model loading excluded)
    replaced: str | None         # the action that was on the ego before (kept, never edited)

    @property
    def model_fps(self) -> float:
        return self.model_frames / self.seconds if self.seconds > 0 else float("inf")


def bake(scene: bpy.types.Scene, frame_start: int | None = None, frame_end: int | None = None,
         model: Any = None, progress: Callable[[int, int], None] | None = None,
         name: str | None = None) -> BakeResult:
    f0 = scene.frame_start if frame_start is None else int(frame_start)
    f1 = scene.frame_end if frame_end is None else int(frame_end)
    if f1 < f0:
        raise UserError(f"Bake range {f0}..{f1} is empty; the end frame must not be before the start")
    if f1 - f0 + 1 > MAX_FRAMES:
        raise UserError(f"Bake range {f0}..{f1} has more than {MAX_FRAMES:,} frames; bake it in parts")
    fps = scene_fps(scene)
    driver = FrameDriver(scene, model=model, keep_frames=None)
    t_start = time.perf_counter()   # generation and keying only: loading the model is not the bake's speed
    ego = driver.writer.object
    n_model = int(math.ceil((f1 - f0) / fps / driver.dt - 1e-6)) + 1
    saved_frame = (scene.frame_current, scene.frame_subframe)
    saved_pose = _pose_snapshot(ego)
    ok = False
    try:
        for k in range(n_model):
            f = f0 + k * driver.dt * fps
            fi = int(math.floor(f + 1e-9))
            scene.frame_set(fi, subframe=max(0.0, f - fi))
            driver.update(scene, bpy.context.evaluated_depsgraph_get(), model_time=k * driver.dt, write=False)
            if progress is not None:
                progress(k + 1, n_model)
        frames = np.arange(f0, f1 + 1, dtype=np.float64)
        poses = driver.poses_at((frames - f0) / fps)
        locs, rots = driver.writer.pose_channels(poses.pelvis, poses.local_rotations)
        rots = api().continuous_quaternions(rots)
        if not (np.isfinite(locs).all() and np.isfinite(rots).all()):
            raise UserError("The model produced NaN poses; check the model file and the inputs")
        ok = True
    finally:
        scene.frame_set(saved_frame[0], subframe=saved_frame[1])
        if not ok:
            _pose_restore(ego, saved_pose)
    st = scene.remogen
    act, replaced = action_mod.write_pose_keys(
        ego, name or f"ReMoGen_{ego.name}_seed{st.seed}", frames, list(api().JOINT_NAMES), locs, rots, root="pelvis")
    _pose_restore(ego, saved_pose)   # the new action drives the pose from here on
    scene.frame_set(saved_frame[0], subframe=saved_frame[1])
    return BakeResult(act, len(frames), n_model, time.perf_counter() - t_start, replaced)


def _pose_snapshot(ob: bpy.types.Object) -> tuple[np.ndarray, np.ndarray]:
    n = len(ob.pose.bones)
    q = np.empty(n * 4, dtype=np.float32)
    loc = np.empty(n * 3, dtype=np.float32)
    ob.pose.bones.foreach_get("rotation_quaternion", q)
    ob.pose.bones.foreach_get("location", loc)
    return q, loc


def _pose_restore(ob: bpy.types.Object, snap: tuple[np.ndarray, np.ndarray]) -> None:
    try:
        ob.pose.bones.foreach_set("rotation_quaternion", snap[0])
        ob.pose.bones.foreach_set("location", snap[1])
        ob.update_tag()
    except ReferenceError:
        pass
