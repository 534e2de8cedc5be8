"""Two-bone leg IK, analytic and batched over frames: bend the knee, then swing the leg about the hip.

Analytic rather than Blender's IK constraint: it runs inside the one per-frame pose computation (the same
numbers live and in a bake, no constraint to add to the user's rig and evaluate per frame), and a reachable
ankle goal is met exactly instead of to an iterative solver's tolerance.

A planted toe can be out of the target leg's reach where the ego's stance leg is at full stretch and the
target's proportions differ (the runtime rolls the ego's own foot about its toe there and the target's foot
follows that roll, but a shorter leg or a longer foot can still fall short). `plant_legs` then first rolls the
foot about the toe (the heel lifts, up to MAX_ROLL), then moves the pelvis (up to MAX_SHIFT of the leg's length)
so that the stretched leg reaches while every other planted leg keeps its length: a straight knee bent by a few
millimetres of pelvis drop would swing the whole leg, so the pelvis moves about the other foot instead.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._runtime import api
from .rotations import axis_angle, cross, norm, rotation_between, solve3, unit

REACH = 0.999                   # share of the stretched leg's length the solve may use (a straight knee flips)
_RT = api()   # the runtime's public package (its toe roll needs no PyTorch)

MAX_ROLL = float(np.radians(8.0))    # foot roll about a planted toe that a stretched leg may add
MAX_SHIFT = 0.04                # share of the leg's length the pelvis may move so that a planted leg reaches
STRAIGHT = (0.98, 0.995)        # hip-to-ankle share of the reach from which a knee counts as straight (fully at 0.995)


def solve_leg(hip: np.ndarray, knee: np.ndarray, ankle: np.ndarray, goal: np.ndarray,
              hint: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotations that bring the ankle to `goal` (as near as the leg reaches): (hip_rot, knee_rot), (N, 3, 3).

    hip, knee, ankle, goal: (N, 3) points. The knee keeps bending in the leg's current plane; `hint` (N, 3)
    is the bend axis for a straight leg. Apply hip_rot to the thigh's orientation and knee_rot to the
    shin's (both pre-multiplied, in the points' space); the foot keeps its own orientation.
    """
    upper, lower = knee - hip, ankle - knee
    l1 = norm(upper)
    l2 = norm(lower)
    d = np.clip(norm(goal - hip), np.abs(l1 - l2) + 1e-6, REACH * (l1 + l2))
    normal = cross(upper, lower)
    straight = norm(normal) < 1e-9 * np.maximum(l1 * l2, 1e-12)
    normal = unit(np.where(straight[:, None], hint, normal))
    cur = np.arccos(np.clip(np.sum(upper * lower, -1) / np.maximum(l1 * l2, 1e-12), -1.0, 1.0))
    want = np.arccos(np.clip((d * d - l1 * l1 - l2 * l2) / np.maximum(2.0 * l1 * l2, 1e-12), -1.0, 1.0))
    bend = axis_angle(normal, want - cur)                      # turns the shin about the knee
    bent_ankle = knee + (bend @ lower[..., None])[..., 0]
    swing = rotation_between(bent_ankle - hip, goal - hip)    # turns the whole leg about the hip
    return swing, swing @ bend


def roll_about_toe(ankle: np.ndarray, toe: np.ndarray, hip: np.ndarray, reach: np.ndarray) -> np.ndarray:
    """(N, 3, 3): the smallest turn of each foot about its toe (at most MAX_ROLL) that brings the ankle within
    `reach` of the hip (the runtime's `toe_roll`); identity where it is within reach already."""
    reach = np.broadcast_to(reach, ankle.shape[:-1])
    out = np.broadcast_to(np.eye(3), ankle.shape[:-1] + (3, 3)).copy()
    for i in np.flatnonzero(norm(hip - ankle) > reach):     # the few stretched legs only
        out[i] = _RT.toe_roll(ankle[i] - toe[i], hip[i] - toe[i], float(reach[i]), MAX_ROLL)
    return out


@dataclass(frozen=True)
class Leg:
    """One leg of a rig: its bones' slots, the toe point in the ankle bone's frame, how far the ankle reaches."""
    hip: int
    knee: int
    ankle: int
    toe: np.ndarray
    reach: float        # REACH times thigh plus shin length


def plant_legs(q: np.ndarray, heads: np.ndarray, legs: list[Leg], goals: np.ndarray, hint: np.ndarray) -> np.ndarray:
    """Put each toe on its goal, in place on `q` (T, B, 3, 3) orientations and `heads` (T, B, 3); returns the
    pelvis move (T, 3) (already applied to `heads`).

    goals (T, 2, 3): toe goals per leg, NaN for a free foot; hint (T, 3) the knees' bend axis. Both legs are
    solved in one batch (a live frame is one pose: the per-call cost counts).
    """
    rows, sides = np.nonzero(np.isfinite(goals).all(-1))
    shift = np.zeros((len(q), 3))
    if len(rows) == 0:
        return shift
    hip, knee, ankle = (np.array([getattr(leg, n) for leg in legs])[sides] for n in ("hip", "knee", "ankle"))
    toe = np.stack([leg.toe for leg in legs])[sides]
    reach = np.array([leg.reach for leg in legs])
    goal = goals[rows, sides]
    ankle_goal = goal - (q[rows, ankle] @ toe[..., None])[..., 0]          # the foot turned as posed
    roll = roll_about_toe(ankle_goal, goal, heads[rows, hip], reach[sides])
    q[rows, ankle] = roll @ q[rows, ankle]
    ankle_goal = goal + (roll @ (ankle_goal - goal)[..., None])[..., 0]
    per_leg = np.full(goals.shape, np.nan)
    per_leg[rows, sides] = ankle_goal
    shift = _pelvis_shift(heads[:, [leg.hip for leg in legs]], per_leg, reach)
    heads += shift[:, None, :]
    turn_hip, turn_knee = solve_leg(heads[rows, hip], heads[rows, knee], heads[rows, ankle], ankle_goal, hint[rows])
    q[rows, hip] = turn_hip @ q[rows, hip]
    q[rows, knee] = turn_knee @ q[rows, knee]
    return shift


def _pelvis_shift(hips: np.ndarray, ankle_goals: np.ndarray, reach: np.ndarray, damping: float = 0.05,
                  steps: int = 2) -> np.ndarray:
    """(T, 3): the smallest pelvis move that brings each planted leg's ankle goal within reach while every
    other planted leg that is nearly straight keeps its hip-to-goal distance (a bent knee takes up a small
    change unseen). Damped least squares, linearised, `steps` Newton steps.

    hips (T, 2, 3), ankle_goals (T, 2, 3) NaN for a free foot, reach (2,).
    """
    planted = np.isfinite(ankle_goals).all(-1)                              # (T, 2)
    goals = np.where(planted[..., None], ankle_goals, 0.0)
    dist0 = np.where(planted, norm(goals - hips), 0.0)
    want = np.minimum(dist0, reach)                                          # too far: reach; else: keep
    rows = np.flatnonzero((planted & (dist0 > reach)).any(-1))
    shift = np.zeros((len(hips), 3))
    if len(rows) == 0:
        return shift
    g, h = goals[rows], hips[rows]
    weight = np.where(planted[rows], np.clip((dist0[rows] / reach - STRAIGHT[0]) / (STRAIGHT[1] - STRAIGHT[0]),
                                             0.0, 1.0), 0.0)
    m = np.zeros((len(rows), 3))
    for _ in range(steps):
        v = g - (h + m[:, None, :])
        dist = norm(v)
        u = v / np.maximum(dist, 1e-12)[..., None]                                    # (N, 2, 3)
        err = dist - want[rows]                                                      # moving along u shortens
        a = np.einsum("nk,nki,nkj->nij", weight, u, u) + damping * np.eye(3)
        b = np.einsum("nk,nk,nki->ni", weight, err, u)
        m = m + solve3(a, b)
    limit = MAX_SHIFT * reach.max() / REACH
    length = norm(m)[:, None]
    shift[rows] = m * np.minimum(1.0, limit / np.maximum(length, 1e-12))
    return shift
