"""One generated character: its settings, its rollout state and the per-ego parts of a step.

A ReactionGroup (group.py) holds one `Ego` per generated character and runs the networks for all of them
at once; everything here is the work that belongs to one ego alone: its canonical frames, the window of
the character it reacts to, its cost targets, and turning its generated features into an EgoFrame.
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import numpy as np
import torch

from .checks import Checked, check_alpha, check_guidance, check_point, check_seed, check_text
from .control import ControlConfig, ControlTargets, partner_future, passing_away
from .distance_field import DistanceField
from .errors import DEFAULT_GUIDANCE, MAX_COORD, InputError
from .features import (ROOT_T, ROT6D, canonical_frame, feature_joints, features_from_pose, self_consistent,
                       to_canonical, world_points_to_canonical)
from .footlock import FootLock
from .navigation import NAV_CELL, FloorMap, NavigationField
from .quat import matrix_to_quat_np
from .skeleton import (NUM_JOINTS, forward_kinematics_np, quat_to_matrix, rot6d_to_matrix_np,
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


@dataclass
class EgoSettings:
    """What one ego of a ReactionGroup does (checked when the group is built; alpha None = all modules 1)."""
    text: str = ""
    seed: int = 0
    alpha: dict | None = None
    guidance: float = DEFAULT_GUIDANCE
    fwsr: bool = True
    cleanup: bool = True


def frames_from_world_features(index: int, feat_world: torch.Tensor, feet: list[FootLock]) -> list[EgoFrame]:
    """The EgoFrames of one generated frame of each ego (feat_world (B, 276)); `feet[i]` marks ego i's planted
    feet and, when it locks, pins them. The skeleton maths runs once for all egos."""
    f = feat_world.numpy()
    rot = rot6d_to_matrix_np(f[:, ROT6D].reshape(-1, NUM_JOINTS, 6))
    pelvis = f[:, ROOT_T]
    joints, world = forward_kinematics_np(rot, pelvis, world_rotations=True)
    contacts = np.zeros((len(f), 2), bool)
    solved = []
    for i, lock in enumerate(feet):
        mine = rot[i]
        if np.isfinite(joints[i]).all():      # else reported as a model output problem by the caller
            cleaned, contacts[i] = lock.apply(mine, joints[i], world[i])
            if cleaned is not mine:           # a leg was solved: the joints follow the new rotations
                rot[i] = cleaned
                solved.append(i)
    if solved:                                # once for all of them
        joints[solved] = forward_kinematics_np(rot[solved], pelvis[solved])
    quats = matrix_to_quat_np(rot).astype(np.float32)
    out = []
    for i in range(len(f)):
        root = np.eye(4, dtype=np.float32)
        root[:3, :3], root[:3, 3] = rot[i, 0], pelvis[i]
        out.append(EgoFrame(index, joints[i].astype(np.float32), root, quats[i], contacts[i]))
    return out


def _frame_pose(frame: EgoFrame) -> tuple[torch.Tensor, torch.Tensor]:
    """(22, 3, 3) local rotations and (3,) pelvis of a frame a session starts from; InputError when malformed."""
    rot = quat_to_matrix(torch.as_tensor(np.asarray(frame.local_rotations, np.float32)))
    pelvis = torch.as_tensor(np.asarray(frame.root, np.float32)[:3, 3])
    if rot.shape != (NUM_JOINTS, 3, 3) or not torch.isfinite(rot).all() or not torch.isfinite(pelvis).all():
        raise InputError("reset frame must hold finite (22, 4) local_rotations and a (4, 4) root")
    return rot, pelvis


def _moving_history(frames: Sequence[EgoFrame], history: int) -> torch.Tensor:
    """The world history of a body continuing from its latest frames (10 fps, oldest first): its last `history`
    frames, the first one repeated in front when fewer are given. A history row also holds the step to the next
    frame; the last frame's step is its previous one again (the body keeps its pace and turn)."""
    frames = list(frames) if isinstance(frames, (list, tuple)) else []
    if not frames or not all(isinstance(f, EgoFrame) for f in frames):
        raise InputError("reset frames must be one EgoFrame or a sequence of EgoFrames (10 fps, oldest first)")
    poses = [_frame_pose(f) for f in frames[-history:]]
    poses = [poses[0]] * (history - len(poses)) + poses
    rot = torch.stack([r for r, _ in poses])
    pelvis = torch.stack([p for _, p in poses])
    # one frame past the last: the last step repeated (the root's turn and the pelvis's move; the pose held)
    turn = rot[-1, 0] @ rot[-2, 0].transpose(-1, -2) if history > 1 else torch.eye(3)
    ahead = rot[-1].clone()
    ahead[0] = turn @ rot[-1, 0]
    step = pelvis[-1] - pelvis[-2] if history > 1 else torch.zeros(3)
    return features_from_pose(torch.cat((rot, ahead[None])), torch.cat((pelvis, (pelvis[-1] + step)[None])))


def output_problem(feat_world: torch.Tensor, joints: np.ndarray, rotations: np.ndarray) -> str | None:
    """What is wrong with generated frames, one ego's or a step's stacked for all egos (non-finite or absurdly
    far joints), or None."""
    if not (bool(torch.isfinite(feat_world).all()) and np.isfinite(joints).all() and np.isfinite(rotations).all()):
        return "non-finite joints"
    if not (np.abs(joints) < MAX_COORD).all():
        return f"joints beyond {MAX_COORD:.0e} m"
    return None


def cue_windows(egos: Sequence["Ego"], rots: Sequence[torch.Tensor], transes: Sequence[torch.Tensor], n: int,
                hidden: Sequence[bool] | None = None) -> tuple[torch.Tensor, torch.Tensor]:
    """`Ego.cue_window` of several egos at once, each in its own frame: (B, n, 22, 3) points, (B, n) present.

    One array is filled and moved by one batched transform; per ego a handful of small torch calls cost more
    than the maths (the same numbers as ego by ego, to float rounding: tests/test_group.py)."""
    b = len(egos)
    hidden = [False] * b if hidden is None else hidden
    present = np.zeros((b, n), bool)
    pts = np.zeros((b, n, NUM_JOINTS, 3), np.float32)
    for i, (e, hide) in enumerate(zip(egos, hidden)):
        if hide:
            continue
        for k, p in enumerate(e.cue[-n:]):
            if p is not None:
                present[i, k] = True
                pts[i, k] = p
    mask = torch.from_numpy(present)
    if not present.any():
        return torch.from_numpy(pts), mask
    rot, trans = torch.stack(list(rots)).unsqueeze(1), torch.stack(list(transes)).unsqueeze(1)
    moved = world_points_to_canonical(torch.from_numpy(pts), rot, trans)
    return torch.where(mask[:, :, None, None], moved, 0.0), mask


def as_transform(rot: torch.Tensor, trans: torch.Tensor) -> np.ndarray:
    m = np.eye(4, dtype=np.float32)
    m[:3, :3] = rot.numpy()
    m[:3, 3] = trans.numpy()
    return m


NAV_LOOK_AHEAD = 1.5   # m: on the way around obstacles, face the point this far along the way (not the goal)
PASS_FRAMES = 4    # the latest frames whose motion tells whether, and how, the ego is passing someone


class Ego:
    """One ego: settings that may change between steps, and the state its rollout carries from step to step."""

    def __init__(self, model: Any, settings: EgoSettings) -> None:
        if not isinstance(settings, EgoSettings):
            raise InputError(f"each ego must be a model_runtime.EgoSettings, got {type(settings).__name__}")
        self.model, self.cfg = model, model.cfg
        self._feet = FootLock()
        self.seed = settings.seed
        self.text = settings.text
        self.alpha = settings.alpha
        self.guidance = settings.guidance
        self.fwsr = settings.fwsr
        self.cleanup = settings.cleanup
        self.reset(self.start_history())

    # ------------------------------------------------------------------ live settings
    seed = Checked(check_seed, "The noise seed; used from the next reset().")

    @property
    def text(self) -> str:
        return self._text

    @text.setter
    def text(self, value: str) -> None:
        self._text = check_text(value)
        self.text_emb = self.model.encode_text(value)
        self.text_warning = self.model.text_warning(value)   # one line when the encoder cannot read it, else None

    @property
    def alpha(self) -> dict[str, float]:
        return dict(self._alpha)

    @alpha.setter
    def alpha(self, value: dict | None) -> None:
        self._alpha = check_alpha(value)

    guidance = Checked(check_guidance)
    fwsr = Checked(bool)

    @property
    def cleanup(self) -> bool:
        """Planted-foot cleanup of the output (leg IK); contacts are reported either way. Next frame on."""
        return self._feet.locks

    @cleanup.setter
    def cleanup(self, value: bool) -> None:
        self._feet.locks = bool(value)

    # ------------------------------------------------------------------ reset
    def start_history(self, root_position: Sequence[float] = (0.0, 0.0, 0.0), yaw: float = 0.0,
                      frame: EgoFrame | Sequence[EgoFrame] | None = None, name: str = "root_position") -> torch.Tensor:
        """The world history of a body standing at rest on `root_position` facing `yaw`, holding `frame`, or
        moving on from `frame` given as its latest frames (a sequence at the model's 10 fps, oldest first; the last
        is where it is now): a walking body then keeps walking at its pace instead of setting off from a stand.

        Checks only, changes nothing: reset() applies it. yaw is in radians about +Z; yaw = 0 faces -Y.
        """
        h = self.cfg.history
        if frame is not None and not isinstance(frame, EgoFrame):
            return _moving_history(frame, h)
        if frame is not None:
            rot, pelvis = _frame_pose(frame)
        else:
            pos = check_point(name, root_position)
            if not math.isfinite(float(yaw)):
                raise InputError(f"yaw must be a finite angle in radians, got {yaw!r}")
            rot = torch.eye(3).repeat(NUM_JOINTS, 1, 1)
            rot[0] = yaw_matrix(torch.tensor(float(yaw)))
            pelvis = torch.as_tensor(pos) + torch.tensor([0.0, 0.0, standing_pelvis_height()])
        # H + 1 identical frames: a body standing still (zero deltas)
        return features_from_pose(rot.expand(h + 1, -1, -1, -1), pelvis.expand(h + 1, -1))

    def reset(self, hist_world: torch.Tensor) -> None:
        self.hist_world = hist_world
        w = self.cfg.partner_window
        self.cue: list = [None] * w          # the character this ego reacts to: its latest frames, oldest first
        self.cue_id: int = -1                # which one: -1 the partner, else the index of another ego
        self.passing: tuple[int, np.ndarray] | None = None   # (cue_id, world direction) while passing it
        self.goal: np.ndarray | None = None
        self._nav: tuple | None = None       # (floor map, goal xy, NavigationField) of the latest goal, see navigation()
        self.gen = torch.Generator().manual_seed(self._seed)
        self.seg: dict | None = None         # this ego's part of the running segment
        latest = feature_joints(hist_world[-1]).numpy().astype(np.float32)
        self.trail: deque = deque([latest] * w, maxlen=w)   # its own latest joints, for the other egos
        self._feet.reset()

    # ------------------------------------------------------------------ a step's state
    def snapshot(self) -> tuple:
        """What a step changes, to undo a failed one (tensors are replaced, never changed in place)."""
        seg = None if self.seg is None else dict(self.seg)
        return (list(self.cue), self.cue_id, self.passing, self.goal, self.gen.get_state(), seg, self._feet.state(),
                list(self.trail))

    def restore(self, snap: tuple) -> None:
        cue, self.cue_id, self.passing, self.goal, gen_state, self.seg, feet, trail = snap
        self.cue = cue
        self.gen.set_state(gen_state)
        self._feet.set_state(feet)
        self.trail.clear()
        self.trail.extend(trail)

    def commit(self, feat_world: torch.Tensor, frame: EgoFrame) -> None:
        """A step succeeded: its frame joins the history (and the trail the other egos see)."""
        self.hist_world = torch.cat((self.hist_world[1:], feat_world.unsqueeze(0)), 0)
        self.trail.append(frame.joints.copy())   # the frame is the caller's to change

    @property
    def feet(self) -> FootLock:
        return self._feet

    # ------------------------------------------------------------------ per-ego inputs of the networks
    def pelvis(self) -> np.ndarray:
        """The pelvis of the latest frame (world)."""
        return self.trail[-1][0]

    def canonical_history(self, hist_world: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(rot, trans, normalised (1, H, D) history) of a history in its own canonical frame, the generated frames
        made self-consistent first (features.self_consistent)."""
        hist_world = self_consistent(hist_world)
        rot, trans = canonical_frame(feature_joints(hist_world[0]))
        return rot, trans, self.model.stats.normalize(to_canonical(hist_world, rot, trans)).unsqueeze(0)

    def cue_window(self, rot: torch.Tensor, trans: torch.Tensor, n: int,
                   hidden: bool = False) -> tuple[torch.Tensor, torch.Tensor]:
        """The latest n frames of the character it reacts to, in a canonical frame, and which are present
        (none when hidden): (1, n, 22, 3), (1, n)."""
        return cue_windows([self], [rot], [trans], n, [hidden])

    def _paths(self, plans: tuple[torch.Tensor, torch.Tensor] | None = None) -> tuple[np.ndarray, np.ndarray] | None:
        """The latest pelvis positions (xy) of the ego and of the character it reacts to, oldest first; None
        while that one is not seen in each of them. With `plans` (both egos' world joints over the segment now
        starting), the last positions of those instead: where and how the two will walk when this job's
        segment starts."""
        if plans is not None:
            own, other = plans
            return own[-PASS_FRAMES:, 0, :2].double().numpy(), other[-PASS_FRAMES:, 0, :2].double().numpy()
        n = min(PASS_FRAMES, len(self.cue), len(self.trail))
        other = self.cue[-n:]
        if n < 2 or any(p is None for p in other):
            return None
        own = np.stack([j[0, :2] for j in list(self.trail)[-n:]]).astype(np.float64)
        return own, np.stack([j[0, :2] for j in other]).astype(np.float64)

    def pass_away(self, cc: ControlConfig, plans: tuple[torch.Tensor, torch.Tensor] | None = None) -> np.ndarray | None:
        """Which way to keep clear of the character it reacts to, if passing it (world xy); remembered per
        character so the side does not flip while passing. Only another ego is passed this way: two egos
        follow the same convention, so their choices fit together; the partner follows its own animation
        (the partner cost alone keeps the ego clear of it, as for a single ego)."""
        paths = self._paths(plans) if self.cue_id >= 0 else None
        before = self.passing[1] if self.passing is not None and self.passing[0] == self.cue_id else None
        away = None if paths is None else passing_away(*paths, before, cc)
        self.passing = None if away is None else (self.cue_id, away)
        return away

    def occupancy(self, scene: Any, rot: torch.Tensor, trans: torch.Tensor) -> torch.Tensor:
        occ = scene.sample_ego(as_transform(rot, trans), bounds=self.cfg.scene_bounds,
                               resolution=self.cfg.voxel_resolution)
        return torch.as_tensor(np.asarray(occ, np.float32)).unsqueeze(0)

    def canonical_goal(self, rot: torch.Tensor, trans: torch.Tensor) -> torch.Tensor | None:
        if self.goal is None:
            return None
        return world_points_to_canonical(torch.as_tensor(self.goal).view(1, 1, 3), rot, trans)[:, 0]

    def navigation(self, floor: FloorMap) -> NavigationField:
        """The walking-distance field to its goal on the scene's floor map, rebuilt only when the map changes or
        the goal moves by more than half a floor cell (a build takes a few ms; dragging a goal rebuilds it)."""
        goal = np.asarray(self.goal, np.float64)[:2]
        cached = self._nav
        if cached is None or cached[0] is not floor or np.hypot(*(cached[1] - goal)) > NAV_CELL / 2:
            cached = self._nav = (floor, goal, NavigationField(floor, goal))
        return cached[2]

    def control_targets(self, rot: torch.Tensor, trans: torch.Tensor, lead: int,
                        field: Callable[[], DistanceField] | None, cc: ControlConfig,
                        alpha: dict[str, float] | None = None,
                        floor: Callable[[], FloorMap] | None = None,
                        cue_plan: torch.Tensor | None = None,
                        own_plan: torch.Tensor | None = None) -> ControlTargets:
        """Test-time control of one job: its costs' targets in the job's canonical frame. `field` and `floor` give
        the scene's distance field and floor map (each built once per grid), None without a scene; `alpha` the
        alphas to steer with (default: the current ones)."""
        alpha = self._alpha if alpha is None else alpha
        targets = ControlTargets(alpha_hhi=alpha["hhi"], alpha_hsi=alpha["hsi"])
        if targets.alpha_hhi > 0.0:
            window, present = self.cue_window(rot, trans, self.cfg.partner_window)
            if cue_plan is not None and self.cue_id >= 0 and 0 < len(cue_plan) <= lead:
                # another ego's own plan for the frames before this job's segment (world joints): known, so
                # extrapolate from its end instead of from that ego's latest frame
                k = len(cue_plan)
                planned = world_points_to_canonical(cue_plan, rot, trans).unsqueeze(0)
                window = torch.cat((window[:, k:], planned), 1)
                present = torch.cat((present[:, k:], torch.ones(1, k, dtype=torch.bool)), 1)
                lead = lead - k
            targets.partner, targets.partner_still = partner_future(window[0], present[0], lead + 1,
                                                                    self.cfg.future + int(cc.look_ahead), cc)
            plans = (own_plan, cue_plan) if own_plan is not None and cue_plan is not None else None
            away = self.pass_away(cc, plans)
            if away is not None and targets.partner is not None:
                targets.pass_away = (rot[:2, :2].T @ torch.as_tensor(away, dtype=torch.float32))
        if targets.alpha_hsi > 0.0:
            if field is not None:
                targets.field, targets.to_world = field(), (rot, trans)
            if self.goal is not None:
                targets.goal_xy = world_points_to_canonical(torch.as_tensor(self.goal).view(1, 3), rot, trans)[0, :2]
                if floor is not None and floor().blocks:
                    targets.nav = nav = self.navigation(floor())
                    start = trans[:2].numpy()    # the canonical origin: the ego at the segment's start
                    ahead = nav.waypoint(start, NAV_LOOK_AHEAD)
                    targets.face_xy = world_points_to_canonical(
                        torch.tensor([ahead[0], ahead[1], 0.0], dtype=torch.float32).view(1, 3), rot, trans)[0, :2]
        return targets
