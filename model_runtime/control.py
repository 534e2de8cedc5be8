"""Test-time control: steer a segment's latent while it is denoised, with gradients of costs on its motion.

DART steers a latent motion prior by optimisation over many iterations; here the budget is a few
milliseconds a frame, so a segment's denoised latent takes a few (`final_steers`) steps down the gradient of
differentiable costs on the segment it decodes to (one decoder forward and backward each), and at the segment's
start a few more (`seam_steers`) with the real history. The last `steered_steps` denoising steps can also move
their predicted clean latent x0 (off by default: the denoising after them undoes part of it, and on the val
split they bought nothing for their time).

The costs, on the decoded segment in the job's canonical frame (metres):
- partner: ego joints closer than `partner_margin` to the partner's joints, the partner moved on at its
  recent velocity to the times the segment plays; and turning to face a partner who stands close by;
- scene: ego joints closer than `scene_margin` to an obstacle, from a distance field built once per grid;
- goal: progress toward the goal at a walking pace and facing it while far, coming to rest on it when near;
- feet: toe sliding while near the floor, and joints below the floor;
- passing (between egos of a group): a walking ego passing another keeps `pass_clearance` aside on a side
  both choose alike (the one each is on, else keep right), so that two egos walking at each other move
  apart instead of into each other's way (a body's joints alone push back evenly on both sides).
Every cost takes a batch of segments (a group of egos), one row each, and gives one cost per row.
alpha_HHI scales the partner cost and alpha_HSI the scene and goal costs, so the sliders keep their
meaning and alpha 0 ignores the partner or the scene; the foot and floor costs belong to the motion itself
and apply at any alpha. Nothing here draws random numbers: the same seed still gives the same frames.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from . import control_grad as cg
from .distance_field import DistanceField
from .features import JOINTS, ROOT_T, feature_joints
from .joints import JOINT_INDEX, LEFT_HIP, RIGHT_HIP, SOLE_BELOW_FOOT_JOINT
from .navigation import NavigationField

FPS = 10.0
PASS_TIE = 0.05          # m: this close to the line of the relative motion, neither side is taken yet ...
PASS_TIE_SLOPE = 0.1     # ... plus this much per metre between them (4 degrees of walking direction noise)
TOES = (JOINT_INDEX["left_foot"], JOINT_INDEX["right_foot"])


@dataclass(frozen=True)
class ControlConfig:
    """Cost weights and step sizes of test-time control (chosen on the behaviour suite's val split)."""
    steered_steps: int = 0          # the last N denoising steps are steered (one gradient step each)
    final_steers: int = 6           # then this many gradient steps on the denoised latent
    step_size: float = 3.0          # latent units per steered step at full gradient
    max_gradient: float = 1.0       # gradient norms above this are scaled down to it (bounded step length)
    negligible_cost: float = 1e-4   # a segment costing less is left as it is
    partner_margin: float = 0.5     # m: joint-to-joint distance the partner cost keeps (0.6 kept no more on val
                                    # with the shipped modules, and two egos walking at each other then collided)
    partner_weight: float = 200.0
    pass_clearance: float = 0.7     # m: sideways pelvis offset kept from another ego while passing it ...
    pass_length: float = 2.0        # m: ... while within this distance of it along the relative motion (1 -> 2
                                    # with ego_plans on val: two egos head on 0 of 40 under 0.10 m, mean closest
                                    # 0.69 -> 1.09 m; the crowd family 75.0 -> 87.5 % keep 0.10 m)
    pass_weight: float = 20.0
    pass_speed: float = 0.3         # m/s: an ego or a relative motion slower than this passes no one
    face_weight: float = 10.0       # turning toward a partner standing within face_radius
    face_radius: float = 2.5        # m
    look_ahead: int = 8             # partner frames past a segment's end its last pose must keep clear of
    still_speed: float = 0.3        # m/s: a partner slower than this counts as standing
    max_partner_speed: float = 2.5  # m/s: the extrapolation never moves a partner faster than this
    ego_plans: int = 1              # 1: another ego is extrapolated from the end of its own segment now starting
                                    # (known), not from its latest frame, and whether two egos pass each other
                                    # is read from both plans' ends; 0: from the latest frames
    scene_margin: float = 0.12      # m: joint clearance the scene cost keeps from obstacles
    scene_weight: float = 40.0
    goal_weight: float = 2.0
    pace: float = 1.2               # m/s: the progress a segment is asked to make toward a far goal
    goal_face_weight: float = 10.0  # facing the goal while further than goal_face_distance
    goal_face_distance: float = 1.0  # m
    rest_radius: float = 0.6        # m: within this of the goal the segment is asked to stand on it
    rest_weight: float = 20.0
    seam_weight: float = 100.0      # joints accelerate no more across a segment's start than within it ...
    seam_steers: int = 2            # ... in this many gradient steps with the real history, at the boundary,
    partner_seam_steers: int = 3    # ... or this many where an ego reacts to another character (its partner
                                    # module turns the latent further from what the history alone would make:
                                    # val, the approach family's seam ratio 1.32 with 2, 1.18 with 3; walking
                                    # and standing alone keep 2, where 3 slid walking toes 0.9 -> 10 cm/s)
    still_partner_seam_weight: float = 250.0  # seam_weight for an ego facing a partner standing within reach,
                                    # blended in by alpha_hhi: the approach's pops were there (val, 144 approach
                                    # episodes: seam ratio 1.28 at 100, 1.15 at 250, 1.10 at 400); 200 everywhere
                                    # let a standing ego without a partner drift 0.38 m a minute
    keep_weight: float = 5.0        # the rest of the segment stays as the model made it (3 -> 5 on val: walking
                                    # forward turned 24 -> 16 deg per 20 s, the other targets held)
    seam_step_size: float = 1.0     # each this long at most (longer ones made a standing body glide away)
    skate_weight: float = 1.0       # light: stronger, it buys less sliding by not walking at all
    skate_body_share: float = 0.0   # how much of the skate gradient may move the pelvis (1: all of it, which
                                    # buys less sliding by slowing the body down: "a person runs" 1.21 -> 0.27
                                    # m/s on val); 0 moves the legs against the pelvis only
    floor_weight: float = 40.0
    glide_guard: float = 3.0        # m/s, 0 = off: a steering step that makes the pelvis step faster than this
                                    # (and 0.5 m/s faster than before the step) is taken back and halved (0 -> 3
                                    # with ego plans, val: crowd 87.5 -> 93.8 % keep 0.10 m, glides 42 -> 12 %)
    glide_weight: float = 0.0       # with a partner: pelvis accelerations past glide_accel, so that a dodge is
    glide_accel: float = 10.0       # walked, not glided (m/s^2; egos dodging one another moved their pelvis 4-10
                                    # m/s between two frames; real clips' pelvis accelerations: 99.9 % under 8)

    def __post_init__(self) -> None:
        from .errors import InputError
        for name, value in vars(self).items():
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value) or value < 0:
                raise InputError(f"control config: {name} = {value!r} must be a finite number >= 0")


GLIDE_MARGIN = 0.5    # m/s: a step that raises the peak pelvis speed less than this is no new glide
NORM_EPS = 1e-12      # under a square root whose hinge is zero near zero: only keeps its gradient finite


def _smooth_norm(v: torch.Tensor, eps: float = 0.05) -> torch.Tensor:
    """|v| with a rounded bottom, so the gradient does not flip back and forth at zero."""
    return torch.sqrt((v * v).sum(-1) + eps * eps) - eps


def hip_forward(joints: torch.Tensor) -> torch.Tensor:
    """(..., 22, 3) -> (..., 2) horizontal unit facing (+Y canonical forward = up x (right hip - left hip))."""
    across = joints[..., RIGHT_HIP, :2] - joints[..., LEFT_HIP, :2]
    fwd = torch.stack((-across[..., 1], across[..., 0]), -1)
    return torch.nn.functional.normalize(fwd, dim=-1, eps=1e-6)


def partner_cost(joints: torch.Tensor, partner: torch.Tensor, margin: float) -> torch.Tensor:
    """Joint pairs closer than `margin`: sum of squared shortfalls. joints (..., T, 22, 3), partner
    (..., T + L, 22, 3); one cost per leading index.

    The partner's frames past the segment's end (L of them) are compared with the segment's last pose: a
    segment must end out of the way of where the partner goes next, since the next one starts from there.
    """
    t = joints.shape[-3]
    last = joints[..., -1:, :, :]
    ego = torch.cat((joints, last.expand(last.shape[:-3] + (partner.shape[-3] - t, -1, -1))), -3)
    d = torch.cdist(ego, partner)
    return torch.relu(margin - d).pow(2).sum((-3, -2, -1))


def facing_cost(joints: torch.Tensor, target_xy: torch.Tensor) -> torch.Tensor:
    """1 - cos of the angle between the last frame's facing and the direction to target_xy (..., 2)."""
    last = joints[..., -1, :, :]
    to = torch.nn.functional.normalize(target_xy - last[..., 0, :2], dim=-1, eps=1e-6)
    return 1.0 - (hip_forward(last) * to).sum(-1)


def scene_cost(world_joints: torch.Tensor, field: DistanceField, margin: float) -> torch.Tensor:
    """Joints closer than `margin` to an obstacle (or inside one): sum of squared shortfalls.
    world_joints (T, 22, 3) or any points (..., 3): one cost; (B, T, 22, 3): one per segment."""
    short = torch.relu(margin - field(world_joints)).pow(2)
    return short.sum((-2, -1)) if short.dim() > 2 else short.sum()


def goal_cost(pelvis: torch.Tensor, start_xy: torch.Tensor, goal_xy: torch.Tensor,
              cfg: ControlConfig, walk=None) -> torch.Tensor:
    """Progress toward a floor goal at `pace`, then standing on it. pelvis (..., T, 3); start_xy (..., 2) the
    pelvis before; goal_xy (..., 2). `walk`, when given, maps floor points (..., 2) to the walking distance to
    the goal around obstacles (navigation.py): progress is then measured along the way around them."""
    frames = pelvis.shape[-2]
    start = torch.linalg.vector_norm(goal_xy - start_xy, dim=-1)
    if walk is None:
        far, end = start, _smooth_norm(pelvis[..., -1, :2] - goal_xy)
    else:
        far, end = walk(start_xy).detach(), walk(pelvis[..., -1, :2])
    wanted = torch.clamp(far - cfg.pace * frames / FPS, min=0.0)
    cost = cfg.goal_weight * torch.relu(end - wanted)

    def rest() -> torch.Tensor:
        path = torch.cat((start_xy.unsqueeze(-2), pelvis[..., :2]), -2)
        steps = (path[..., 1:, :] - path[..., :-1, :]).pow(2).sum((-2, -1))
        return cfg.rest_weight * (steps + end.pow(2))

    return _plus_where(cost, (start < cfg.rest_radius).reshape(-1).tolist(), rest)


def seam_cost(joints: torch.Tensor, before: torch.Tensor, earlier: torch.Tensor) -> torch.Tensor:
    """Joint accelerations where a segment meets its history: at the last history frame and the first new one.
    joints (..., T, 22, 3); before, earlier (..., 22, 3) the last two history frames; one cost per leading index.

    Accelerations rather than "continue the history's velocity": that one made any drift of a standing body
    carry on into every next segment and grow (measured: 28-50 m per minute of "a person stands").
    """
    at_history = joints[..., 0, :, :] - 2.0 * before + earlier
    at_first = joints[..., 1, :, :] - 2.0 * joints[..., 0, :, :] + before
    return at_history.pow(2).sum((-2, -1)) + at_first.pow(2).sum((-2, -1))


def glide_cost(pelvis_xy: torch.Tensor, history_xy: torch.Tensor, limit: float) -> torch.Tensor:
    """Horizontal pelvis accelerations past `limit` (m per frame^2): sum of squared excess. pelvis_xy (..., T, 2)
    the segment's pelvis path, history_xy (..., H, 2) the history's last frames before it (oldest first)."""
    path = torch.cat((history_xy, pelvis_xy), -2)
    acc = path[..., 2:, :] - 2.0 * path[..., 1:-1, :] + path[..., :-2, :]
    size = torch.sqrt((acc * acc).sum(-1) + NORM_EPS)
    return torch.relu(size - limit).pow(2).sum(-1)


def foot_cost(joints: torch.Tensor, before: torch.Tensor, cfg: ControlConfig) -> torch.Tensor:
    """Toes sliding while near the floor, and any joint below it. joints (..., T, 22, 3); before (..., 22, 3)."""
    toes = torch.cat((before[..., TOES, :].unsqueeze(-3), joints[..., :, TOES, :]), -3)      # (..., T + 1, 2, 3)
    sole = toes[..., 2] - SOLE_BELOW_FOOT_JOINT
    near = torch.sigmoid((0.04 - sole) / 0.01).detach()       # how planted each toe is; not a thing to move
    # The pelvis's own motion enters the slide's gradient only by skate_body_share: a sliding foot is fixed by the
    # leg. (pelvis - pelvis.detach() is zero in value; it only takes that share of the gradient off the pelvis.)
    pelvis = joints[..., :, :1, :2]
    moved = joints[..., :, TOES, :2] - (1.0 - cfg.skate_body_share) * (pelvis - pelvis.detach())
    toes_xy = torch.cat((before[..., TOES, :2].unsqueeze(-3), moved), -3)
    slide = (toes_xy[..., 1:, :, :] - toes_xy[..., :-1, :, :]).pow(2).sum(-1)
    skate = (near[..., 1:, :] * near[..., :-1, :] * slide).sum((-2, -1))
    below = torch.relu(-sole).pow(2).sum((-2, -1)) + torch.relu(-joints[..., 2]).pow(2).sum((-2, -1))
    return cfg.skate_weight * skate + cfg.floor_weight * below


def passing_cost(ego_xy: torch.Tensor, partner_xy: torch.Tensor, away: torch.Tensor,
                 cfg: ControlConfig) -> torch.Tensor:
    """Passing a partner on one side with room to spare. ego_xy, partner_xy (R, N, 2) pelvis paths; away (R, 2)
    the unit direction, across the relative motion, in which the ego keeps clear of the partner. Each frame
    within `pass_length` of the partner along the motion asks for `pass_clearance` that way, so the gradient
    moves the ego aside instead of only slowing it down (a body's joints push back evenly on both sides)."""
    rel = ego_xy - partner_xy
    along = torch.stack((away[:, 1], -away[:, 0]), -1)
    lon = (rel * along.unsqueeze(1)).sum(-1)
    lat = (rel * away.unsqueeze(1)).sum(-1)
    near = torch.relu(1.0 - lon.abs() / cfg.pass_length).detach()         # where to be aside, not a thing to move
    return (near * torch.relu(cfg.pass_clearance - lat).pow(2)).sum(-1)


def passing_away(own: np.ndarray, other: np.ndarray, before: np.ndarray | None,
                 cfg: ControlConfig) -> np.ndarray | None:
    """The world direction (unit xy) in which to pass another character, or None when not passing anyone.

    own, other (N, 2), N >= 2: the latest pelvis positions (xy, oldest first, one a frame) of the ego and of
    the other; their velocities are taken over all N, steadier than a step. Only a walking ego starts a
    pass: standing, it faces whoever comes (the partner cost still keeps its joints clear). A pass starts on
    the side of their relative motion the ego is on, or with the other on its left ("keep right") when that
    is not clear yet (the offset a few metres ahead is within the noise of the walking direction), and keeps
    that side (`before`, its direction so far) until the two have passed each other. Two egos passing each
    other see each other's inputs mirrored, so they choose opposite sides: they move apart.
    """
    frames = len(own) - 1
    own_v = (own[-1] - own[0]) / frames
    rel_v = own_v - (other[-1] - other[0]) / frames
    speed = float(np.hypot(rel_v[0], rel_v[1]))
    if speed * FPS < cfg.pass_speed or (before is None and float(np.hypot(own_v[0], own_v[1])) * FPS < cfg.pass_speed):
        return None                    # walking alongside is no pass; a standing ego lets others come to it
    along = rel_v / speed
    left = np.array([-along[1], along[0]])
    rel = own[-1] - other[-1]
    lon, lat = float(rel @ along), float(rel @ left)
    if lon > cfg.pass_length:          # moving apart and clear of each other: the pass is over
        return None
    if before is not None:
        side = float(np.sign(before @ left)) or -1.0
    else:
        side = float(np.sign(lat)) if abs(lat) > PASS_TIE + PASS_TIE_SLOPE * abs(lon) else -1.0
    return side * left


def _plus_where(cost: torch.Tensor, mask: list[bool], term) -> torch.Tensor:
    """cost + term() on the rows of `mask`: the plain sum when every row takes it, cost itself when none."""
    if not any(mask):
        return cost
    extra = term()
    if all(mask):
        return cost + extra
    return cost + torch.where(torch.tensor(mask).view(extra.shape[:1] + (1,) * (extra.dim() - 1)), extra,
                              torch.zeros_like(extra))


def _held(x: torch.Tensor, frames: int) -> torch.Tensor:
    """(R, T, ...) -> (R, frames, ...): the last entry held for the frames past T."""
    last = x[:, -1:]
    return torch.cat((x, last.expand((last.shape[0], frames - x.shape[1]) + last.shape[2:])), 1)


def _weight(values: list[float]) -> float | torch.Tensor:
    """One number when every row shares it (one segment stays exactly as it was), else one per row."""
    return values[0] if all(v == values[0] for v in values) else torch.tensor(values)


@dataclass
class ControlTargets:
    """What one segment is steered toward, in the job's canonical frame; None where a cost does not apply."""
    partner: torch.Tensor | None = None        # (T + L, 22, 3) the partner at the segment's frames and L after
    partner_still: bool = False                # standing within reach: also face them
    pass_away: torch.Tensor | None = None      # (2,) unit: passing the partner, keep clear of it this way
    field: DistanceField | None = None
    to_world: tuple[torch.Tensor, torch.Tensor] | None = None   # (rot, trans) canonical -> world
    goal_xy: torch.Tensor | None = None
    nav: NavigationField | None = None         # walking distance to the goal around the scene (world)
    face_xy: torch.Tensor | None = None        # (2,) where to face on the way to the goal (default: the goal)
    alpha_hhi: float = 0.0
    alpha_hsi: float = 0.0


def _per_row(weight: float | torch.Tensor, dims: int) -> float | np.ndarray:
    """A `_weight` for NumPy: one number, or one per row shaped to broadcast over `dims` trailing axes."""
    if isinstance(weight, torch.Tensor):
        return weight.double().numpy().reshape((-1,) + (1,) * dims)
    return float(weight)


def _held_np(x: np.ndarray, frames: int) -> np.ndarray:
    return np.concatenate((x, np.repeat(x[:, -1:], frames - x.shape[1], 1)), 1)


def _walking_distance(targets: list[ControlTargets]):
    """Canonical floor points (R, 2) -> (R,) walking distance to each row's goal, through its own field."""
    frames = [(t.to_world[0][:2, :2], t.to_world[1][:2], t.nav) for t in targets]

    def walk(xy: torch.Tensor) -> torch.Tensor:
        return torch.stack([nav(xy[k] @ rot.T + trans) for k, (rot, trans, nav) in enumerate(frames)])

    return walk


class _Rows:
    """The rows (segments) a cost applies to, and their inputs stacked: `index` None when all rows."""

    def __init__(self, take: list[bool]) -> None:
        self.any = any(take)
        self.all = all(take)
        self.rows = [i for i, t in enumerate(take) if t]
        self.index = None if self.all else torch.tensor(self.rows, dtype=torch.long)

    def of(self, x: torch.Tensor) -> torch.Tensor:
        return x if self.index is None else x[self.index]

    def add(self, cost: torch.Tensor, term: torch.Tensor) -> torch.Tensor:
        return cost + term if self.index is None else cost.index_add(0, self.index, term)


class SegmentCosts:
    """The cost of decoded segments (normalised features (B, T, D) -> (B,)), one row per segment, given their
    histories and targets: one ControlTargets per row (a group of egos) or one for all rows."""

    def __init__(self, stats, hist_n: torch.Tensor, targets: ControlTargets | list[ControlTargets],
                 cfg: ControlConfig, keep: torch.Tensor | None = None) -> None:
        """With `keep`, the joints ((B,) F, 22, 3) finished latents decode to with the real history at a
        segment's start, the seam is costed too, and each segment after its first frames is kept close to it."""
        self.stats, self.cfg = stats, cfg
        self.keep = keep.unsqueeze(0) if keep is not None and keep.dim() == 3 else keep
        hist = stats.denormalize(hist_n)
        self.before_joints = feature_joints(hist[:, -1])
        self.before_xy = hist[:, -1, ROOT_T][:, :2]
        self.history_xy = hist[:, -2:, ROOT_T][..., :2]      # the pelvis path the segment's path continues
        self.earlier_joints = feature_joints(hist[:, -2]) if hist.shape[1] >= 2 else None
        ts = list(targets) if isinstance(targets, (list, tuple)) else [targets] * hist_n.shape[0]
        p = self.partner = _Rows([t.partner is not None and t.alpha_hhi > 0.0 for t in ts])
        if p.any:
            self.partner_future = torch.stack([ts[i].partner for i in p.rows])
            self.still = [bool(ts[i].partner_still) for i in p.rows]
            self.alpha_hhi = _weight([ts[i].alpha_hhi for i in p.rows])
            # passing rows among the partner rows
            self.passes = _Rows([ts[i].pass_away is not None for i in p.rows])
            if self.passes.any:
                self.away = torch.stack([ts[p.rows[k]].pass_away for k in self.passes.rows])
        # the seam cost's weight per row: heavier where an ego faces a partner standing within reach
        weights = [cfg.seam_weight] * len(ts)
        for k, i in enumerate(p.rows):
            if self.still[k]:
                weights[i] += (cfg.still_partner_seam_weight - cfg.seam_weight) * ts[i].alpha_hhi
        self.seam_weights = _weight(weights)
        s = self.scene = _Rows([t.alpha_hsi > 0.0 for t in ts])
        if s.any:
            on = [ts[i] for i in s.rows]
            self.alpha_hsi = _weight([t.alpha_hsi for t in on])
            self.field = on[0].field if all(t.field is not None and t.to_world is not None for t in on) else None
            if self.field is not None:
                self.rot = torch.stack([t.to_world[0] for t in on])
                self.trans = torch.stack([t.to_world[1] for t in on])
            # goals among the scene rows, and which of them are far enough to be faced
            self.goal = _Rows([t.goal_xy is not None for t in on])
            if self.goal.any:
                goals = [on[i] for i in self.goal.rows]
                self.goal_xy = torch.stack([t.goal_xy for t in goals])
                self.face_xy = torch.stack([t.face_xy if t.face_xy is not None else t.goal_xy for t in goals])
                self.walk = _walking_distance(goals) if all(t.nav is not None for t in goals) else None
                self._walk_frames = [(t.to_world[0][:2, :2].double().numpy(), t.to_world[1][:2].double().numpy(),
                                      t.nav) for t in goals] if self.walk is not None else None
                start = self.goal.of(s.of(self.before_xy))
                self.far = (torch.linalg.vector_norm(self.goal_xy - start, dim=-1) > cfg.goal_face_distance).tolist()

    def __call__(self, feat_n: torch.Tensor) -> torch.Tensor:
        feat = self.stats.denormalize(feat_n)
        joints = feature_joints(feat)
        cfg = self.cfg
        cost = foot_cost(joints, self.before_joints, cfg)
        if self.keep is not None and self.earlier_joints is not None:
            cost = cost + self.seam_weights * seam_cost(joints, self.before_joints, self.earlier_joints)
            cost = cost + cfg.keep_weight * (joints[:, 2:] - self.keep[:, 2:]).pow(2).sum((-3, -2, -1))
        p = self.partner
        if p.any:
            mine = p.of(joints)
            partner = cfg.partner_weight * partner_cost(mine, self.partner_future, cfg.partner_margin)
            w = self.passes
            if w.any:
                held = _held(w.of(p.of(feat))[..., ROOT_T][..., :2], self.partner_future.shape[1])
                passing = passing_cost(held, w.of(self.partner_future)[..., 0, :2], self.away, cfg)
                partner = w.add(partner, cfg.pass_weight * passing)
            partner = _plus_where(partner, self.still, lambda: cfg.face_weight * facing_cost(
                mine, self.partner_future[:, -1, 0, :2]))
            if cfg.glide_weight > 0.0:
                partner = partner + cfg.glide_weight * glide_cost(p.of(feat[..., ROOT_T][..., :2]),
                                                                  p.of(self.history_xy), cfg.glide_accel / FPS ** 2)
            cost = p.add(cost, self.alpha_hhi * partner)
        s = self.scene
        if s.any:
            mine = s.of(joints)
            scene = torch.zeros(mine.shape[0])
            if self.field is not None:
                if mine.shape[0] == 1:    # one segment: the very product it has alone
                    world = mine @ self.rot[0].T + self.trans[0]
                else:
                    world = mine @ self.rot.transpose(-1, -2).unsqueeze(1) + self.trans.view(-1, 1, 1, 3)
                scene = cfg.scene_weight * scene_cost(world, self.field, cfg.scene_margin)
            g = self.goal
            if g.any:
                at = g.of(mine)
                goal = goal_cost(g.of(s.of(feat))[..., ROOT_T], g.of(s.of(self.before_xy)), self.goal_xy, cfg,
                                 self.walk)
                goal = _plus_where(goal, self.far, lambda: cfg.goal_face_weight * facing_cost(at, self.face_xy))
                scene = g.add(scene, goal)
            cost = s.add(cost, self.alpha_hsi * scene)
        return cost


    # ------------------------------------------------------------------ the same costs with their gradient, in NumPy
    def _np(self) -> dict:
        """The constant inputs of the costs as float64 NumPy arrays (built on first use)."""
        c = getattr(self, "_np_cache", None)
        if c is not None:
            return c
        n = lambda t: t.detach().double().numpy()   # noqa: E731
        c = {"mean": n(self.stats.mean), "std": n(self.stats.std), "before": n(self.before_joints),
             "before_xy": n(self.before_xy), "history_xy": n(self.history_xy),
             "earlier": None if self.earlier_joints is None else n(self.earlier_joints),
             "keep": None if self.keep is None else n(self.keep),
             "seam_w": np.reshape(n(self.seam_weights) if torch.is_tensor(self.seam_weights)
                                  else np.float64(self.seam_weights), (-1, 1, 1, 1))}
        if self.partner.any:
            c["future"] = n(self.partner_future)
            c["still"] = np.asarray(self.still, bool)
            if self.passes.any:
                c["away"] = n(self.away)
        if self.scene.any:
            if self.field is not None:
                c["rot"], c["trans"] = n(self.rot), n(self.trans)
            if self.goal.any:
                c["goal_xy"], c["face_xy"] = n(self.goal_xy), n(self.face_xy)
                c["far"] = np.asarray(self.far, bool)
                if self._walk_frames is not None:
                    start = c["before_xy"][self.scene.rows][self.goal.rows]
                    c["far_walk"] = self._walk_np(start)[0]
        self._np_cache = c
        return c

    def _walk_np(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Walking distances of canonical floor points (R, 2), one per goal row, and their gradients (R, 2)."""
        vals, grads = np.zeros(len(xy)), np.zeros((len(xy), 2))
        for k, (rot, trans, nav) in enumerate(self._walk_frames):
            v, g = cg.nav_value_and_grad(nav, (xy[k] @ rot.T + trans)[None])
            vals[k], grads[k] = v[0], g[0] @ rot
        return vals, grads

    def value_and_grad(self, feat_n: torch.Tensor) -> tuple[np.ndarray, torch.Tensor]:
        """What __call__ gives for normalised features (B, T, D), (B,), and its gradient with respect to them
        (B, T, D): the same sums with their derivatives written out in NumPy (control_grad.py), far cheaper than
        autograd on ~100 tiny ops."""
        c, cfg = self._np(), self.cfg
        f = feat_n.detach().double().numpy() * c["std"] + c["mean"]
        b, t = f.shape[:2]
        joints = f[..., JOINTS].reshape(b, t, -1, 3)
        pelvis = f[..., ROOT_T]
        cost, g_j = cg.foot(joints, c["before"], TOES, cfg.skate_weight, cfg.floor_weight, cfg.skate_body_share)
        g_root = np.zeros_like(pelvis)
        if c["keep"] is not None and c["earlier"] is not None:
            sc, sg = cg.seam(joints, c["before"], c["earlier"])
            diff = joints[:, 2:] - c["keep"][:, 2:]
            cost = cost + c["seam_w"][:, 0, 0, 0] * sc + cfg.keep_weight * (diff * diff).sum((1, 2, 3))
            g_j = g_j + c["seam_w"] * sg
            g_j[:, 2:] += 2.0 * cfg.keep_weight * diff
        p = self.partner
        if p.any:
            mine, future = joints[p.rows], c["future"]
            pc, pg = cg.partner(mine, future, cfg.partner_margin)
            pc, pg = cfg.partner_weight * pc, cfg.partner_weight * pg
            pr = np.zeros(mine.shape[:2] + (3,))
            w = self.passes
            if w.any:
                held = _held_np(pelvis[p.rows][w.rows][..., :2], future.shape[1])
                wc, wg = cg.passing(held, future[w.rows][..., 0, :2], c["away"], cfg.pass_clearance, cfg.pass_length)
                pc[w.rows] += cfg.pass_weight * wc
                gp = cfg.pass_weight * wg[:, :t]
                gp[:, -1] += cfg.pass_weight * wg[:, t:].sum(1)
                pr[w.rows, :, :2] += gp
            if c["still"].any():
                fc, fg = cg.facing(mine, future[:, -1, 0, :2])
                pc = pc + np.where(c["still"], cfg.face_weight * fc, 0.0)
                pg = pg + np.where(c["still"][:, None, None, None], cfg.face_weight * fg, 0.0)
            if cfg.glide_weight > 0.0:
                gc, gg = cg.glide(pelvis[p.rows][..., :2], c["history_xy"][p.rows], cfg.glide_accel / FPS ** 2)
                pc = pc + cfg.glide_weight * gc
                pr[..., :2] += cfg.glide_weight * gg
            cost[p.rows] += _per_row(self.alpha_hhi, 0) * pc
            g_j[p.rows] += _per_row(self.alpha_hhi, 3) * pg
            g_root[p.rows] += _per_row(self.alpha_hhi, 2) * pr
        s = self.scene
        if s.any:
            mine = joints[s.rows]
            sc, sg, sr = np.zeros(len(s.rows)), np.zeros_like(mine), np.zeros(mine.shape[:2] + (3,))
            if self.field is not None:
                rot = c["rot"]
                world = np.einsum("rtjk,rik->rtji", mine, rot) + c["trans"][:, None, None]
                val, gw = cg.field_value_and_grad(self.field, world)
                short = np.maximum(cfg.scene_margin - val, 0.0)
                sc = cfg.scene_weight * (short * short).sum((1, 2))
                sg = np.einsum("rtji,rik->rtjk", cfg.scene_weight * -2.0 * short[..., None] * gw, rot)
            g = self.goal
            if g.any:
                walk_end = self._walk_np if self._walk_frames is not None else None
                gc, gg = cg.goal(pelvis[s.rows][g.rows], c["before_xy"][s.rows][g.rows], c["goal_xy"], cfg,
                                 c.get("far_walk"), walk_end)
                if c["far"].any():
                    fc, fg = cg.facing(mine[g.rows], c["face_xy"])
                    gc = gc + np.where(c["far"], cfg.goal_face_weight * fc, 0.0)
                    sg[g.rows] += np.where(c["far"][:, None, None, None], cfg.goal_face_weight * fg, 0.0)
                sc[g.rows] += gc
                sr[g.rows] += gg
            cost[s.rows] += _per_row(self.alpha_hsi, 0) * sc
            g_j[s.rows] += _per_row(self.alpha_hsi, 3) * sg
            g_root[s.rows] += _per_row(self.alpha_hsi, 2) * sr
        grad = np.zeros_like(f)
        grad[..., JOINTS] = g_j.reshape(b, t, -1)
        grad[..., ROOT_T] += g_root
        return cost, torch.from_numpy((grad * c["std"]).astype(np.float32))


class LatentSteer:
    """Moves predicted clean latents down the gradients of their segments' costs: one decoder pass each way
    for the whole batch (a group of egos). Rows do not mix (the decoder treats them apart), so the gradient
    of the summed costs is each row's own gradient."""

    def __init__(self, model, hist_n: torch.Tensor, costs: SegmentCosts, cfg: ControlConfig,
                 step_size: float | None = None) -> None:
        self.model, self.costs, self.cfg, self.hist = model, costs, cfg, hist_n
        self.step_size = cfg.step_size if step_size is None else step_size
        # with cfg.glide_guard: the latent before the last step, that step, and its pelvis's peak speed
        self._before: tuple[torch.Tensor, torch.Tensor, torch.Tensor] | None = None

    @staticmethod
    def decode_with_grad(model, hist_n: torch.Tensor, x0: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(latent that takes gradients, its decoded segment): a steering step's forward pass, which a caller
        that also needs the decoded segment (to build the costs from it) can hand to the first step."""
        with torch.enable_grad():
            z = x0.detach().clone().requires_grad_(True)
            return z, model.decode(hist_n, z)

    def __call__(self, x0: torch.Tensor, forward: tuple[torch.Tensor, torch.Tensor] | None = None) -> torch.Tensor:
        """One step from x0; `forward`: decode_with_grad(model, hist, x0) already computed, else done here."""
        z, decoded = forward if forward is not None else self.decode_with_grad(self.model, self.hist, x0)
        if self.cfg.glide_guard > 0.0:
            return self._guarded(x0, z, decoded)
        return self._step(x0, z, decoded)

    def settle(self, x0: torch.Tensor) -> torch.Tensor:
        """The last step checked as every other one is (glide_guard): x0 itself, or with the rows whose last step
        made them glide taken back to half that step (one more decoder pass; none with the guard off)."""
        if self.cfg.glide_guard <= 0.0 or self._before is None:
            return x0
        back = self._glided(self._peak_speed(self.model.decode(self.hist, x0)))
        start, taken, _ = self._before
        return torch.where(back.view(-1, 1, 1), start - 0.5 * taken, x0).detach() if bool(back.any()) else x0

    def _glided(self, peak: torch.Tensor) -> torch.Tensor:
        """(B,) bool: the rows whose last step made a glide, given their pelvis's peak speed after it."""
        return (peak > self.cfg.glide_guard) & (peak > self._before[2] + GLIDE_MARGIN)

    def _peak_speed(self, decoded: torch.Tensor) -> torch.Tensor:
        """(B,) the fastest horizontal pelvis step of each decoded segment, from the history's last frame, in m/s."""
        pelvis = self.costs.stats.denormalize(decoded.detach())[..., ROOT_T][..., :2]
        path = torch.cat((self.costs.before_xy.unsqueeze(1), pelvis), 1)
        return torch.linalg.vector_norm(path[:, 1:] - path[:, :-1], dim=-1).amax(1) * FPS

    def _guarded(self, x0: torch.Tensor, z: torch.Tensor, decoded: torch.Tensor) -> torch.Tensor:
        """A step as _step makes it, except for the rows whose previous step made their pelvis glide: those go
        back to where they were and take half that step instead. A glide is a new peak pelvis speed over
        glide_guard that is 0.5 m/s faster than before the step (a segment that was fast already may stay so)."""
        peak = self._peak_speed(decoded)
        moved = self._step(x0, z, decoded)
        if self._before is not None:
            start, taken, peak_before = self._before
            back = self._glided(peak)
            if bool(back.any()):
                rows = back.view(-1, 1, 1)
                halved = 0.5 * taken
                moved = torch.where(rows, start - halved, moved)
                self._before = (torch.where(rows, start, x0), torch.where(rows, halved, x0 - moved),
                                torch.where(back, peak_before, peak))
                return moved.detach()
        self._before = (x0, x0 - moved, peak)
        return moved

    def _step(self, x0: torch.Tensor, z: torch.Tensor, decoded: torch.Tensor) -> torch.Tensor:
        """One bounded step down the costs' gradient, per row; rows costing (almost) nothing stay."""
        with torch.enable_grad():
            cost, d_cost = self.costs.value_and_grad(decoded)
            # a row costing (almost) nothing is left as it is; with none left, skip the backward pass too
            rows = torch.from_numpy(cost >= self.cfg.negligible_cost)
            if not bool(rows.any()):
                return x0      # nothing to correct: skip the backward pass (most of a steering step's time)
            if not bool(rows.all()):
                d_cost[~rows] = 0.0
            (grad,) = torch.autograd.grad(decoded, z, grad_outputs=d_cost)
        if x0.shape[0] == 1:
            return self._moved(x0, grad)
        norm = grad.flatten(1).norm(dim=1)
        move = rows & torch.isfinite(norm) & (norm > 0.0)
        scale = self.step_size * torch.clamp(self.cfg.max_gradient / norm, max=1.0)
        return torch.where(move.view(-1, 1, 1), x0 - scale.view(-1, 1, 1) * grad, x0).detach()

    def _moved(self, x0: torch.Tensor, grad: torch.Tensor) -> torch.Tensor:
        """One bounded step down `grad`; x0 itself when the gradient is useless."""
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
