"""Planted feet: per-foot contact from the generated motion, and two-bone leg IK that holds a planted foot still.

The model's decoded frames slide their feet a little (a latent decoder has no notion of a fixed point on
the floor). This is output cleanup only: the session feeds the model its own raw frames as history, so
the model stays on the motion it was trained on, and applies the lock to what it hands out.

A foot is in contact when its toe's sole is near the floor and the toe moves slowly (with hysteresis).
At touch-down the toe's position is stored; while in contact the leg is solved so that, with the foot
turned as the model generated it, the toe stays on that point across the floor and the foot rests on the floor
(its toe, or its heel while the toes point up, at the floor's height), wherever within touch_height of it the
toe touched down. Where the pelvis has moved past the leg's reach (a push-off the model stretched a little too
far) the foot rolls about the toe, the heel lifting as in a real push-off, so the toe stays put. After lift-off the correction fades out over a few frames instead of snapping.
When the pelvis has moved well out of the leg's reach (judged on the foot as generated) the contact is released
early.

A foot out of contact that travels fast while near the floor (the model sweeping it low across the floor, or the
catch-up after a held contact lets go) is lifted into a swing: its sole is raised in proportion to that frame's
travel, its path across the floor unchanged, so a foot that moves a step's length in a frame leaves the floor
as a stepping foot does instead of skating along it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .joints import ANKLE_ABOVE_SOLE, JOINT_INDEX, PARENTS, SOLE_BELOW_FOOT_JOINT, rest_offsets_np

FPS = 10.0
LEGS = {"left": tuple(JOINT_INDEX[f"left_{n}"] for n in ("hip", "knee", "ankle", "foot")),
        "right": tuple(JOINT_INDEX[f"right_{n}"] for n in ("hip", "knee", "ankle", "foot"))}
_OFFSETS = rest_offsets_np()
_LEG_LENGTH = {leg: float(np.linalg.norm(_OFFSETS[leg[1]]) + np.linalg.norm(_OFFSETS[leg[2]])) for leg in LEGS.values()}


@dataclass(frozen=True)
class FootLockConfig:
    touch_height: float = 0.03      # m: the toe's sole below this starts a contact ...
    touch_speed: float = 1.0        # m/s: ... unless the toe sweeps past faster than this (a low swing)
    lift_height: float = 0.05       # m: a contact ends when the generated toe rises above this ...
    lift_speed: float = 1.5         # m/s: ... or sweeps faster than this
    fade_frames: int = 2            # frames to blend the correction out after lift-off
    reach: float = 0.999            # fraction of the leg's length the IK may stretch to
    max_miss: float = 0.04          # m: a planted toe further than this out of the leg's reach is let go
    max_roll_deg: float = 30.0      # heel lift about a planted toe that a stretched leg may add (push-offs reach 30+)
    ground: bool = True             # a planted foot rests on the floor (its lower end, toe or heel, at the floor's
                                    # height) rather than where its toe touched down, up to touch_height above it
    swing_speed: float = 1.0        # m/s: a free toe this fast and under touch_height is skating: it is lifted,
    swing_lift: float = 0.3         # its sole raised to this fraction of the frame's travel (15 cm: 4.5 cm),
    max_swing_lift: float = 0.05    # at most this high (m; real walks' toes past 1 m/s: sole p10 3.5, p50 6.8 cm)


# 3-vector helpers: np.cross and np.linalg.norm cost tens of microseconds on one small vector (axis handling),
# and the IK runs on every output frame; these compute the very same floating-point expressions.
def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.array((a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]))


def _norm(v: np.ndarray) -> float:
    return math.sqrt(float(v @ v))


def _rotation_between(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The smallest rotation taking direction u to direction v (3x3)."""
    u = u / max(_norm(u), 1e-12)
    v = v / max(_norm(v), 1e-12)
    axis = _cross(u, v)
    s, c = _norm(axis), min(1.0, max(-1.0, float(u @ v)))
    if s < 1e-9:
        if c > 0:
            return np.eye(3)
        perp = _cross(u, np.array([1.0, 0.0, 0.0]) if abs(u[0]) < 0.9 else np.array([0.0, 1.0, 0.0]))
        return _axis_angle(perp / _norm(perp), np.pi)
    return _axis_angle(axis / s, np.arctan2(s, c))


def _axis_angle(axis: np.ndarray, angle: float) -> np.ndarray:
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + math.sin(angle) * k + (1.0 - math.cos(angle)) * (k @ k)


_NO_TURN = np.eye(3)
_NO_TURN.setflags(write=False)     # returned shared: most frames need no roll, and a new array costs per frame


def toe_roll(toe_to_ankle: np.ndarray, toe_to_hip: np.ndarray, reach: float, max_roll: float) -> np.ndarray:
    """(3, 3): the smallest turn of a foot about its planted toe (at most `max_roll` radians) that brings the ankle
    within `reach` of the hip; the identity (read-only) where it is within reach already. Vectors (3,) from the
    toe. One foot at a time, in scalar arithmetic: it runs per frame (the foot lock here, a target rig's leg
    solver)."""
    a, h = toe_to_ankle, toe_to_hip
    r, dist = _norm(a), _norm(h)
    if dist < 1e-9 or _norm(h - a) <= reach:
        return _NO_TURN
    now = math.acos(min(1.0, max(-1.0, float(a @ h) / (r * dist))))
    need = math.acos(min(1.0, max(-1.0, (r * r + dist * dist - reach * reach) / (2.0 * r * dist))))
    axis = _cross(a, h)
    if _norm(axis) < 1e-9:
        return _NO_TURN
    return _axis_angle(axis / _norm(axis), min(max(now - need, 0.0), max_roll))


def roll_about_toe(foot_rot: np.ndarray, toe_in_foot: np.ndarray, toe: np.ndarray, hip: np.ndarray,
                   reach: float, max_roll: float) -> np.ndarray:
    """The foot's world rotation (3, 3) turned about its toe at `toe` by `toe_roll`.
    toe_in_foot: the toe joint's offset in the foot's (ankle's) frame."""
    turn = toe_roll(-(foot_rot @ toe_in_foot), hip - toe, reach, max_roll)
    return foot_rot if turn is _NO_TURN else turn @ foot_rot


def global_rotations(local_rot: np.ndarray) -> np.ndarray:
    """(22, 3, 3) local -> world rotations (the skeleton's FK, which computes them level by level)."""
    from .skeleton import forward_kinematics_np
    return forward_kinematics_np(local_rot, np.zeros(3, local_rot.dtype), world_rotations=True)[1]


def solve_leg(glob: np.ndarray, joints: np.ndarray, leg: tuple[int, int, int, int], target: np.ndarray,
              foot_rot: np.ndarray, reach: float, max_miss: float = 0.0) -> bool:
    """Rotate hip and knee (world rotations, in place) so the ankle reaches `target`; set the ankle's world
    rotation to `foot_rot`. A target up to `max_miss` beyond the stretched leg is approached as near as the
    leg goes; further out it returns False and changes nothing."""
    hip, knee, ankle, _ = leg
    h = joints[hip]
    l1 = _norm(glob[hip] @ _OFFSETS[knee])
    l2 = _norm(glob[knee] @ _OFFSETS[ankle])
    d_true = _norm(target - h)
    d = min(d_true, reach * (l1 + l2))
    if d_true - d > max_miss or d < abs(l1 - l2) + 1e-4:
        return False
    k = h + glob[hip] @ _OFFSETS[knee]
    a = k + glob[knee] @ _OFFSETS[ankle]
    # 1) bend the knee so the hip-ankle distance becomes d (law of cosines), about the leg plane's normal
    upper, lower = k - h, a - k
    normal = _cross(upper, lower)
    if _norm(normal) < 1e-9:           # a straight leg: bend about the hip's sideways axis
        normal = glob[hip][:, 0]
    normal = normal / _norm(normal)
    cur = math.acos(min(1.0, max(-1.0, float(upper @ lower) / (l1 * l2))))        # angle between the bones
    want = math.acos(min(1.0, max(-1.0, (d * d - l1 * l1 - l2 * l2) / (2 * l1 * l2))))
    bend = _axis_angle(normal, want - cur)
    glob[knee] = bend @ glob[knee]
    a = k + glob[knee] @ _OFFSETS[ankle]
    # 2) swing the whole leg about the hip so the ankle points at the target
    swing = _rotation_between(a - h, target - h)
    glob[hip] = swing @ glob[hip]
    glob[knee] = swing @ glob[knee]
    glob[ankle] = foot_rot
    return True


def local_from_global(glob: np.ndarray, joints_idx: tuple[int, ...], local_rot: np.ndarray) -> None:
    """Write the local rotations of `joints_idx` from world rotations (in place)."""
    for i in joints_idx:
        local_rot[i] = glob[PARENTS[i]].T @ glob[i]


class FootLock:
    """Per-session contact state; `apply` cleans one frame and returns the per-foot contacts."""

    def __init__(self, config: FootLockConfig | None = None, locks: bool = True) -> None:
        self.cfg = config or FootLockConfig()
        self.locks = locks          # False: only report contacts, leave the pose as generated
        self.reset()

    def reset(self) -> None:
        self._prev_toe = {side: None for side in LEGS}
        self._anchor: dict[str, np.ndarray | None] = {side: None for side in LEGS}
        self._fade: dict[str, tuple[int, np.ndarray] | None] = {side: None for side in LEGS}
        self._prev_out: dict[str, np.ndarray | None] = {side: None for side in LEGS}   # the toe as handed out

    def state(self) -> tuple:
        """A copy of the contact state (to undo a failed frame)."""
        return dict(self._prev_toe), dict(self._anchor), dict(self._fade), dict(self._prev_out)

    def set_state(self, state: tuple) -> None:
        self._prev_toe, self._anchor, self._fade, self._prev_out = (dict(d) for d in state)

    def _jump_to(self, side: str, toe_out: np.ndarray) -> float:
        """Horizontal speed (m/s) of the handed-out toe if it were at `toe_out` this frame (0 on the first)."""
        prev = self._prev_out[side]
        if prev is None:
            return 0.0
        return math.hypot(float(toe_out[0] - prev[0]), float(toe_out[1] - prev[1])) * FPS

    def _swing_height(self, side: str, toe_out: np.ndarray, floor: float) -> float:
        """How far (m) to raise a free toe handed out at `toe_out` so it swings instead of skating; 0 for none."""
        speed = self._jump_to(side, toe_out)
        if speed < self.cfg.swing_speed:
            return 0.0
        sole = float(toe_out[2]) - SOLE_BELOW_FOOT_JOINT - floor
        if sole >= self.cfg.touch_height:       # already clear of the floor: a swing as generated is left alone
            return 0.0
        return max(0.0, min(self.cfg.max_swing_lift, self.cfg.swing_lift * speed / FPS) - sole)

    def _reach(self, leg: tuple[int, int, int, int]) -> float:
        """How far from the hip the IK may put the ankle (m)."""
        return self.cfg.reach * _LEG_LENGTH[leg]

    def _rolled(self, foot: np.ndarray, leg: tuple[int, int, int, int], toe: np.ndarray,
                joints: np.ndarray) -> np.ndarray:
        """The foot's world rotation rolled about a toe at `toe` as far as the leg needs to reach it."""
        return roll_about_toe(foot, _OFFSETS[leg[3]], toe, joints[leg[0]], self._reach(leg),
                              math.radians(self.cfg.max_roll_deg))

    def _grounded(self, anchor: np.ndarray, toe_from_ankle: np.ndarray, floor: float) -> np.ndarray:
        """The planted toe's point: `anchor` across the floor, at the height where the foot (its toe at
        `toe_from_ankle` from its ankle) rests on the floor with its lower end (the toe, or the heel while the toes
        point up)."""
        if not self.cfg.ground:
            return anchor
        heel_above_toe = -float(toe_from_ankle[2]) - ANKLE_ABOVE_SOLE + SOLE_BELOW_FOOT_JOINT
        out = anchor.copy()
        out[2] = floor + SOLE_BELOW_FOOT_JOINT + max(0.0, -heel_above_toe)
        return out

    def _contact(self, side: str, toe: np.ndarray, floor: float) -> bool:
        prev = self._prev_toe[side]
        speed = 0.0 if prev is None else float(np.linalg.norm(toe[:2] - prev[:2]) * FPS)
        sole = toe[2] - SOLE_BELOW_FOOT_JOINT - floor
        if self._anchor[side] is not None:
            return sole < self.cfg.lift_height and speed < self.cfg.lift_speed
        return sole < self.cfg.touch_height and speed < self.cfg.touch_speed

    def apply(self, local_rot: np.ndarray, joints: np.ndarray, world_rot: np.ndarray,
              floor: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """One raw frame's local rotations (22, 3, 3), joints (22, 3) and world rotations (22, 3, 3) ->
        (local rotations with planted feet pinned, contacts (2,) bool: left, right).

        Without `locks` only the contacts are tracked and the rotations come back unchanged. The caller
        recomputes joints from the returned rotations (the pelvis is not moved)."""
        contacts = np.zeros(2, bool)
        out = glob = None
        for n, (side, leg) in enumerate(LEGS.items()):
            toe = joints[leg[3]]
            in_contact = self._contact(side, toe, floor)
            self._prev_toe[side] = toe.copy()
            if in_contact and self._anchor[side] is None and self.locks \
                    and self._jump_to(side, toe) >= self.cfg.swing_speed:
                in_contact = False              # a catch-up still under way: land it next frame, lifted on the way
            if in_contact and self._anchor[side] is None:
                self._anchor[side] = toe.copy()
            if not in_contact and self._anchor[side] is not None:
                self._fade[side] = (self.cfg.fade_frames, self._anchor[side]) if self.locks else None
                self._anchor[side] = None
            if not self.locks:
                contacts[n] = self._anchor[side] is not None
                continue
            if glob is None:                    # the first leg that is solved: work on copies
                out, glob = local_rot.copy(), world_rot.copy()
            generated_foot = glob[leg[2]].copy()
            toe_held = None
            if self._anchor[side] is not None:
                toe_from_ankle = generated_foot @ _OFFSETS[leg[3]]
                anchor = self._grounded(self._anchor[side], toe_from_ankle, floor)
                # whether the contact holds is judged on the foot as generated, as if it could not roll: a roll
                # never keeps a toe planted that the model has moved on from (its swing would then snap)
                miss = _norm(anchor - toe_from_ankle - joints[leg[0]]) - self._reach(leg)
                held = miss <= self.cfg.max_miss
                if held:                                # only a held toe is worth rolling the foot for
                    foot = self._rolled(generated_foot, leg, anchor, joints)
                    held = solve_leg(glob, joints, leg, anchor - foot @ _OFFSETS[leg[3]], foot, self.cfg.reach,
                                     self.cfg.max_miss)
                if held:
                    contacts[n] = True
                    toe_held = anchor
                else:                                   # out of reach: let this foot go
                    self._fade[side] = (self.cfg.fade_frames, anchor)
                    self._anchor[side] = None
            toe_out = toe_held if self._anchor[side] is not None else toe
            if self._anchor[side] is None:
                target = None
                if self._fade[side] is not None:
                    left, anchor = self._fade[side]
                    w = left / (self.cfg.fade_frames + 1.0)
                    target = (1.0 - w) * toe + w * anchor
                    target[2] = max(target[2], toe[2])      # lifts as generated: a fading toe is never dragged low
                    self._fade[side] = (left - 1, anchor) if left > 1 else None
                lift = self._swing_height(side, toe if target is None else target, floor)
                if lift > 0.0:
                    target = (toe if target is None else target) + np.array((0.0, 0.0, lift))
                if target is not None:
                    foot = self._rolled(generated_foot, leg, target, joints)
                    if solve_leg(glob, joints, leg, target - foot @ _OFFSETS[leg[3]], foot, self.cfg.reach,
                                 self.cfg.max_miss):
                        toe_out = target
            self._prev_out[side] = toe_out.copy()
            local_from_global(glob, leg[:3], out)
        return (local_rot if out is None else out), contacts
