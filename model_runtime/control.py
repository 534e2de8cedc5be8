"""Test-time control: steer a segment's latent while it is denoised, with gradients of costs on its motion.

DART steers a latent motion prior by optimisation over many iterations; here the budget is a few
milliseconds a frame, so the last `steered_steps` denoising steps of a segment each move their predicted
clean latent x0 one step down the gradient of differentiable costs on the segment it decodes to (one
decoder forward and backward per steered step), and the diffusion carries on from the steered x0.

The costs, on the decoded segment in the job's canonical frame (metres):
- partner: ego joints closer than `partner_margin` to the partner's joints, the partner moved on at its
  recent velocity to the times the segment plays; and turning to face a partner who stands close by;
- scene: ego joints closer than `scene_margin` to an obstacle, from a distance field built once per grid;
- goal: progress toward the goal at a walking pace and facing it while far, coming to rest on it when near;
- feet: toe sliding while near the floor, and joints below the floor.
alpha_HHI scales the partner cost and alpha_HSI the scene and goal costs, so the sliders keep their
meaning and alpha 0 ignores the partner or the scene; the foot and floor costs belong to the motion itself
and apply at any alpha. Nothing here draws random numbers: the same seed still gives the same frames.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from .distance_field import DistanceField
from .features import ROOT_T, feature_joints
from .joints import JOINT_INDEX, LEFT_HIP, RIGHT_HIP, SOLE_BELOW_FOOT_JOINT

FPS = 10.0
TOES = (JOINT_INDEX["left_foot"], JOINT_INDEX["right_foot"])


@dataclass(frozen=True)
class ControlConfig:
    """Cost weights and step sizes of test-time control (chosen on the behaviour suite's val split)."""
    steered_steps: int = 4          # the last N denoising steps are steered (one gradient step each)
    final_steers: int = 8           # then this many gradient steps on the denoised latent
    step_size: float = 3.0          # latent units per steered step at full gradient
    max_gradient: float = 1.0       # gradient norms above this are scaled down to it (bounded step length)
    negligible_cost: float = 1e-4   # a segment costing less is left as it is
    partner_margin: float = 0.5     # m: joint-to-joint distance the partner cost keeps
    partner_weight: float = 200.0
    face_weight: float = 10.0       # turning toward a partner standing within face_radius
    face_radius: float = 2.5        # m
    look_ahead: int = 8             # partner frames past a segment's end its last pose must keep clear of
    still_speed: float = 0.3        # m/s: a partner slower than this counts as standing
    max_partner_speed: float = 2.5  # m/s: the extrapolation never moves a partner faster than this
    scene_margin: float = 0.12      # m: joint clearance the scene cost keeps from obstacles
    scene_weight: float = 40.0
    goal_weight: float = 2.0
    pace: float = 1.2               # m/s: the progress a segment is asked to make toward a far goal
    goal_face_weight: float = 10.0  # facing the goal while further than goal_face_distance
    goal_face_distance: float = 1.0  # m
    rest_radius: float = 0.6        # m: within this of the goal the segment is asked to stand on it
    rest_weight: float = 20.0
    seam_weight: float = 100.0      # joints accelerate no more across a segment's start than within it ...
    seam_steers: int = 4            # ... in this many gradient steps with the real history, at the boundary,
    keep_weight: float = 3.0        # the rest of the segment stays as the model made it
    seam_step_size: float = 1.0     # each this long at most (longer ones made a standing body glide away)
    skate_weight: float = 1.0       # light: stronger, it buys less sliding by not walking at all
    floor_weight: float = 40.0

    def __post_init__(self) -> None:
        from .errors import InputError
        for name, value in vars(self).items():
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value) or value < 0:
                raise InputError(f"control config: {name} = {value!r} must be a finite number >= 0")


def _smooth_norm(v: torch.Tensor, eps: float = 0.05) -> torch.Tensor:
    """|v| with a rounded bottom, so the gradient does not flip back and forth at zero."""
    return torch.sqrt((v * v).sum(-1) + eps * eps) - eps


def hip_forward(joints: torch.Tensor) -> torch.Tensor:
    """(..., 22, 3) -> (..., 2) horizontal unit facing (+Y canonical forward = up x (right hip - left hip))."""
    across = joints[..., RIGHT_HIP, :2] - joints[..., LEFT_HIP, :2]
    fwd = torch.stack((-across[..., 1], across[..., 0]), -1)
    return torch.nn.functional.normalize(fwd, dim=-1, eps=1e-6)


def partner_cost(joints: torch.Tensor, partner: torch.Tensor, margin: float) -> torch.Tensor:
    """Joint pairs closer than `margin`: sum of squared shortfalls. joints (T, 22, 3), partner (T + L, 22, 3).

    The partner's frames past the segment's end (L of them) are compared with the segment's last pose: a
    segment must end out of the way of where the partner goes next, since the next one starts from there.
    """
    t = joints.shape[0]
    ego = torch.cat((joints, joints[-1:].expand(partner.shape[0] - t, -1, -1)), 0)
    d = torch.cdist(ego, partner)
    return torch.relu(margin - d).pow(2).sum()


def facing_cost(joints: torch.Tensor, target_xy: torch.Tensor) -> torch.Tensor:
    """1 - cos of the angle between the last frame's facing and the direction to target_xy (2,)."""
    last = joints[-1]
    to = torch.nn.functional.normalize(target_xy - last[0, :2], dim=-1, eps=1e-6)
    return 1.0 - (hip_forward(last) * to).sum()


def scene_cost(world_joints: torch.Tensor, field: DistanceField, margin: float) -> torch.Tensor:
    """Joints closer than `margin` to an obstacle (or inside one): sum of squared shortfalls."""
    return torch.relu(margin - field(world_joints)).pow(2).sum()


def goal_cost(pelvis: torch.Tensor, start_xy: torch.Tensor, goal_xy: torch.Tensor,
              cfg: ControlConfig) -> torch.Tensor:
    """Progress toward a floor goal at `pace`, then standing on it. pelvis (T, 3); start_xy the pelvis before."""
    frames = pelvis.shape[0]
    start = torch.linalg.vector_norm(goal_xy - start_xy)
    end = _smooth_norm(pelvis[-1, :2] - goal_xy)
    wanted = torch.clamp(start - cfg.pace * frames / FPS, min=0.0)
    cost = cfg.goal_weight * torch.relu(end - wanted)
    if float(start) < cfg.rest_radius:
        path = torch.cat((start_xy.unsqueeze(0), pelvis[:, :2]), 0)
        steps = (path[1:] - path[:-1]).pow(2).sum()
        cost = cost + cfg.rest_weight * (steps + end.pow(2))
    return cost


def seam_cost(joints: torch.Tensor, before: torch.Tensor, earlier: torch.Tensor) -> torch.Tensor:
    """Joint accelerations where a segment meets its history: at the last history frame and the first new one.

    Accelerations rather than "continue the history's velocity": that one made any drift of a standing body
    carry on into every next segment and grow (measured: 28-50 m per minute of "a person stands").
    """
    at_history = joints[0] - 2.0 * before + earlier
    at_first = joints[1] - 2.0 * joints[0] + before
    return at_history.pow(2).sum() + at_first.pow(2).sum()


def foot_cost(joints: torch.Tensor, before: torch.Tensor, cfg: ControlConfig) -> torch.Tensor:
    """Toes sliding while near the floor, and any joint below it. joints (T, 22, 3); before (22, 3)."""
    toes = torch.cat((before[TOES, :].unsqueeze(0), joints[:, TOES, :]), 0)      # (T + 1, 2, 3)
    sole = toes[..., 2] - SOLE_BELOW_FOOT_JOINT
    near = torch.sigmoid((0.04 - sole) / 0.01).detach()       # how planted each toe is; not a thing to move
    slide = (toes[1:, :, :2] - toes[:-1, :, :2]).pow(2).sum(-1)
    skate = (near[1:] * near[:-1] * slide).sum()
    below = torch.relu(-sole).pow(2).sum() + torch.relu(-joints[..., 2]).pow(2).sum()
    return cfg.skate_weight * skate + cfg.floor_weight * below


@dataclass
class ControlTargets:
    """What one segment is steered toward, in the job's canonical frame; None where a cost does not apply."""
    partner: torch.Tensor | None = None        # (T + L, 22, 3) the partner at the segment's frames and L after
    partner_still: bool = False                # standing within reach: also face them
    field: DistanceField | None = None
    to_world: tuple[torch.Tensor, torch.Tensor] | None = None   # (rot, trans) canonical -> world
    goal_xy: torch.Tensor | None = None
    alpha_hhi: float = 0.0
    alpha_hsi: float = 0.0


class SegmentCosts:
    """The total cost of a decoded segment (normalised features) given its history and targets."""

    def __init__(self, stats, hist_n: torch.Tensor, targets: ControlTargets, cfg: ControlConfig,
                 keep: torch.Tensor | None = None) -> None:
        """With `keep`, the joints (F, 22, 3) a finished latent decodes to with the real history at a segment's
        start, the seam is costed too, and the segment after its first frames is kept close to `keep`."""
        self.keep = keep
        self.stats, self.t, self.cfg = stats, targets, cfg
        hist = stats.denormalize(hist_n[0])
        self.before_joints = feature_joints(hist[-1])
        self.before_xy = hist[-1, ROOT_T][:2]
        self.earlier_joints = feature_joints(hist[-2]) if hist.shape[0] >= 2 else None

    def __call__(self, feat_n: torch.Tensor) -> torch.Tensor:
        feat = self.stats.denormalize(feat_n[0])
        joints = feature_joints(feat)
        t, cfg = self.t, self.cfg
        cost = foot_cost(joints, self.before_joints, cfg)
        if self.keep is not None and self.earlier_joints is not None:
            cost = cost + cfg.seam_weight * seam_cost(joints, self.before_joints, self.earlier_joints)
            cost = cost + cfg.keep_weight * (joints[2:] - self.keep[2:]).pow(2).sum()
        if t.partner is not None and t.alpha_hhi > 0.0:
            partner = cfg.partner_weight * partner_cost(joints, t.partner, cfg.partner_margin)
            if t.partner_still:
                partner = partner + cfg.face_weight * facing_cost(joints, t.partner[-1, 0, :2])
            cost = cost + t.alpha_hhi * partner
        if t.alpha_hsi > 0.0:
            scene = torch.zeros(())
            if t.field is not None and t.to_world is not None:
                rot, trans = t.to_world
                world = joints @ rot.T + trans
                scene = cfg.scene_weight * scene_cost(world, t.field, cfg.scene_margin)
            if t.goal_xy is not None:
                scene = scene + goal_cost(feat[:, ROOT_T], self.before_xy, t.goal_xy, cfg)
                far = float(torch.linalg.vector_norm(t.goal_xy - self.before_xy)) > cfg.goal_face_distance
                if far:
                    scene = scene + cfg.goal_face_weight * facing_cost(joints, t.goal_xy)
            cost = cost + t.alpha_hsi * scene
        return cost


class LatentSteer:
    """Moves a predicted clean latent down the gradient of a segment's costs (one decoder pass each way)."""

    def __init__(self, model, hist_n: torch.Tensor, costs: SegmentCosts, cfg: ControlConfig,
                 step_size: float | None = None) -> None:
        self.model, self.costs, self.cfg, self.hist = model, costs, cfg, hist_n
        self.step_size = cfg.step_size if step_size is None else step_size

    def __call__(self, x0: torch.Tensor) -> torch.Tensor:
        with torch.enable_grad():
            z = x0.detach().clone().requires_grad_(True)
            cost = self.costs(self.model.decode(self.hist, z))
            if not cost.requires_grad or float(cost.detach()) < self.cfg.negligible_cost:
                return x0      # nothing to correct: skip the backward pass (most of a steering step's time)
            (grad,) = torch.autograd.grad(cost, z)
        norm = float(grad.norm())
        if not np.isfinite(norm) or norm == 0.0:
            return x0
        scale = self.step_size * min(1.0, self.cfg.max_gradient / norm)
        return (x0 - scale * grad).detach()


def partner_future(window: torch.Tensor, present: torch.Tensor, lead: int, frames: int,
                   cfg: ControlConfig) -> tuple[torch.Tensor | None, bool]:
    """The partner at the next `frames` frames, moved on at its recent velocity, and whether it stands still.

    window (n, 22, 3) canonical partner frames (oldest first), present (n,) bool. `lead` is how many frames
    after the latest partner frame the first of them plays.
    """
    idx = torch.nonzero(present).flatten()
    if idx.numel() == 0:
        return None, False
    last = int(idx[-1])
    latest = window[last]
    velocity = torch.zeros(3)
    if idx.numel() >= 2:
        first = int(idx[max(0, idx.numel() - 4)])
        if last > first:
            velocity = (window[last, 0] - window[first, 0]) / (last - first)
    velocity[2] = 0.0
    speed = float(velocity.norm()) * FPS
    if speed > cfg.max_partner_speed:
        velocity = velocity * (cfg.max_partner_speed / speed)
    ahead = torch.arange(lead, lead + frames, dtype=torch.float32).view(-1, 1, 1)
    future = latest.unsqueeze(0) + ahead * velocity.view(1, 1, 3)
    still = speed < cfg.still_speed and float(latest[0, :2].norm()) < cfg.face_radius
    return future, still
