"""Bake: generate a frame range deterministically for the seeds and key it into a new action on the ego, on
the target rig when one is set, and on every other ego of the scene's ego list (each posed armature gets its
own new action; their old ones are kept).

The session is stepped once per model frame (0.1 s) with the partner as Live sees it during playback: at
the scene frame where Live first needs that model frame (the frame at its time at 10 fps, up to 0.1 s
earlier at other rates). Every scene frame in the range is then keyed from the model frames around it,
interpolated as Live shows them, so a bake replays what Live shows frame by frame. Nothing is written until generation succeeded, and the scene's current frame
and the ego's pose are put back whatever happens, so a failed or cancelled bake leaves the file as it was.

`BakeJob` does the work in steps, so that the UI operator can run it a chunk per timer tick (progress,
Esc) and a script or the command line can stop it between model frames; `bake()` runs one to the end.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any, Callable

import bpy
import numpy as np

from . import action as action_mod
from ._runtime import UserError, api
from .ego_state import PoseSnapshot
from .frame import FrameDriver, scene_fps

MAX_FRAMES = 100_000         # scene frames keyed in one bake
MAX_MODEL_SECONDS = 3600.0   # model time generated in one bake (36,000 model frames at 10 fps)


class BakeCancelled(UserError):
    """The bake was cancelled; the scene, the egos and their actions are as they were."""


@dataclass
class BakeResult:
    action: bpy.types.Action     # the first keyed armature's new action (the ego's, or the target's alone)
    frames: int                  # scene frames keyed
    model_frames: int            # model frames generated
    seconds: float               # generation + keying (model loading excluded)
    replaced: str | None         # the action that was on that armature before (kept, never edited)
    keyed: list[tuple[str, bpy.types.Action, str | None]] = field(default_factory=list)
    # every keyed armature: (object name, new action, the action it replaced)

    @property
    def model_fps(self) -> float:
        return self.model_frames / self.seconds if self.seconds > 0 else float("inf")


class BakeJob:
    """One bake: check the range, generate model frames in steps, then key them (or put everything back)."""

    def __init__(self, scene: bpy.types.Scene, frame_start: int | None = None, frame_end: int | None = None,
                 model: Any = None, name: str | None = None) -> None:
        f0 = scene.frame_start if frame_start is None else int(frame_start)
        f1 = scene.frame_end if frame_end is None else int(frame_end)
        if f1 < f0:
            raise UserError(f"Bake range {f0}..{f1} is empty; the end frame must not be before the start")
        if f1 - f0 + 1 > MAX_FRAMES:
            raise UserError(f"Bake range {f0}..{f1} has more than {MAX_FRAMES:,} frames; bake it in parts")
        self.scene = scene
        self.f0, self.f1 = f0, f1
        self.fps = scene_fps(scene)
        self.name = name
        # No helper process: a bake steps back to back, where the helper's job sets the pace and saves nothing,
        # and Blender crashed now and then in the bake operator's call or its undo step while a helper was there.
        self.driver = FrameDriver(scene, model=model, keep_frames=None, pipeline=False)
        dt = self.driver.dt
        # Model frames, not scene frames, are the cost: 12 frames at 0.001 fps are 12,000 s of motion.
        self.total = int(math.ceil((f1 - f0) / self.fps / dt - 1e-6)) + 1
        limit = int(round(MAX_MODEL_SECONDS / dt))
        if self.total > limit:
            raise UserError(f"Bake range {f0}..{f1} at {self.fps:g} fps is {(f1 - f0) / self.fps:,.0f} s, "
                            f"{self.total:,} model frames; the limit is {limit:,} ({MAX_MODEL_SECONDS / 60:g} "
                            "minutes of motion): bake it in parts or check the scene's frame rate")
        self.done = 0                # model frames generated so far
        self._frame = f0             # the scene frame the next model frame reads the partner at
        self._frame_set: int | None = None
        self.posed = self.driver.posed_objects
        self._saved_frame = (scene.frame_current, scene.frame_subframe)
        self._saved_poses = [PoseSnapshot.take(ob) for ob in self.posed]
        self._t_start = time.perf_counter()   # generation and keying: loading the model is not the bake's speed
        self._closed = False

    @property
    def finished_generating(self) -> bool:
        return self.done >= self.total

    def step(self, max_frames: int = 1, seconds: float | None = None) -> bool:
        """Generate up to `max_frames` model frames (or as many as fit in `seconds`, at least one).

        Returns True once every model frame is generated. Any error puts the scene back first.
        """
        t_end = None if seconds is None else time.perf_counter() + seconds
        try:
            n = 0
            while not self.finished_generating and (n < max_frames if t_end is None
                                                    else (n == 0 or time.perf_counter() < t_end)):
                self._generate(self.done)
                self.done += 1
                n += 1
        except BaseException:
            self.cancel()
            raise
        return self.finished_generating

    def _generate(self, k: int) -> None:
        dt, scene, driver = self.driver.dt, self.scene, self.driver
        while driver.last_needed((self._frame - self.f0) / self.fps) < k:
            self._frame += 1
        if self._frame != self._frame_set:
            scene.frame_set(self._frame)
            self._frame_set = self._frame
        driver.update(scene, bpy.context.evaluated_depsgraph_get(), model_time=k * dt, write=False)

    def cancel(self) -> None:
        """Put the current frame and the ego's pose back; nothing was written. Safe to call twice."""
        if self._closed:
            return
        self._closed = True
        self.scene.frame_set(self._saved_frame[0], subframe=self._saved_frame[1])
        self._restore_poses()

    def _restore_poses(self) -> None:
        for ob, pose in zip(self.posed, self._saved_poses):
            pose.restore(ob)

    def finish(self) -> BakeResult:
        """Key every scene frame into a new action on each posed armature (the only change the bake makes)."""
        if not self.finished_generating:
            raise RuntimeError("BakeJob.finish() before every model frame was generated")
        driver = self.driver
        try:
            frames = np.arange(self.f0, self.f1 + 1, dtype=np.float64)
            poses = driver.poses_at((frames - self.f0) / self.fps)
            channels = []                     # per posed armature: [(bone, property, (T, n) values)]
            if driver.writer is not None:
                channels.append(_ego_channels("Ego", driver.writer, poses))
            if driver.target is not None:
                locs, rots = driver.target_channels(poses)
                _check_finite("Target", driver.target.name, locs, rots)
                channels.append(driver.target.key_channels(locs, rots))
            for k, e in enumerate(driver.others, start=1):
                channels.append(_ego_channels(e.label, e.writer, driver.poses_at((frames - self.f0) / self.fps, k)))
        except BaseException:
            self.cancel()
            raise
        self.scene.frame_set(self._saved_frame[0], subframe=self._saved_frame[1])
        # the seed in each action's name is its ego's: the first ego's for the ego and the target
        seeds = [self.scene.remogen.seed] * (len(self.posed) - len(driver.others)) + [e.source.seed for e in driver.others]
        keyed = []
        for k, (ob, chans, seed) in enumerate(zip(self.posed, channels, seeds)):
            name = (self.name if k == 0 else f"{self.name}_{ob.name}") if self.name else f"ReMoGen_{ob.name}_seed{seed}"
            act, replaced = action_mod.write_bone_keys(ob, name, frames, chans)
            keyed.append((ob.name, act, replaced))
        self._restore_poses()   # the new actions drive the poses from here on
        self._closed = True
        return BakeResult(keyed[0][1], len(frames), self.total, time.perf_counter() - self._t_start, keyed[0][2],
                          keyed)


def _ego_channels(what: str, writer: Any, poses: Any) -> list:
    """The key channels of an ego armature for a batch of poses, checked finite."""
    locs, rots = writer.pose_channels(poses.pelvis, poses.local_rotations)
    rots = api().continuous_quaternions(rots)
    _check_finite(what, writer.name, locs, rots)
    return action_mod.pose_channels(list(api().JOINT_NAMES), locs, rots, root="pelvis")


def _check_finite(what: str, name: str, locs: np.ndarray, rots: np.ndarray) -> None:
    if not (np.isfinite(locs).all() and np.isfinite(rots).all()):
        raise UserError(f"{what} '{name}': the baked poses are not finite and were not keyed; "
                        f"check the {what.lower()}'s transform")


def bake(scene: bpy.types.Scene, frame_start: int | None = None, frame_end: int | None = None,
         model: Any = None, progress: Callable[[int, int], None] | None = None,
         name: str | None = None, cancelled: Callable[[], bool] | None = None) -> BakeResult:
    """Bake to the end. progress(done, total) after each model frame; cancelled() True stops the bake
    before the next model frame with BakeCancelled, leaving everything as it was."""
    job = BakeJob(scene, frame_start, frame_end, model=model, name=name)
    while not job.finished_generating:
        if cancelled is not None and cancelled():
            job.cancel()
            raise BakeCancelled(f"Bake cancelled after {job.done:,} of {job.total:,} model frames; "
                                "nothing was changed")
        job.step()
        if progress is not None:
            progress(job.done, job.total)
    return job.finish()
