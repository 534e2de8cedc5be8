"""The one per-frame function: read the partner -> step the egos -> write the egos and/or the target.

`FrameDriver.update()` is called by the live modal operator (timer), the frame-change handler and the bake
loop alike. Scene time (any fps, any frame_start) maps to model time, one model frame per 0.1 s; frames
between two model frames are shown by interpolation (lerp of the pelvis, slerp of the rotations).

A target rig (the user's own armature, rig/target.py) is posed from the same poses, beside the ego or
instead of it. While the ego reports a foot planted (EgoFrame.contacts) the target's toe stays where it was
at the model frame that contact began; after lift-off the remaining correction fades out by the next model
frame. Those points are computed per model frame, so live and a bake pin the same points.

More egos (the scene's ego list) are stepped together with the first one as one ReactionGroup; each reacts
to the nearest other character, the partner or another ego. The target follows the first ego.
"""
from __future__ import annotations

import math
import time
from collections import deque
from dataclasses import dataclass
from typing import Any

import bpy
import numpy as np

from . import rig
from ._runtime import UserError, api, get_model, runtime, torch_error, use_helper_process
from .properties import GUIDANCE_MAX
from .scene import SceneCache

_RT = api()   # the runtime's public package; these parts of it need no PyTorch

MODEL_DT = 0.1          # seconds per model frame of the shipped models; a FrameDriver uses its model.fps
MAX_CATCH_UP = 1.0      # live: a forward jump longer than this continues from the current pose instead
MAX_PARTNER_SPAN = 5.0  # metres: no person spans more; a rig that does is in centimetres
_EPS = 1e-6


def scene_fps(scene: bpy.types.Scene) -> float:
    return scene.render.fps / scene.render.fps_base


def scene_time(scene: bpy.types.Scene, frame: float | None = None) -> float:
    """Seconds since the scene's frame_start for `frame` (default: the current frame and subframe)."""
    f = scene.frame_current + scene.frame_subframe if frame is None else frame
    return (f - scene.frame_start) / scene_fps(scene)


@dataclass
class Pose:
    """Ego poses in world space: pelvis position and SMPL-X local quaternions (w first), one pose (no leading
    axis) or a batch (T, ...), with the feet's contacts."""
    pelvis: np.ndarray            # (3,) or (T, 3)
    local_rotations: np.ndarray   # (22, 4) or (T, 22, 4)
    frame: np.ndarray             # () or (T,) int: the model frame at or just before each time
    planted: np.ndarray           # (2,) or (T, 2): 1 while a foot is planted, fading to 0 after lift-off, else 0
    contact_start: np.ndarray     # (2,) or (T, 2) int: model frame where the contact at `frame` began, -1 none


def _settings(src: Any) -> tuple:
    """The panel settings an ego follows (a change is passed on before the next model frame)."""
    return src.text, src.seed, src.alpha_hhi, src.alpha_hsi, src.guidance, src.use_fwsr


@dataclass
class OtherEgo:
    """An ego of the scene's ego list: its entry (where its settings are), its name in messages, its writer."""
    source: Any
    label: str
    writer: rig.EgoWriter


def other_egos(scene: bpy.types.Scene) -> list[OtherEgo]:
    """The egos of the scene's ego list, checked: each has its own armature, in the scene, that is neither
    the first ego, the partner nor the target."""
    st = scene.remogen
    seen = {ob.name for ob in (st.ego, st.target) if ob is not None}
    out = []
    for n, item in enumerate(st.egos, start=2):
        label = f"Ego {n}"
        if item.ego is None:
            raise UserError(f"{label} of the ego list has no armature; pick one or remove the entry")
        if item.ego == st.partner:
            raise UserError(f"The partner and {label.lower()} are the same armature; pick another partner")
        if item.ego.name in seen:
            raise UserError(f"Armature '{item.ego.name}' is used twice among the egos and the target; "
                            "give each ego its own armature")
        seen.add(item.ego.name)
        _check_in_scene(scene, item.ego, label)
        _check_finite_transform(item.ego, label)
        out.append(OtherEgo(item, label, rig.EgoWriter(item.ego)))
    return out


class FrameDriver:
    """Running ReMoGen egos bound to one scene's partner, scene collection, goal, egos and target."""

    def __init__(self, scene: bpy.types.Scene, model: Any = None, keep_frames: int | None = 600,
                 pipeline: bool | None = None) -> None:
        """`pipeline`: run each segment's diffusion in the runtime's helper process (None: the preference)."""
        st = scene.remogen
        if torch_error():                       # the most basic problem first
            raise UserError(torch_error())
        only_target = st.target is not None and st.target_mode == 'TARGET'
        if st.ego is None and not only_target:
            raise UserError("No ego armature: press 'Create Ego' in the ReMoGen panel (or pick a target rig)")
        if st.partner is None:
            raise UserError("Pick a partner armature in the ReMoGen panel")
        if st.partner == st.ego and not only_target:
            raise UserError("The partner and the ego are the same armature; pick another partner")
        self.scene_name = scene.name
        self.writer: rig.EgoWriter | None = None      # None: "Target only", the ego is left alone
        if not only_target:
            _check_in_scene(scene, st.ego, "Ego")
            _check_finite_transform(st.ego, "Ego")
            self.writer = rig.EgoWriter(st.ego)
        self.target = self._make_target(scene, st) if st.target is not None else None
        self.others = other_egos(scene)
        self.reader = self._make_reader(scene, st)
        self.model = model if model is not None else get_model()
        self.dt = 1.0 / float(getattr(self.model, "fps", 1.0 / MODEL_DT))   # seconds per model frame
        rt = runtime()
        self.group = rt.ReactionGroup(
            self.model, [rt.EgoSettings(text=src.text, seed=src.seed, alpha=_alpha(src), guidance=_guidance(src),
                                        fwsr=src.use_fwsr, cleanup=st.use_foot_lock) for src in self._sources(st)],
            scene=None, control=st.use_control,
            pipeline=use_helper_process() if pipeline is None else pipeline)
        root, yaw = (self.writer or self.target).start_pose()
        starts = [(root, yaw)] + [e.writer.start_pose() for e in self.others]
        self.group.reset(root_positions=[r for r, _ in starts], yaws=[y for _, y in starts])
        if self.target is not None:
            self.target.follow(root, yaw)
        self._applied = self._all_settings(st)
        self.scene_cache = SceneCache()
        self.frames: deque = deque(maxlen=keep_frames)   # the first ego's EgoFrames, newest last
        self.other_frames: deque = deque(maxlen=keep_frames)   # per model frame, the other egos' EgoFrames
        self.contact_starts: deque = deque(maxlen=keep_frames)   # per frame: (left, right) contact_start
        self._toes: dict[int, np.ndarray] = {}            # model frame -> target's (2, 3) world toes there
        self.first_index = 0                              # model index of frames[0]
        self.anchor = scene_time(scene)                   # scene time of model frame 0 (live)
        self.last_time = 0.0
        self.step_ms = 0.0        # the last model step: read partner, scene, session.step
        self.update_ms = 0.0      # the last update(): steps + interpolation + writing the pose

    @property
    def posed_objects(self) -> list[bpy.types.Object]:
        """The armatures this driver poses: the ego, the target, or both, and the other egos."""
        return [w.object for w in (self.writer, self.target) if w is not None] + [e.writer.object for e in self.others]

    # ------------------------------------------------------------------ inputs
    @staticmethod
    def _make_reader(scene: bpy.types.Scene, st: Any) -> rig.PartnerReader:
        _check_in_scene(scene, st.partner, "Partner")
        _check_finite_transform(st.partner, "Partner")
        return rig.PartnerReader(st.partner, rig.ensure_bone_map(st, st.partner))

    @staticmethod
    def _make_target(scene: bpy.types.Scene, st: Any) -> rig.TargetWriter:
        target = rig.check_armature(st.target, "Target")
        if target == st.partner:
            raise UserError("The target and the partner are the same armature; pick your character as the target")
        if target == st.ego:
            raise UserError("The target is the ego armature; pick your own character's armature as the target")
        _check_in_scene(scene, target, "Target")
        _check_finite_transform(target, "Target")
        return rig.TargetWriter(target, rig.ensure_bone_map(st, target, rig.TARGET))

    def _sources(self, st: Any) -> list:
        """Where each ego's settings are: scene.remogen for the first, its entry of the ego list for the others."""
        return [st] + [e.source for e in self.others]

    def _all_settings(self, st: Any) -> tuple:
        return tuple(_settings(src) for src in self._sources(st)) + (st.use_foot_lock, st.use_control)

    def _sync_settings(self, st: Any) -> None:
        """Pass slider, text and toggle changes to the egos before the next model frame.

        The runtime applies them from its next segment's diffusion (within 0.8 s of model time); FWSR
        still reacts to the partner every frame."""
        self._check_ego_list(st)
        now = self._all_settings(st)
        if now == self._applied:
            return
        for src, ego in zip(self._sources(st), self.group.egos):
            if src.text != ego.text:
                ego.text = src.text
            ego.alpha = _alpha(src)
            ego.guidance = _guidance(src)
            ego.fwsr = src.use_fwsr
            ego.cleanup = st.use_foot_lock
        self.group.control = st.use_control
        # a new seed only matters for a new run (live restarts, bake resets); the egos keep their own
        self._applied = now

    def _check_ego_list(self, st: Any) -> None:
        """The egos are fixed for a run: an entry added, removed or pointed elsewhere needs a new start."""
        try:
            same = [item.ego for item in st.egos] == [e.writer.object for e in self.others]
        except ReferenceError:
            same = False
        if not same:
            raise UserError("The ego list changed; start Live or the bake again to include the change")

    def _partner(self, scene: bpy.types.Scene, st: Any, depsgraph: bpy.types.Depsgraph) -> np.ndarray:
        try:
            partner = st.partner
        except ReferenceError:
            partner = None
        if partner is None or not _in_scene(scene, partner):
            # bpy.ops.object.delete only unlinks an object the panel still points at
            raise UserError(f"Partner '{self.reader.name}' was deleted or is no longer in the scene; "
                            "pick a partner and start again")
        if partner.name != self.reader.name or self.reader.object != partner:   # another partner picked
            self.reader = self._make_reader(scene, st)
        joints = self.reader.read(depsgraph)
        what = f"Partner '{self.reader.name}'"
        _check_position(joints, what)
        # Before the scene grid is built: a rig in centimetres would otherwise be blamed on the scene.
        span = float(np.ptp(joints, axis=0).max())
        if span > MAX_PARTNER_SPAN:
            raise UserError(f"{what} spans {span:.1f} m; it looks like centimetres: scale it by 0.01 "
                            "(or import it at scale 0.01)")
        return joints

    @staticmethod
    def _goal(st: Any, depsgraph: bpy.types.Depsgraph) -> np.ndarray | None:
        if st.goal is None:
            return None
        m = np.array(st.goal.evaluated_get(depsgraph).matrix_world, dtype=np.float64)
        _check_position(m[:3, 3], f"Goal '{st.goal.name}'")
        return m[:3, 3]

    # ------------------------------------------------------------------ stepping
    def step(self, scene: bpy.types.Scene, depsgraph: bpy.types.Depsgraph) -> Any:
        """Advance one model frame with the partner, goal and scene as they are now; the first ego's frame."""
        t0 = time.perf_counter()
        st = scene.remogen
        self._sync_settings(st)
        posed = [("Ego", self.writer), ("Target", self.target)] + [(e.label, e.writer) for e in self.others]
        for what, w in posed:
            if w is not None and not _in_scene(scene, w.object):
                raise UserError(f"{what} '{w.name}' was deleted or is no longer in the scene; "
                                f"pick {'a target' if what == 'Target' else 'or create an ego'} and start again")
        partner = self._partner(scene, st, depsgraph)
        goal = self._goal(st, depsgraph)
        if self.group.reads_scene_next:     # the only steps that read it: checking the meshes costs ~1 ms
            self.group.scene = self.scene_cache.grid(st.scene_collection, depsgraph)
        frames = self._model_step(partner, goal)
        frame = frames[0]
        self.frames.append(frame)
        self.other_frames.append(frames[1:])
        prev = self.contact_starts[-1] if self.contact_starts else (-1, -1)
        self.contact_starts.append(tuple((prev[s] if prev[s] >= 0 else frame.index) if frame.contacts[s] else -1
                                         for s in range(2)))
        self.first_index = frame.index - len(self.frames) + 1
        self.step_ms = (time.perf_counter() - t0) * 1e3
        return frame

    def _model_step(self, partner: np.ndarray, goal: np.ndarray | None) -> list:
        """One step of every ego (group.step()), stopping at the first non-finite output with its cause named."""
        index = self.latest_index + 1
        try:
            frames = self.group.step(partner=partner, goals=[goal] * len(self.group.egos))
        except _RT.RemogenError:
            # A non-finite pose inside the runtime can surface as a later input check (the scene
            # sample's ego transform): name the real cause when there is one.
            cause = _bad_weights(self.model)
            if cause is None:
                raise
            raise UserError(_nonfinite_message(index, cause)) from None
        for ego, frame in zip(self.group.egos, frames):
            if not all(np.isfinite(a).all() for a in (frame.joints, frame.root, frame.local_rotations)):
                cause = _bad_weights(self.model) or (f"with guidance {ego.guidance:g}; lower the guidance "
                                                     "or check the model file")
                raise UserError(_nonfinite_message(index, cause))
        return frames

    @property
    def latest_index(self) -> int:
        return self.frames[-1].index if self.frames else -1

    def pose_at(self, model_time: float, ego: int = 0) -> Pose:
        """The pose of one ego (0: the first) at one model time already generated (live and frame-change;
        see poses_at)."""
        p = self.poses_at(np.array([model_time]), ego)
        return Pose(p.pelvis[0], p.local_rotations[0], p.frame[0], p.planted[0], p.contact_start[0])

    def poses_at(self, model_times: np.ndarray, ego: int = 0) -> Pose:
        """Poses of one ego (0: the first) at model times already generated, clamped to the frames kept: pelvis
        (T, 3), local_rotations (T, 22, 4). Between two model frames the pelvis is blended linearly and the
        rotations by slerp; live, frame-change and bake all go through here, so a bake's keys are what live
        shows. A foot is planted between two model frames that both have it planted, and fades out between
        its last planted model frame and the next (the first ego's contacts: the ones the target follows)."""
        x = np.asarray(model_times, dtype=np.float64) / self.dt
        k0 = np.floor(x + _EPS).astype(np.int64)
        a = np.clip(x - k0, 0.0, 1.0)
        lo = np.clip(k0 - self.first_index, 0, len(self.frames) - 1)
        hi = np.clip(k0 + 1 - self.first_index, 0, len(self.frames) - 1)
        a = np.where((hi == lo) | (a <= _EPS), 0.0, a)
        need, where = np.unique(np.concatenate((lo, hi)), return_inverse=True)   # stack only these frames
        egos = [self.frames[i] if ego == 0 else self.other_frames[i][ego - 1] for i in need]
        pel = np.stack([f.root[:3, 3] for f in egos]).astype(np.float64)
        rot = np.stack([f.local_rotations for f in egos]).astype(np.float64)
        i0, i1 = where[:len(lo)], where[len(lo):]
        p = (1.0 - a)[:, None] * pel[i0] + a[:, None] * pel[i1]
        q = _RT.qslerp(rot[i0], rot[i1], a[:, None, None])
        con = np.stack([self.frames[i].contacts for i in need]).astype(np.float64)
        began = np.array([self.contact_starts[i] for i in need], dtype=np.int64)
        index = np.array([self.frames[i].index for i in need], dtype=np.int64)
        planted = con[i0] * (1.0 - a[:, None] * (1.0 - con[i1]))
        return Pose(p, q, index[i0], planted, began[i0])

    def last_needed(self, model_time: float) -> int:
        """The index of the last model frame needed to show `model_time` (the one at or just after it)."""
        return int(math.ceil(model_time / self.dt - _EPS))

    def update(self, scene: bpy.types.Scene, depsgraph: bpy.types.Depsgraph | None = None,
               model_time: float | None = None, write: bool = True) -> Pose:
        """THE per-frame function: generate the model frames up to the time shown, then pose the egos (and the
        target). Returns the first ego's pose.

        model_time None (live): follow the scene clock; a backward jump, or a forward jump of more than
        MAX_CATCH_UP seconds, continues from the ego's current pose instead of replaying or fast-forwarding.
        """
        t0 = time.perf_counter()
        depsgraph = depsgraph or bpy.context.evaluated_depsgraph_get()
        if model_time is None:
            model_time = scene_time(scene) - self.anchor
            latest_t = self.latest_index * self.dt
            if model_time < self.last_time - _EPS or model_time > latest_t + MAX_CATCH_UP:
                self.anchor = scene_time(scene) - (latest_t + self.dt)
                model_time = latest_t + self.dt
        need = self.last_needed(model_time)
        while self.latest_index < need:
            self.step(scene, depsgraph)
        pose = self.pose_at(model_time)
        if write:   # the bake keys all frames at the end instead
            self._write(pose, model_time)
        self.last_time = model_time
        self.update_ms = (time.perf_counter() - t0) * 1e3
        return pose

    def advance_wall(self, scene: bpy.types.Scene, seconds: float,
                     depsgraph: bpy.types.Depsgraph | None = None) -> Pose:
        """Live with the timeline standing still: the ego keeps living in wall-clock time."""
        self.anchor -= max(0.0, min(seconds, MAX_CATCH_UP))
        return self.update(scene, depsgraph)

    def show_latest(self) -> None:
        """Pose the egos again as the last update() did (after something else posed them)."""
        if self.frames:
            self._write(self.pose_at(self.last_time), self.last_time)

    def _write(self, pose: Pose, model_time: float) -> None:
        """Pose the first ego and the target from `pose`, and the other egos at `model_time`; every armature's
        channels are checked before any is written."""
        writes = []
        if self.writer is not None:
            loc, rot = self.writer.pose_channels(pose.pelvis, pose.local_rotations)
            writes.append(("Ego", self.writer, loc, rot))
        if self.target is not None:
            batch = Pose(pose.pelvis[None], pose.local_rotations[None], np.atleast_1d(pose.frame),
                         pose.planted[None], pose.contact_start[None])
            loc, rot = self.target_channels(batch)
            writes.append(("Target", self.target, loc[0], rot[0]))
        for k, e in enumerate(self.others, start=1):
            p = self.pose_at(model_time, k)
            writes.append((e.label, e.writer, *e.writer.pose_channels(p.pelvis, p.local_rotations)))
        for what, w, loc, rot in writes:
            self._check_channels(what, w.name, loc, rot)
        for _what, w, loc, rot in writes:
            w.write_channels(loc, rot)

    def _check_channels(self, what: str, name: str, loc: np.ndarray, rot: np.ndarray) -> None:
        if not (np.isfinite(loc).all() and np.isfinite(rot).all()):   # never a NaN on the rig
            raise UserError(f"{what} '{name}': its pose at model frame {self.latest_index} is not "
                            f"finite and was not written; check the {what.lower()}'s transform")

    def target_channels(self, poses: Pose) -> tuple[np.ndarray, np.ndarray]:
        """The target's channels for a batch of poses (rig/target.py), planted toes pinned when Plant Feet is on."""
        if not self.group.egos[0].cleanup:
            return self.target.pose_channels(poses.pelvis, poses.local_rotations)
        pinned = poses.planted >= 1.0
        fading = (poses.planted > 0.0) & ~pinned
        began = np.where(poses.planted > 0.0, poses.contact_start, -1)
        at = np.where(fading, poses.frame[:, None], -1)
        pins = np.where(pinned[..., None], self._free_toes(began), np.nan)
        shifts = np.where(fading[..., None], poses.planted[..., None] * (self._free_toes(began) - self._free_toes(at)),
                          np.nan)
        return self.target.pose_channels(poses.pelvis, poses.local_rotations, pins, shifts)

    def _free_toes(self, frames: np.ndarray) -> np.ndarray:
        """(T, 2, 3) the target's toes (left, right) in the world at model frames (T, 2) before any is pinned,
        NaN where the frame is -1; each model frame's are computed once."""
        keys = np.unique(frames[frames >= 0])
        new = [int(k) for k in keys if int(k) not in self._toes]
        if new:
            p = self.poses_at(np.array(new, dtype=np.float64) * self.dt)
            for k, toes in zip(new, self.target.toes(p.pelvis, p.local_rotations)):
                self._toes[k] = toes
        if len(keys) == 0:
            return np.full(frames.shape + (3,), np.nan)
        table = np.stack([self._toes[int(k)] for k in keys])               # (K, 2, 3)
        picked = table[np.searchsorted(keys, np.maximum(frames, keys[0])), np.arange(2)]
        return np.where((frames >= 0)[..., None], picked, np.nan)

    def restore_rest(self) -> None:
        for w in [self.writer] + [e.writer for e in self.others]:
            if w is not None:
                w.write_rest()


def _in_scene(scene: bpy.types.Scene, ob: bpy.types.Object) -> bool:
    try:
        return scene.objects.get(ob.name) == ob
    except ReferenceError:
        return False


def _check_in_scene(scene: bpy.types.Scene, ob: bpy.types.Object, what: str) -> None:
    if not _in_scene(scene, ob):
        raise UserError(f"{what} was deleted or is not in scene '{scene.name}'; pick one that is")


def _bad_weights(model: Any) -> str | None:
    """The cause when the model's weights are not all finite, else None."""
    import torch
    if all(torch.isfinite(t).all() for t in model.state_dict().values() if t.is_floating_point()):
        return None
    return ("the model file has NaN or infinite weights; pick another model file in the add-on preferences "
            "or train it again")


def _nonfinite_message(index: int, cause: str) -> str:
    return f"The model produced non-finite joints at model frame {index} ({cause}); nothing was written"


def _guidance(src: Any) -> float:
    """The guidance setting; a file saved before the limit existed may hold any value."""
    g = float(src.guidance)
    if not 0.0 <= g <= GUIDANCE_MAX:
        raise UserError(f"Guidance {g:g} is out of range: set it between 0 and {GUIDANCE_MAX:g}")
    return g


def _alpha(src: Any) -> dict[str, float]:
    return {"hhi": float(src.alpha_hhi), "hsi": float(src.alpha_hsi)}


def _check_position(p: np.ndarray, what: str) -> None:
    # Blender clamps inf to float32 max, which passes a finiteness check and overflows later: bound it too.
    if not np.isfinite(p).all() or np.abs(p).max() > _RT.MAX_COORD:
        raise UserError(f"{what} has a NaN, infinite or far-off position (beyond {_RT.MAX_COORD:g} m); "
                        "fix its transform or animation")


def _check_finite_transform(ob: bpy.types.Object, what: str) -> None:
    try:
        m = np.array(ob.matrix_world, dtype=np.float64)
    except ReferenceError:
        raise UserError(f"{what} was deleted") from None
    if not np.isfinite(m).all() or np.abs(m[:3, 3]).max() > _RT.MAX_COORD:
        raise UserError(f"{what} '{ob.name}' has a NaN or infinite transform; reset its location, rotation "
                        "and scale")
    if abs(np.linalg.det(m[:3, :3])) < 1e-12:
        raise UserError(f"{what} '{ob.name}' has a zero scale; give it a non-zero scale")
