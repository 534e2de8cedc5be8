"""ReactionSession: the online rollout, one 10 fps model frame per `step()`.

Scheduling (why no frame ever pays for a whole diffusion): while segment i plays, the reverse
diffusion of segment i+1 runs a step or two per frame, conditioned on segment i's *predicted* last
frames (its canonical frame and history) and the partner/scene seen when it started. At the boundary
the finished latent is decoded with the *real* history. A job's inputs (history, contexts, text,
alpha, guidance) are fixed when it starts, one segment ahead of the frames shown: a change is read by
the next job to start and shows in the segment it produces, 0.8 to 1.5 s of model time later (F = 8),
while FWSR reacts to the partner every frame and switching FWSR on or off acts on the next frame.
(A background thread for the diffusion was measured and rejected: with two Python threads issuing
small torch ops, GIL contention made the job finish later than spreading it, p99 38 ms vs 9 ms.)
With FWSR on, every frame f >= 1 of a segment re-decodes a latent refined from the latest history and
partner frames (Algorithm 1), so reactions show up within a frame rather than at the next segment.
`slide=True` is the paper's ablation: a full diffusion every frame. Everything draws noise from one
seeded generator in a fixed order, so the same seed and inputs give the same frames. Every frame is
checked before it is emitted: a non-finite pose raises ModelOutputError and leaves the session as it
was before that step.
"""
from __future__ import annotations

import math
from collections import deque
from functools import lru_cache
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np
import torch

from .control import ControlConfig, ControlTargets, LatentSteer, SegmentCosts, partner_future
from .distance_field import DistanceField
from .errors import MAX_COORD, MAX_GUIDANCE, InputError, ModelOutputError
from .features import (ROOT_T, ROT6D, canonical_frame, feature_joints, features_from_pose, to_canonical,
                       to_world, world_points_to_canonical)
from .footlock import FootLock
from .model import MODULE_NAMES, Contexts, DiffusionJob, ReMoGenModel, non_finite_weight
from .quat import matrix_to_quat_np
from .skeleton import (JOINT_NAMES, NUM_JOINTS, forward_kinematics_np, quat_to_matrix, rot6d_to_matrix_np,
                       standing_pelvis_height, yaw_matrix)


@dataclass
class EgoFrame:
    """One generated frame in world space (Z-up metres)."""
    index: int
    joints: np.ndarray           # (22, 3) float32
    root: np.ndarray             # (4, 4) float32 pelvis transform (global orientation + position)
    local_rotations: np.ndarray  # (22, 4) float32 quaternions w-first; [0] = global orientation
    contacts: np.ndarray = field(default_factory=lambda: np.zeros(2, bool))  # (left, right) foot planted

    @property
    def position(self) -> np.ndarray:
        return self.root[:3, 3]


def _frame_from_world_features(index: int, feat_world: torch.Tensor, feet: FootLock) -> EgoFrame:
    """The EgoFrame of one generated frame; `feet` marks planted feet and, when it locks, pins them."""
    f = feat_world.numpy()
    rot = rot6d_to_matrix_np(f[ROT6D].reshape(NUM_JOINTS, 6))
    pelvis = f[ROOT_T]
    joints, world = forward_kinematics_np(rot, pelvis, world_rotations=True)
    if np.isfinite(joints).all():
        cleaned, contacts = feet.apply(rot, joints, world)
        if cleaned is not rot:                  # a leg was solved: the joints follow the new rotations
            rot = cleaned
            joints = forward_kinematics_np(rot, pelvis)
    else:
        contacts = np.zeros(2, bool)    # reported as a model output problem by the caller
    root = np.eye(4, dtype=np.float32)
    root[:3, :3], root[:3, 3] = rot[0], pelvis
    return EgoFrame(index, joints.astype(np.float32), root, matrix_to_quat_np(rot).astype(np.float32), contacts)


def _as_transform(rot: torch.Tensor, trans: torch.Tensor) -> np.ndarray:
    m = np.eye(4, dtype=np.float32)
    m[:3, :3] = rot.numpy()
    m[:3, 3] = trans.numpy()
    return m




def _check_partner(partner: Any) -> np.ndarray | None:
    if partner is None:
        return None
    try:
        p = np.asarray(partner, dtype=np.float32)
    except (TypeError, ValueError):
        raise InputError("partner must be a (22, 3) array of world joint positions or None") from None
    if p.shape != (NUM_JOINTS, 3):
        raise InputError(f"partner joints must have shape (22, 3) (SMPL-X joint order, metres), got {p.shape}")
    # Blender stores inf as float32 max, so "finite" alone is not enough: bound the magnitude too
    bad = ~(np.isfinite(p) & (np.abs(p) < MAX_COORD)).all(axis=1)
    if bad.any():
        names = ", ".join(JOINT_NAMES[i] for i in np.flatnonzero(bad)[:4])
        raise InputError(f"partner joints contain NaN, inf or values beyond {MAX_COORD:.0e} m ({names}); "
                         "fix the partner's transforms or pass None")
    extent = float(np.ptp(p, axis=0).max())
    if extent > 5.0:
        raise InputError(f"partner skeleton spans {extent:.1f} m; it looks like centimetres: scale it by 0.01")
    return p


def _check_point(name: str, v: Any) -> np.ndarray | None:
    if v is None:
        return None
    try:
        p = np.asarray(v, dtype=np.float32).reshape(-1)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be an (x, y, z) point in metres or None") from None
    if p.shape != (3,):
        shape = np.shape(v)
        raise InputError(f"{name} must be one (x, y, z) point in metres or None, got {p.size} values (shape {shape}); "
                         "pass a single point")
    if not (np.isfinite(p) & (np.abs(p) < MAX_COORD)).all():
        raise InputError(f"{name} must be a finite (x, y, z) point within {MAX_COORD:.0e} m, or None; "
                         f"got ({', '.join(f'{x:g}' for x in p)})")
    return p


def _check_seed(seed: Any) -> int:
    # bool is an int in Python but never a meant seed; floats would be truncated silently
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= int(seed) < 2 ** 64:
        raise InputError(f"seed must be an integer in 0..2**64-1, got {seed!r}; pass e.g. seed=0")
    return int(seed)


def _check_alpha(alpha: Any) -> dict[str, float]:
    if alpha is None:
        return {k: 1.0 for k in MODULE_NAMES}
    if not isinstance(alpha, dict):
        raise InputError("alpha must be a dict like {'hhi': 1.0, 'hsi': 0.5}")
    unknown = sorted(map(repr, set(alpha) - set(MODULE_NAMES)))
    if unknown:
        raise InputError(f"unknown alpha key(s) {', '.join(unknown)}; use {list(MODULE_NAMES)}")
    out = {}
    for k in MODULE_NAMES:
        v = alpha.get(k, 0.0)
        if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) or not (
                math.isfinite(v) and v >= 0):
            raise InputError(f"alpha[{k!r}] must be a finite number >= 0, got {v!r}; e.g. {{'{k}': 1.0}}")
        out[k] = float(v)
    return out


def _output_problem(feat_world: torch.Tensor, frame: EgoFrame) -> str | None:
    """What is wrong with a generated frame (non-finite or absurdly far joints), or None."""
    if not (bool(torch.isfinite(feat_world).all()) and np.isfinite(frame.joints).all()
            and np.isfinite(frame.local_rotations).all()):
        return "non-finite joints"
    if not (np.abs(frame.joints) < MAX_COORD).all():
        return f"joints beyond {MAX_COORD:.0e} m"
    return None


# Cost of one denoising step in units of a plain step: a steered step adds a decoder forward and backward.
STEERED_STEP_COST = 2.5
# The boundary frame (f = 0) also decodes a segment and encodes contexts: about this many plain steps.
BOUNDARY_COST = 1.0


@lru_cache(maxsize=64)
def steps_per_frame(steps: int, frames: int, steered: int, boundary: float = BOUNDARY_COST) -> tuple[int, ...]:
    """Denoising steps per frame of a segment, spreading the job's cost evenly over its frames.

    Steps run in order and the last `steered` of them cost STEERED_STEP_COST each; frame 0 starts with
    `boundary` already spent (its decode, contexts and seam steering). The split minimises the sum of squared frame costs (so both the typical and
    the worst frame stay low), by dynamic programming over (steps done, frame). Sums to `steps`.
    """
    if steps * steps * frames > 2_000_000:     # research configs with very many steps: an even split
        base, extra = divmod(steps, frames)
        return tuple(base + (1 if i >= frames - extra else 0) for i in range(frames))
    cost = [STEERED_STEP_COST if t < steered else 1.0 for t in range(steps - 1, -1, -1)]
    prefix = [0.0]
    for c in cost:
        prefix.append(prefix[-1] + c)
    inf = float("inf")
    # best[f][i]: least sum of squares with the first i steps done by the end of frame f
    best = [[inf] * (steps + 1) for _ in range(frames)]
    choice = [[0] * (steps + 1) for _ in range(frames)]
    for i in range(steps + 1):
        best[0][i] = (boundary + prefix[i]) ** 2
    for f in range(1, frames):
        for i in range(steps + 1):
            for j in range(i + 1):
                v = best[f - 1][j] + (prefix[i] - prefix[j]) ** 2
                if v < best[f][i] - 1e-12:
                    best[f][i], choice[f][i] = v, j
    out, i = [0] * frames, steps
    for f in range(frames - 1, 0, -1):
        j = choice[f][i]
        out[f], i = i - j, j
    out[0] = i
    return tuple(out)


class ReactionSession:
    """Online reaction generation. See module docstring for the scheduling."""

    def __init__(self, model: ReMoGenModel, text: str = "", seed: int = 0, alpha: dict | None = None,
                 guidance: float = 5.0, fwsr: bool = True, scene: Any = None, slide: bool = False,
                 cleanup: bool = True, control: bool = True, control_config: ControlConfig | None = None) -> None:
        self.model = model.eval()
        self.cfg = model.cfg
        self._feet = FootLock()
        self.cleanup = cleanup
        self.control = control
        self.control_config = control_config if control_config is not None else ControlConfig()
        self._field: tuple[Any, DistanceField] | None = None   # (grid, its distance field), built on first use
        self.seed = seed
        self.slide = bool(slide)
        self._job: DiffusionJob | None = None
        self.text = text
        self.alpha = alpha
        self.guidance = guidance
        self.fwsr = fwsr
        self.scene = scene
        self.reset()

    # ------------------------------------------------------------------ live settings
    @property
    def seed(self) -> int:
        """The noise seed; used from the next reset()."""
        return self._seed

    @seed.setter
    def seed(self, value: int) -> None:
        self._seed = _check_seed(value)

    @property
    def text(self) -> str:
        return self._text

    @text.setter
    def text(self, value: str) -> None:
        if not isinstance(value, str):
            raise InputError(f"text must be a string, got {type(value).__name__}")
        self._text = value
        self._text_emb = self.model.encode_text(value)
        self._text_warning = self.model.text_warning(value)

    @property
    def text_warning(self) -> str | None:
        """One line when the text encoder cannot read the current text (another script, only emoji or symbols),
        else None."""
        return self._text_warning

    @property
    def alpha(self) -> dict[str, float]:
        return dict(self._alpha)

    @alpha.setter
    def alpha(self, value: dict | None) -> None:
        self._alpha = _check_alpha(value)

    @property
    def guidance(self) -> float:
        return self._guidance

    @guidance.setter
    def guidance(self, value: float) -> None:
        ok = not isinstance(value, bool) and isinstance(value, (int, float, np.integer, np.floating))
        if not ok or not 0.0 <= float(value) <= MAX_GUIDANCE:
            raise InputError(f"guidance must be a number in 0..{MAX_GUIDANCE:g} (default 5), got {value!r}")
        self._guidance = float(value)

    @property
    def cleanup(self) -> bool:
        """Planted-foot cleanup of the output (leg IK); contacts are reported either way. Next frame on."""
        return self._feet.locks

    @cleanup.setter
    def cleanup(self, value: bool) -> None:
        self._feet.locks = bool(value)

    @property
    def control(self) -> bool:
        """Test-time control (control.py): steer each segment with cost gradients. From the next segment on."""
        return self._control

    @control.setter
    def control(self, value: bool) -> None:
        self._control = bool(value)

    @property
    def control_config(self) -> ControlConfig:
        return self._control_config

    @control_config.setter
    def control_config(self, value: ControlConfig) -> None:
        if not isinstance(value, ControlConfig):
            raise InputError("control_config must be a model_runtime.ControlConfig")
        self._control_config = value

    @property
    def fwsr(self) -> bool:
        return self._fwsr

    @fwsr.setter
    def fwsr(self, value: bool) -> None:
        self._fwsr = bool(value)

    @property
    def scene(self) -> Any:
        return self._scene

    @scene.setter
    def scene(self, value: Any) -> None:
        if value is not None and not hasattr(value, "sample_ego"):
            raise InputError("scene must be an OccupancyGrid (model_runtime.OccupancyGrid) or None")
        self._scene = value

    # ------------------------------------------------------------------ reset
    def reset(self, root_position: Sequence[float] = (0.0, 0.0, 0.0), yaw: float = 0.0,
              frame: EgoFrame | None = None) -> None:
        """Start over standing at rest on the floor point `root_position` facing `yaw`, or from a frame.

        yaw is in radians about +Z; yaw = 0 faces -Y (the SMPL-X rest facing, Blender's front view).
        """
        h = self.cfg.history
        if frame is not None:
            rot = quat_to_matrix(torch.as_tensor(np.asarray(frame.local_rotations, np.float32)))
            pelvis = torch.as_tensor(np.asarray(frame.root, np.float32)[:3, 3])
            if rot.shape != (NUM_JOINTS, 3, 3) or not torch.isfinite(rot).all() or not torch.isfinite(pelvis).all():
                raise InputError("reset frame must hold finite (22, 4) local_rotations and a (4, 4) root")
        else:
            pos = _check_point("root_position", root_position)
            if not math.isfinite(float(yaw)):
                raise InputError(f"yaw must be a finite angle in radians, got {yaw!r}")
            rot = torch.eye(3).repeat(NUM_JOINTS, 1, 1)
            rot[0] = yaw_matrix(torch.tensor(float(yaw)))
            pelvis = torch.as_tensor(pos) + torch.tensor([0.0, 0.0, standing_pelvis_height()])
        # H + 1 identical frames: a body standing still (zero deltas)
        self._hist_world = features_from_pose(rot.expand(h + 1, -1, -1, -1), pelvis.expand(h + 1, -1))
        self._partner: deque = deque([None] * self.cfg.partner_window, maxlen=self.cfg.partner_window)
        self._goal: np.ndarray | None = None
        self._gen = torch.Generator().manual_seed(self._seed)
        self._seg: dict | None = None
        self._job = None
        self._index = 0
        self._feet.reset()

    # ------------------------------------------------------------------ stepping
    @torch.no_grad()     # not inference_mode: test-time control takes gradients inside a step
    def step(self, partner: Any = None, goal: Any = None) -> EgoFrame:
        """Advance one model frame (0.1 s). partner: (22, 3) world joints or None; goal: (x, y, z) or None.

        Raises InputError for bad inputs and ModelOutputError for a non-finite pose; either way the
        session is left exactly as before the call.
        """
        p = _check_partner(partner)
        g = _check_point("goal", goal)
        before = self._snapshot()
        try:
            self._partner.append(p)
            self._goal = g
            feat_world = self._slide_frame() if self.slide else self._segment_frame()
            with np.errstate(over="ignore", invalid="ignore"):   # a broken frame is reported just below
                out = _frame_from_world_features(self._index, feat_world, self._feet)
            problem = _output_problem(feat_world, out)
            if problem:
                raise ModelOutputError(self._output_error(problem))
        except BaseException:   # also KeyboardInterrupt: a half-done step must not stay behind
            self._restore(before)
            raise
        self._hist_world = torch.cat((self._hist_world[1:], feat_world.unsqueeze(0)), 0)
        self._index += 1
        return out

    def _output_error(self, problem: str) -> str:
        where = f"the model produced {problem} at frame {self._index}"
        bad = non_finite_weight(self.model.state_dict())
        if bad is not None:
            return f"{where}: its weight {bad} holds NaN or inf; load an intact model file"
        return (f"{where} with guidance {self._guidance:g} and alpha {self._alpha}; lower the guidance or alpha, "
                "or reset the session")

    def _snapshot(self) -> tuple:
        """What a step changes, to undo a failed one (tensors are replaced, never changed in place)."""
        seg = None if self._seg is None else dict(self._seg)
        job = None if self._job is None else (self._job, self._job.snapshot())
        return (list(self._partner), self._goal, self._gen.get_state(), seg, job, self._feet.state())

    def _restore(self, snap: tuple) -> None:
        partner, self._goal, gen_state, self._seg, job, feet = snap
        self._feet.set_state(feet)
        self._partner.clear()
        self._partner.extend(partner)
        self._gen.set_state(gen_state)
        self._job = None
        if job is not None:
            self._job = job[0]
            self._job.restore(job[1])

    def _segment_frame(self) -> torch.Tensor:
        seg = self._seg
        if seg is None or seg["f"] >= self.cfg.future:
            job = self._finish_job()
            seg = self._seg = self._start_segment(job.result)
            predicted = to_world(self.model.stats.denormalize(seg["future"][0, -self.cfg.history:]),
                                 seg["rot"], seg["trans"])
            self._job = self._new_job(predicted, lead=self.cfg.future)
        f = seg["f"]
        if f == 0:
            job = self._job
            seam = self._control_config.seam_steers if self._control else 0
            seg["steps_at"] = steps_per_frame(job.total_steps, self.cfg.future, job.steered_steps + job.final_steers,
                                              BOUNDARY_COST + seam * STEERED_STEP_COST)
        if self._fwsr and f >= 1:
            # the latest H emitted frames, already canonical and normalised in this segment's frame
            recent = seg["emitted"][-self.cfg.history:].unsqueeze(0)
            # alpha_HHI = 0 means "ignore the partner": FWSR's refiner reads partner frames too, so it sees
            # none (measured: with them it turned a prior-only ego toward the partner)
            partner, present = self._partner_window(seg["rot"], seg["trans"], self.cfg.history,
                                                    hidden=self._alpha["hhi"] == 0.0)
            z = self.model.refine(seg["z0"], recent, partner, present, f)
            feat_n = self.model.decode(seg["hist_n"], z)[0, f]
        else:
            feat_n = seg["future"][0, f]
        seg["emitted"] = torch.cat((seg["emitted"], feat_n.unsqueeze(0)), 0)
        self._job.advance(seg["steps_at"][f])
        seg["f"] = f + 1
        return to_world(self.model.stats.denormalize(feat_n).unsqueeze(0), seg["rot"], seg["trans"])[0]

    def _finish_job(self) -> DiffusionJob:
        """The finished diffusion for the segment about to start (all of it now after a reset)."""
        job = self._job if self._job is not None else self._new_job(self._hist_world, lead=0)
        job.advance(job.total_steps)  # a no-op when the spread schedule already finished it
        self._job = None
        return job

    def _slide_frame(self) -> torch.Tensor:
        job = self._new_job(self._hist_world, lead=0)
        job.advance(job.total_steps)
        seg = self._start_segment(job.result)
        return to_world(self.model.stats.denormalize(seg["future"][0, :1]), seg["rot"], seg["trans"])[0]

    def _start_segment(self, z0: torch.Tensor) -> dict:
        """Decode a finished latent with the real history in its own canonical frame."""
        rot, trans = canonical_frame(feature_joints(self._hist_world[0]))
        hist_n = self.model.stats.normalize(to_canonical(self._hist_world, rot, trans)).unsqueeze(0)
        cc = self._control_config
        if self._control and cc.seam_steers and self.cfg.history >= 2:
            # the latent was made for a predicted history: join it to the real one without a jump, still
            # under the same costs (its first frame plays now)
            made = feature_joints(self.model.stats.denormalize(self.model.decode(hist_n, z0)[0]))
            steer = self._steer(hist_n, rot, trans, lead=0, keep=made, step_size=cc.seam_step_size)
            for _ in range(cc.seam_steers):
                z0 = steer(z0)
        return {"rot": rot, "trans": trans, "hist_n": hist_n, "z0": z0,
                "future": self.model.decode(hist_n, z0), "f": 0, "emitted": hist_n[0]}

    def _new_job(self, hist_world: torch.Tensor, lead: int) -> DiffusionJob:
        """A diffusion job for the segment that starts after `hist_world` (real or predicted), whose first
        frame plays `lead` frames after the latest partner frame."""
        rot, trans = canonical_frame(feature_joints(hist_world[0]))
        hist_n = self.model.stats.normalize(to_canonical(hist_world, rot, trans)).unsqueeze(0)
        contexts = self._encode_contexts(rot, trans)
        steer = self._steer(hist_n, rot, trans, lead) if self._control else None
        cc = self._control_config
        return DiffusionJob(self.model, hist_n, self._text_emb, contexts, self._alpha, self._guidance, self._gen,
                            steer=steer, steered_steps=cc.steered_steps, final_steers=cc.final_steers)

    def _steer(self, hist_n: torch.Tensor, rot: torch.Tensor, trans: torch.Tensor, lead: int,
               keep: torch.Tensor | None = None, step_size: float | None = None) -> LatentSteer:
        """Test-time control of one job: its costs' targets in the job's canonical frame."""
        cc = self._control_config
        targets = ControlTargets(alpha_hhi=self._alpha["hhi"], alpha_hsi=self._alpha["hsi"])
        if targets.alpha_hhi > 0.0:
            window, present = self._partner_window(rot, trans, self.cfg.partner_window)
            targets.partner, targets.partner_still = partner_future(window[0], present[0], lead + 1,
                                                                    self.cfg.future + int(cc.look_ahead), cc)
        if targets.alpha_hsi > 0.0:
            if self._scene is not None:
                targets.field, targets.to_world = self._distance_field(), (rot, trans)
            if self._goal is not None:
                targets.goal_xy = world_points_to_canonical(torch.as_tensor(self._goal).view(1, 3), rot, trans)[0, :2]
        return LatentSteer(self.model, hist_n, SegmentCosts(self.model.stats, hist_n, targets, cc, keep=keep), cc,
                           step_size=step_size)

    def _distance_field(self) -> DistanceField:
        """The scene's distance field, built once per grid (a grid never changes once built)."""
        if self._field is None or self._field[0] is not self._scene:
            self._field = (self._scene, DistanceField(self._scene))
        return self._field[1]

    def _encode_contexts(self, rot: torch.Tensor, trans: torch.Tensor) -> Contexts:
        partner, present = self._partner_window(rot, trans, self.cfg.partner_window)
        occupancy = goal = None
        if self._scene is not None:
            occ = self._scene.sample_ego(_as_transform(rot, trans), bounds=self.cfg.scene_bounds,
                                         resolution=self.cfg.voxel_resolution)
            occupancy = torch.as_tensor(np.asarray(occ, np.float32)).unsqueeze(0)
        if self._goal is not None:
            goal = world_points_to_canonical(torch.as_tensor(self._goal).view(1, 1, 3), rot, trans)[:, 0]
        # Only the modules this job uses: a job keeps the alpha it starts with, so a slider moved
        # mid-segment takes effect from the next segment's diffusion (module docstring).
        return self.model.encode_contexts(partner, present, occupancy, goal, self._alpha)

    def _partner_window(self, rot: torch.Tensor, trans: torch.Tensor, n: int,
                        hidden: bool = False) -> tuple[torch.Tensor, torch.Tensor]:
        """The latest n partner frames in a canonical frame, and which are present (none when hidden)."""
        frames = list(self._partner)[-n:]
        if hidden:
            frames = [None] * len(frames)
        present = torch.tensor([p is not None for p in frames]).unsqueeze(0)
        pts = torch.zeros(1, n, NUM_JOINTS, 3)
        for i, p in enumerate(frames):
            if p is not None:
                pts[0, i] = world_points_to_canonical(torch.from_numpy(p), rot, trans)
        return pts, present

    # ------------------------------------------------------------------ introspection
    @property
    def frame_index(self) -> int:
        return self._index

    def history_world_features(self) -> torch.Tensor:
        """(H, 276) the latest emitted frames as world-frame features (for tools and tests)."""
        return self._hist_world.clone()
