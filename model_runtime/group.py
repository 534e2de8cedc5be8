"""ReactionGroup: the online rollout of one or more egos, one 10 fps model frame per `step()`.

Scheduling (why no frame ever pays for a whole diffusion): while segment i plays, the reverse
diffusion of segment i+1 runs a step or two per frame, conditioned on segment i's *predicted* last
frames (its canonical frame and history) and the partner/scene seen when it started. At the boundary
the finished latent is decoded with the *real* history. A job's inputs (history, contexts, text,
alpha, guidance) are fixed when it starts, one segment ahead of the frames shown: a change is read by
the next job to start and shows in the segment it produces, 0.8 to 1.5 s of model time later (F = 8),
while FWSR reacts to the partner every frame and switching FWSR on or off acts on the next frame.
(A background thread for the diffusion was measured and rejected: with two Python threads issuing
small torch ops, GIL contention made the job finish later than spreading it, p99 38 ms vs 9 ms.)
With `pipeline=True` each job after the first runs instead in a helper process (job_worker.py) while
this one plays the segment's frames, and is collected at the segment's start: the same latent, so the
same motion, with only the frames' own work left on the caller's thread. When the helper is well ahead (the
job was back well before it was asked for, as in a viewport playing at real time), the next job's inputs are
fixed at the segment's start as always but it is built and sent at the following step, so the start of a
segment (seam steering, decoding) and the sending of a job do not add up in one step.
With FWSR on, every frame f >= 1 of a segment re-decodes a latent refined from the latest history and
partner frames (Algorithm 1), so reactions show up within a frame rather than at the next segment.
`slide=True` is the paper's ablation: a full diffusion every frame. Every frame is checked before it is
emitted: a non-finite pose raises ModelOutputError and leaves the group as it was before that step.

Several egos share the schedule and go through the networks as one batch: the denoiser (with its
classifier-free guidance pair), the context encoders, the VAE decoder, FWSR and the control's decoder
pass and its backward run once per frame for all of them. Each ego keeps its own text, alpha, guidance,
FWSR switch, foot cleanup and seeded generator, from which it draws its noise in the same order as it
would alone, so a group of one gives exactly the frames of a ReactionSession.

Each ego reacts to the nearest other character, by pelvis distance: the partner or another ego. That
character's latest frames are the cue of its HHI module, its FWSR and its control's partner cost. An
ego is seen by the others as of its latest emitted frame (egos step together, so one frame behind the
partner).
"""
from __future__ import annotations

import copy
from collections import deque
from typing import Any, Sequence

import numpy as np
import torch

from .checks import Checked, check_control_config, check_partner, check_point, check_scene
from .control import ControlConfig, LatentSteer, SegmentCosts
from .distance_field import DistanceField
from .navigation import FloorMap
from .ego import Ego, EgoFrame, EgoSettings, cue_windows, frames_from_world_features, output_problem
from .errors import InputError, ModelOutputError
from .features import feature_joints, to_world
from .job_spec import JobSpec, build_job
from .job_worker import JobWorker, RemoteJob, WorkerError, pipelinable, shared_worker
from .model import DiffusionJob, ReMoGenModel, job_draws, non_finite_weight
from .schedule import BOUNDARY_COST, STEERED_STEP_COST, steps_per_frame


# A job back at least this long before its segment started means the helper has time to spare (a viewport at real
# time: hundreds of ms): the next job may go out a step late. Stepping back to back (a bake) the helper is the
# slower side and a step's delay would hold up the whole chain of jobs.
AHEAD_SLACK = 0.02   # s


class ReactionGroup:
    """Online reaction generation for several egos stepped as one batch. See the module docstring."""

    def __init__(self, model: ReMoGenModel, egos: Sequence[EgoSettings], scene: Any = None, slide: bool = False,
                 control: bool = True, control_config: ControlConfig | None = None, pipeline: bool = False) -> None:
        if isinstance(egos, EgoSettings) or not isinstance(egos, Sequence) or len(egos) == 0:
            raise InputError("egos must be a non-empty list of model_runtime.EgoSettings, one per ego")
        self.model = model.eval()
        self.cfg = model.cfg
        self.egos: list[Ego] = [Ego(self.model, s) for s in egos]
        self.control = control
        self.control_config = control_config if control_config is not None else ControlConfig()
        self._maps: tuple[Any, dict] | None = None   # (grid, {kind: map of it}), each map built on first use
        self.slide = bool(slide)
        self.scene = scene
        self._worker: JobWorker | None = None
        self.pipeline = pipeline
        self._job: DiffusionJob | RemoteJob | None = None
        self.reset()

    # ------------------------------------------------------------------ settings shared by every ego
    control = Checked(bool, "Test-time control (control.py): steer each segment with cost gradients. From the next "
                            "segment on.")
    control_config = Checked(check_control_config)
    scene = Checked(check_scene)

    @property
    def pipeline(self) -> bool:
        """Run each segment's diffusion in a helper process while this one plays frames (job_worker.py): the
        same motion, less work per step on the caller's thread. Starts the shared helper (a second or two,
        meanwhile jobs run here); from the next segment on."""
        return self._pipeline

    @pipeline.setter
    def pipeline(self, value: bool) -> None:
        self._pipeline = bool(value)
        if self._pipeline and self._worker is None and pipelinable(self.model):
            self._worker = shared_worker()

    def helper_ready(self, timeout: float = 0.0) -> bool:
        """Whether pipelined jobs now run in the helper process, waiting up to `timeout` seconds for its start
        (False without pipelining, or when the helper cannot be used: jobs then run here)."""
        worker = self._worker
        if not self._pipeline or worker is None:
            return False
        worker.ready.wait(timeout)
        return worker.usable

    # ------------------------------------------------------------------ reset
    def reset(self, root_positions: Sequence | None = None, yaws: Sequence[float] | None = None,
              frames: Sequence[EgoFrame | Sequence[EgoFrame] | None] | None = None) -> None:
        """Start over: each ego standing at rest on its floor point facing its yaw, or from its frame, or moving on
        from its latest frames (a list of EgoFrames at 10 fps, oldest first: Ego.start_history).

        One entry per ego in each list given; defaults: the origin, yaw 0 (facing -Y). Bad input changes
        nothing.
        """
        n = len(self.egos)
        positions = self._per_ego("root_positions", root_positions, (0.0, 0.0, 0.0))
        angles = self._per_ego("yaws", yaws, 0.0)
        starts = self._per_ego("frames", frames, None)
        name = "root_position" if n == 1 else "root_positions[{}]"
        hists = [e.start_history(p, y, f, name.format(i))
                 for i, (e, p, y, f) in enumerate(zip(self.egos, positions, angles, starts))]
        for e, h in zip(self.egos, hists):
            e.reset(h)
        w = self.cfg.partner_window
        self._partner: deque = deque([None] * w, maxlen=w)
        self._seg: dict | None = None
        self._job = None
        self._pending: tuple | None = None    # a job whose inputs are fixed, to build at the next step
        self._index = 0

    def _per_ego(self, name: str, values: Sequence | None, default: Any) -> list:
        if values is None:
            return [default] * len(self.egos)
        if isinstance(values, (str, bytes)) or not hasattr(values, "__len__") or len(values) != len(self.egos):
            raise InputError(f"{name} must hold one entry per ego ({len(self.egos)}), or be None")
        return list(values)

    # ------------------------------------------------------------------ stepping
    @torch.no_grad()     # not inference_mode: test-time control takes gradients inside a step
    def step(self, partner: Any = None, goals: Sequence | None = None) -> list[EgoFrame]:
        """Advance every ego one model frame (0.1 s); returns their frames in ego order.

        partner: (22, 3) world joints or None; goals: one (x, y, z) or None per ego, or None for none.
        Raises InputError for bad inputs and ModelOutputError for a non-finite pose; either way the group is
        left exactly as before the call.
        """
        p = check_partner(partner)
        targets = [check_point("goal" if len(self.egos) == 1 else f"goals[{i}]", g)
                   for i, g in enumerate(self._per_ego("goals", goals, None))]
        before = self._snapshot()
        try:
            self._partner.append(p)
            cues = [self._nearest(i) for i in range(len(self.egos))]
            for e, g, (who, cue) in zip(self.egos, targets, cues):
                e.goal, e.cue_id, e.cue = g, who, cue
            feats = self._slide_frames() if self.slide else self._segment_frames()
            stacked = torch.stack(feats)
            with np.errstate(over="ignore", invalid="ignore"):   # a broken frame is reported just below
                out = frames_from_world_features(self._index, stacked, [e.feet for e in self.egos])
                # one check for all egos (the usual case), then ego by ego to name the one that failed
                if output_problem(stacked, np.stack([f.joints for f in out]),
                                  np.stack([f.local_rotations for f in out])):
                    for i, (feat, frame) in enumerate(zip(feats, out)):
                        problem = output_problem(feat, frame.joints, frame.local_rotations)
                        if problem:
                            raise ModelOutputError(self._output_error(i, problem))
        except BaseException:   # also KeyboardInterrupt: a half-done step must not stay behind
            self._restore(before)
            raise
        for e, feat, frame in zip(self.egos, feats, out):
            e.commit(feat, frame)
        self._index += 1
        return out

    def _nearest(self, i: int) -> tuple[int, list]:
        """Ego i's cue: (-1 for the partner or the index of an ego, its latest frames) of the nearest other
        character by pelvis distance (the partner's window, gaps included, when no one else is there)."""
        me = self.egos[i].pelvis()
        who, window, best = -1, list(self._partner), np.inf
        if self._partner[-1] is not None:
            best = float(np.linalg.norm(self._partner[-1][0] - me))
        for j, other in enumerate(self.egos):
            if j != i:
                d = float(np.linalg.norm(other.pelvis() - me))
                if d < best:
                    who, window, best = j, list(other.trail), d
        return who, window

    def _output_error(self, i: int, problem: str) -> str:
        who = f"ego {i}: " if len(self.egos) > 1 else ""
        where = f"{who}the model produced {problem} at frame {self._index}"
        bad = non_finite_weight(self.model.state_dict())
        if bad is not None:
            return f"{where}: its weight {bad} holds NaN or inf; load an intact model file"
        e = self.egos[i]
        return (f"{where} with guidance {e.guidance:g} and alpha {e.alpha}; lower the guidance or alpha, "
                "or reset the session")

    def _snapshot(self) -> tuple:
        seg = None if self._seg is None else dict(self._seg)
        job = None if self._job is None else (self._job, self._job.snapshot())
        return list(self._partner), seg, job, [e.snapshot() for e in self.egos], self._pending

    def _restore(self, snap: tuple) -> None:
        partner, self._seg, job, egos, self._pending = snap
        self._partner.clear()
        self._partner.extend(partner)
        for e, s in zip(self.egos, egos):
            e.restore(s)
        self._job = None
        if job is not None:
            self._job = job[0]
            self._job.restore(job[1])

    def _segment_frames(self) -> list[torch.Tensor]:
        seg, cfg = self._seg, self.cfg
        if self._pending is not None:
            self._build_pending()
        if seg is None or seg["f"] >= cfg.future:
            job = self._finish_job()
            seg = self._seg = self._start_segment(job)
            predicted = [p.clone() for p in self._to_world(seg["future"][:, -cfg.history:])]   # own storage each:
            # they go to the helper process, and a view would take the whole group's tensor along
            if isinstance(job, RemoteJob) and job.slack >= AHEAD_SLACK and cfg.future > 1:
                self._pending = self._fix_inputs(predicted, lead=cfg.future)
            else:
                self._job = self._new_job(predicted, lead=cfg.future, ahead=True)
        f = seg["f"]
        if f == 0:
            job = self._job
            if job is None:          # built at the next step, in the helper process: nothing to spread here
                seg["steps_at"] = (0,) * cfg.future
            else:
                seam = seg["seam_steers"]
                seg["steps_at"] = steps_per_frame(job.total_steps, cfg.future, job.steered_steps + job.final_steers,
                                                  BOUNDARY_COST + seam * STEERED_STEP_COST)
        feats_n = [seg["future"][i, f] for i in range(len(self.egos))]
        refined = [i for i, e in enumerate(self.egos) if e.fwsr] if f >= 1 else []
        if refined:
            for k, feat in zip(refined, self._refine(refined, f)):
                feats_n[k] = feat
        for e, feat in zip(self.egos, feats_n):
            e.seg["emitted"] = torch.cat((e.seg["emitted"], feat.unsqueeze(0)), 0)
        if self._job is not None:
            self._job.advance(seg["steps_at"][f])
        seg["f"] = f + 1
        return [w[0] for w in self._to_world(torch.stack(feats_n).unsqueeze(1))]

    def _to_world(self, feats_n: torch.Tensor) -> list[torch.Tensor]:
        """Normalised features (B, T, D), row i in ego i's canonical frame of the running segment -> each ego's
        world features (T, D), in one batched transform for the whole group (the same numbers as one by one)."""
        rot = torch.stack([e.seg["rot"] for e in self.egos])
        trans = torch.stack([e.seg["trans"] for e in self.egos])
        return list(to_world(self.model.stats.denormalize(feats_n), rot, trans).unbind(0))

    def _refine(self, rows: list[int], f: int) -> list[torch.Tensor]:
        """FWSR for frame f of the segment, for the egos in `rows`: their normalised canonical features."""
        seg, h = self._seg, self.cfg.history
        egos = [self.egos[i] for i in rows]
        # the latest H emitted frames, already canonical and normalised in this segment's frame
        recent = torch.stack([e.seg["emitted"][-h:] for e in egos])
        # alpha_HHI = 0 means "ignore the partner": FWSR's refiner reads partner frames too, so it sees
        # none (measured: with them it turned a prior-only ego toward the partner)
        partner, present = cue_windows(egos, [e.seg["rot"] for e in egos], [e.seg["trans"] for e in egos], h,
                                       hidden=[e.alpha["hhi"] == 0.0 for e in egos])
        every = len(rows) == len(self.egos)
        z0 = seg["z0"] if every else seg["z0"][rows]
        hist_n = seg["hist_n"] if every else seg["hist_n"][rows]
        z = self.model.refine(z0, recent, partner, present, f)
        decoded = self.model.decode(hist_n, z)
        return [decoded[k, f] for k in range(len(rows))]

    def _finish_job(self) -> DiffusionJob:
        """The finished diffusion for the segment about to start (all of it now after a reset)."""
        job = self._job if self._job is not None else self._new_job([e.hist_world for e in self.egos], lead=0)
        job.advance(job.total_steps)  # a no-op when the spread schedule already finished it
        self._job = None
        return job

    def _slide_frames(self) -> list[torch.Tensor]:
        job = self._new_job([e.hist_world for e in self.egos], lead=0)
        job.advance(job.total_steps)
        seg = self._start_segment(job)
        return [w[0] for w in self._to_world(seg["future"][:, :1])]

    def _start_segment(self, job: DiffusionJob) -> dict:
        """Decode a finished job's latents with each ego's real history in its own canonical frame. The
        segment's steering, here and while it plays, uses the alphas the job was made with."""
        z0 = job.result
        canon = [e.canonical_history(e.hist_world) for e in self.egos]
        hist_n = torch.cat([c[2] for c in canon])
        cc = self._control_config
        seam_steers = 0
        if self._control and max(cc.seam_steers, cc.partner_seam_steers) and self.cfg.history >= 2:
            # the latent was made for a predicted history: join it to the real one without a jump, still
            # under the same costs (its first frame plays now)
            forward = LatentSteer.decode_with_grad(self.model, hist_n, z0)   # also the first step's forward
            made = feature_joints(self.model.stats.denormalize(forward[1].detach()))
            steer = self._steer(hist_n, canon, lead=0, keep=made, step_size=cc.seam_step_size, alphas=job.alpha)
            # more steps where a partner cost acts on some ego: its module and cost pull the latent further from
            # a plain continuation of the history (one count for the group: the egos steer as one batch)
            seam_steers = cc.partner_seam_steers if steer.costs.partner.any else cc.seam_steers
            for k in range(seam_steers):
                z0 = steer(z0, forward if k == 0 else None)
            z0 = steer.settle(z0)
        for e, (rot, trans, h), alpha in zip(self.egos, canon, job.alpha):
            e.seg = {"rot": rot, "trans": trans, "emitted": h[0], "alpha": alpha}
        return {"hist_n": hist_n, "z0": z0, "future": self.model.decode(hist_n, z0), "f": 0,
                "seam_steers": seam_steers}

    def _fix_inputs(self, hist_worlds: list[torch.Tensor], lead: int) -> tuple:
        """Everything `_new_job` reads, as it is now, for `_build_pending` to build that very job at a later
        step: each ego as a shallow copy (its settings, cue, goal, passing state; its trail copied, as that one
        grows in place), the scene, the control settings and the egos' plans (known only at a segment's start).
        The noise is drawn at the build, from the egos' own generators, which nothing else draws from meanwhile."""
        views = []
        for e in self.egos:
            v = copy.copy(e)
            v.trail = deque(e.trail, maxlen=e.trail.maxlen)
            views.append(v)
        return hist_worlds, lead, views, self._scene, self._control, self._control_config, self._ego_plans(lead)

    def _build_pending(self) -> None:
        """Build and send the job whose inputs `_fix_inputs` fixed: the very job it would have been then."""
        hist_worlds, lead, views, scene, control, cc, plans = self._pending
        views = [copy.copy(v) for v in views]      # a failed step restores the pending job untouched
        live = self.egos, self._scene, self._control, self._control_config
        self.egos, self._scene, self._control, self._control_config = views, scene, control, cc
        try:
            job = self._new_job(hist_worlds, lead, ahead=True, plans=plans)
        finally:
            self.egos, self._scene, self._control, self._control_config = live
        for e, v in zip(self.egos, views):      # what building it changed on the egos
            e.passing, e._nav = v.passing, v._nav
        self._job, self._pending = job, None

    def _new_job(self, hist_worlds: list[torch.Tensor], lead: int, ahead: bool = False,
                 plans: list[torch.Tensor] | None = None) -> DiffusionJob | RemoteJob:
        """A diffusion job for the segments that start after `hist_worlds` (real or predicted, one per ego),
        whose first frame plays `lead` frames after the latest partner frame. A job for a segment `ahead`
        of the one playing runs in the helper process when pipelining, else here, spread over frames.
        `plans`: the egos' plans fixed earlier (`_fix_inputs`), else those of now."""
        canon = [e.canonical_history(h) for e, h in zip(self.egos, hist_worlds)]
        egos = self.egos
        spec = JobSpec(hist_n=torch.cat([c[2] for c in canon]), text_emb=torch.cat([e.text_emb for e in egos]),
                       **self._context_inputs(canon), alpha=[e.alpha for e in egos],
                       guidance=[e.guidance for e in egos], final_guidance_share=self.model.final_guidance_share,
                       final_guidance_min_speed=self.model.final_guidance_min_speed,
                       targets=self._targets(canon, lead, plans=plans) if self._control else None,
                       control=self._control_config if self._control else None,
                       noise=job_draws(self.model, [e.gen for e in egos], len(egos)))
        if ahead and self._pipeline and self._worker is not None and self._worker.usable:
            try:
                return RemoteJob(self._worker, self.model, spec)
            except WorkerError:
                pass          # gone meanwhile: this job, and the next ones, run here
        return build_job(self.model, spec)

    def _targets(self, canon: list[tuple], lead: int, alphas: list[dict] | None = None,
                 plans: list[torch.Tensor] | None = None) -> list:
        """Each ego's control targets in its canonical frame, with `alphas` (default: the egos' current ones) and
        `plans` (default: the egos' plans as of now, `_ego_plans`)."""
        cc = self._control_config
        field, floor = (self._distance_field, self._floor_map) if self._scene is not None else (None, None)
        alphas = alphas if alphas is not None else [None] * len(self.egos)
        plans = plans if plans is not None else self._ego_plans(lead)
        return [e.control_targets(rot, trans, lead, field, cc, a, floor,
                                  cue_plan=plans[e.cue_id] if plans is not None and e.cue_id >= 0 else None,
                                  own_plan=plans[i] if plans is not None else None)
                for i, (e, (rot, trans, _), a) in enumerate(zip(self.egos, canon, alphas))]

    def _ego_plans(self, lead: int) -> list[torch.Tensor] | None:
        """Each ego's world joints for the frames of the segment now starting, when a job is made for the segment
        after it (lead = F): what the others will see of it until that job's segment starts. None otherwise (and
        without control, the only reader)."""
        seg = self._seg
        if (not self._control or not self._control_config.ego_plans or len(self.egos) < 2 or seg is None
                or seg["f"] != 0 or lead != self.cfg.future):
            return None
        return [feature_joints(w) for w in self._to_world(seg["future"])]

    def _steer(self, hist_n: torch.Tensor, canon: list[tuple], lead: int, keep: torch.Tensor | None = None,
               step_size: float | None = None, alphas: list[dict] | None = None) -> LatentSteer:
        """Test-time control of a boundary (with `keep`): each ego's cost targets in its canonical frame."""
        cc = self._control_config
        targets = self._targets(canon, lead, alphas)
        return LatentSteer(self.model, hist_n, SegmentCosts(self.model.stats, hist_n, targets, cc, keep=keep), cc,
                           step_size=step_size)

    def _scene_map(self, kind: type):
        """The scene's map of one kind (DistanceField, FloorMap), built once per grid (a grid never changes once
        built)."""
        if self._maps is None or self._maps[0] is not self._scene:
            self._maps = (self._scene, {})
        maps = self._maps[1]
        if kind not in maps:
            maps[kind] = kind(self._scene)
        return maps[kind]

    def _distance_field(self) -> DistanceField:
        return self._scene_map(DistanceField)

    def _floor_map(self) -> FloorMap:
        return self._scene_map(FloorMap)

    def _context_inputs(self, canon: list[tuple]) -> dict:
        """What the context encoders read, per ego in its canonical frame (JobSpec fields)."""
        partner, present = cue_windows(self.egos, [c[0] for c in canon], [c[1] for c in canon], self.cfg.partner_window)
        occupancy = None
        if self._scene is not None:
            occupancy = torch.cat([e.occupancy(self._scene, rot, trans) for e, (rot, trans, _) in zip(self.egos, canon)])
        goals = [e.canonical_goal(rot, trans) for e, (rot, trans, _) in zip(self.egos, canon)]
        goal = has_goal = None
        if any(g is not None for g in goals):
            goal = torch.cat([g if g is not None else torch.zeros(1, 3) for g in goals])
            if any(g is None for g in goals):
                has_goal = torch.tensor([g is not None for g in goals])
        # The job encodes only the modules it uses: it keeps the alpha it starts with, so a slider moved
        # mid-segment takes effect from the next segment's diffusion (module docstring).
        return {"partner": partner, "present": present,
                "occupancy": occupancy, "goal": goal, "has_goal": has_goal}

    # ------------------------------------------------------------------ introspection
    @property
    def frame_index(self) -> int:
        return self._index

    @property
    def reads_scene_next(self) -> bool:
        """Whether the next step reads `scene`: only a step that starts a segment does (every step with slide),
        so a caller whose scene moves may refresh it for those steps alone."""
        return self.slide or self._seg is None or self._seg["f"] >= self.cfg.future
