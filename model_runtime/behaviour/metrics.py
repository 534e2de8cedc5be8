"""Behaviour metrics: NumPy functions of (T, 22, 3) world joints (Z up, metres, 10 fps model frames).

Each metric is defined here once; the suite, the scenario tests and the real-clip references call these.
"""
from __future__ import annotations

import math
from typing import Iterable, Sequence

import numpy as np

from ..data.pairs import facing_xy as hip_facing  # noqa: F401  (one definition each, shared with evaluation)
from ..data.pairs import min_clearance as min_joint_clearance  # noqa: F401
from ..evaluation.metrics import FEET as TOES  # SMPL-X "foot" joints sit at the toe base
from ..evaluation.metrics import facing_error_deg  # noqa: F401
from ..evaluation.metrics import grounded_foot_speeds
from ..joints import ANKLE_ABOVE_SOLE, JOINT_INDEX, SOLE_BELOW_FOOT_JOINT

FPS = 10.0
SEAM_PERIOD = 8                 # model frames per segment: frame k * 8 (k >= 1) starts a new segment
PLANTED_HEIGHT = 0.02           # m: a toe whose sole is this close to the floor counts as planted
REACH_RADIUS = 0.5              # m: a goal counts as reached once the pelvis is this close (horizontally)
SETTLE_S = 2.0                  # s: "does it stop": distance to the goal this long after arrival
AIRBORNE_HEIGHT = 0.05          # m: the lowest sole this far above the floor counts as airborne
MIN_TRAVEL = 0.3                # m: less horizontal travel has no direction to compare with the facing
WAVE_MIN_RAISED_FRAMES = 10     # a wrist above its shoulder for less than 1 s is not waving
FLOOR_HALF_WINDOW = 5           # frames: a real clip's floor follows its feet over about 1 s (rolling_floor)
DRAGGED_TOE_SPEED = 1.0         # m/s: a planted toe moving this fast is dragged along the floor, not creeping (the
                                # real walk's planted toes creep at 0.12 m/s on average, its fastest step 0.32)
GLIDE_SPEED = 4.0               # m/s: a pelvis step faster than this between two frames is a glide, not a step
                                # (the 4 h library's clips: 99.99 % of pelvis steps under 4.35 m/s, all under 5.0)

ANKLES = (JOINT_INDEX["left_ankle"], JOINT_INDEX["right_ankle"])
WRISTS = (JOINT_INDEX["left_wrist"], JOINT_INDEX["right_wrist"])
SHOULDERS = (JOINT_INDEX["left_shoulder"], JOINT_INDEX["right_shoulder"])


def goal_arrival(ego: np.ndarray, goal: Sequence[float], limit_frames: int,
                 radius: float = REACH_RADIUS, settle_s: float = SETTLE_S) -> tuple[bool, float, float]:
    """(reached, closest distance, distance settle_s after arrival) for the pelvis against a floor goal.

    Reached: within `radius` (horizontal) at some frame < limit_frames. The settle distance is NaN when not
    reached or when the episode ends before arrival + settle_s.
    """
    d = np.linalg.norm(np.asarray(ego, np.float64)[:, 0, :2] - np.asarray(goal, np.float64)[:2], axis=-1)
    inside = np.flatnonzero(d[:limit_frames] < radius)
    if inside.size == 0:
        return False, float(d.min()), float("nan")
    after = inside[0] + int(round(settle_s * FPS))
    return True, float(d.min()), float(d[after]) if after < len(d) else float("nan")


def frames_inside_boxes(joints: np.ndarray, boxes: Sequence) -> np.ndarray:
    """(T,) bool: any joint strictly inside any axis-aligned box (objects with .lo and .hi (3,) corners)."""
    j = np.asarray(joints, np.float64)
    hit = np.zeros(j.shape[0], bool)
    for b in boxes:
        lo, hi = np.asarray(b.lo, np.float64), np.asarray(b.hi, np.float64)
        hit |= ((j > lo) & (j < hi)).all(-1).any(-1)
    return hit


def joint_steps(joints: np.ndarray) -> np.ndarray:
    """(T-1,) mean over joints of the displacement from frame t-1 to frame t (m)."""
    j = np.asarray(joints, np.float64)
    return np.linalg.norm(np.diff(j, axis=0), axis=-1).mean(-1)


def peak_pelvis_speed(joints: np.ndarray) -> float:
    """The fastest horizontal pelvis step between two frames, in m/s: a dodge or a seam made by gliding shows
    here (walking peaks near 2 m/s, running near 4)."""
    if len(joints) < 2:
        return 0.0
    return float(np.linalg.norm(np.diff(joints[:, 0, :2], axis=0), axis=-1).max() * FPS)


def seam_ratio(joints: np.ndarray, period: int = SEAM_PERIOD, offset: int = 0) -> float:
    """Mean joint step into a seam frame (t = offset + k * period, k >= 1) over the mean step into other frames.

    1.0 means seams are invisible; a pop at every segment boundary gives a large ratio. Seams are the frames
    where a new segment starts; the step into frame t is joints[t] - joints[t - 1].
    """
    steps = joint_steps(joints)                     # steps[t - 1] is the step into frame t
    t = np.arange(1, len(steps) + 1)
    seam = ((t - offset) % period == 0) & (t > offset)
    if not seam.any() or seam.all():
        return float("nan")
    other = steps[~seam].mean()
    return float(steps[seam].mean() / max(other, 1e-9))


def planted_toe_speed(joints: np.ndarray, floor: float = 0.0, height: float = PLANTED_HEIGHT) -> np.ndarray:
    """Horizontal toe speeds (m/s) over every frame step where that toe's sole is below `height` at both ends.

    Pooled over both toes; concatenate several sequences' outputs and take the mean.
    """
    # the evaluation's grounded-foot measure (cm per frame, same toe joints) with the tighter planted height
    return grounded_foot_speeds(joints, floor, contact=height) / 100.0 * FPS


def dragged_toe_percent(toe_speeds: np.ndarray) -> float:
    """% of planted toe steps (planted_toe_speed's output, m/s) at DRAGGED_TOE_SPEED or faster: feet swept along the
    floor. The planted-toe mean mixes these with a planted foot's slow creep; a few of them can carry it."""
    s = np.asarray(toe_speeds, np.float64)
    return float(100.0 * (s >= DRAGGED_TOE_SPEED).mean()) if s.size else float("nan")


def heading_deg(joints: np.ndarray) -> np.ndarray:
    """(T,) unwrapped hip heading in degrees (counter-clockwise about +Z)."""
    f = hip_facing(joints)
    return np.degrees(np.unwrap(np.arctan2(f[:, 1], f[:, 0])))


def net_yaw_deg(joints: np.ndarray, per_seconds: float = 20.0) -> float:
    """Net heading change from first to last frame, scaled to `per_seconds` of motion (signed degrees)."""
    h = heading_deg(joints)
    duration = (len(h) - 1) / FPS
    return float((h[-1] - h[0]) * per_seconds / max(duration, 1e-9))


def standing_drift_m(joints: np.ndarray, per_seconds: float = 60.0) -> float:
    """Horizontal pelvis distance from the first to the last frame, scaled to `per_seconds` (m)."""
    p = np.asarray(joints, np.float64)[:, 0, :2]
    duration = (len(p) - 1) / FPS
    return float(np.linalg.norm(p[-1] - p[0]) * per_seconds / max(duration, 1e-9))


def finite_mean(xs: Iterable[float | None]) -> float:
    """Mean of the finite values (None and NaN skipped); NaN when there are none."""
    a = np.asarray([x for x in xs if x is not None and math.isfinite(x)], np.float64)
    return float(a.mean()) if a.size else float("nan")


# ----------------------------------------------------------------------------- what a text prompt changes
def _per_frame(floor, frames: int) -> np.ndarray:
    return np.broadcast_to(np.asarray(floor, np.float64), (frames,))


def lowest_sole(joints: np.ndarray, floor=0.0) -> np.ndarray:
    """(T,) height above the floor of the lowest sole point: toe (foot joint) or heel (ankle joint) of either
    foot. floor: a height or (T,) heights. A heel strike with the toes up is still on the ground."""
    j = np.asarray(joints, np.float64)
    toes = j[:, list(TOES), 2] - SOLE_BELOW_FOOT_JOINT
    heels = j[:, list(ANKLES), 2] - ANKLE_ABOVE_SOLE
    return np.minimum(toes.min(-1), heels.min(-1)) - _per_frame(floor, len(j))


def _window(x: np.ndarray, half: int, reduce) -> np.ndarray:
    return np.array([reduce(x[max(t - half, 0):t + half + 1]) for t in range(len(x))])


def rolling_floor(joints: np.ndarray, half_window: int = FLOOR_HALF_WINDOW) -> np.ndarray:
    """(T,) the floor under a real clip: the lowest sole's lower envelope (the largest of the window minima
    around each frame, both windows +-half_window frames). Some captures' floors slope or step by several
    centimetres, which would read as the feet leaving the ground; a flight shorter than the window
    (2 * half_window + 1 frames) still reads as airborne."""
    return _window(_window(lowest_sole(joints), half_window, np.min), half_window, np.max)


def airborne_percent(joints: np.ndarray, floor=0.0, height: float = AIRBORNE_HEIGHT) -> float:
    """Share of frames (%) whose lowest sole is more than `height` above the floor."""
    return float(100.0 * (lowest_sole(joints, floor) > height).mean())


def travel_vs_facing_deg(joints: np.ndarray, min_travel: float = MIN_TRAVEL) -> float:
    """Angle (0..180 deg) between the pelvis' horizontal travel, first to last frame, and the first frame's
    hip facing: 0 walks forward, 180 backs away. 0 when the pelvis travels less than `min_travel` (no
    direction to judge, and standing still is not moving backwards)."""
    j = np.asarray(joints, np.float64)
    travel = j[-1, 0, :2] - j[0, 0, :2]
    if np.linalg.norm(travel) < min_travel:
        return 0.0
    f = hip_facing(j[0])
    return float(np.degrees(abs(math.atan2(f[0] * travel[1] - f[1] * travel[0], f @ travel))))


def wave_measures(joints: np.ndarray, min_frames: int = WAVE_MIN_RAISED_FRAMES) -> tuple[float, float]:
    """(side-to-side sd in m, raised share in %) of the wrist that waves most.

    For each wrist, the frames where it is above its own shoulder; on those frames, its offset from that
    shoulder along the body's side-to-side axis (horizontal, square to the hip facing of that frame); the sd
    of that offset. A wrist raised on fewer than `min_frames` frames scores 0. Relative to the shoulder and
    the hips' own axis, so walking or turning while the arm is still reads as no wave.
    """
    j = np.asarray(joints, np.float64)
    f = hip_facing(j)
    side = np.stack((-f[:, 1], f[:, 0]), -1)
    best = (0.0, 0.0)
    for wrist, shoulder in zip(WRISTS, SHOULDERS):
        raised = j[:, wrist, 2] > j[:, shoulder, 2]
        if raised.sum() < min_frames:
            continue
        offset = ((j[:, wrist, :2] - j[:, shoulder, :2]) * side).sum(-1)
        best = max(best, (float(offset[raised].std()), float(100.0 * raised.mean())))
    return best


def text_measures(joints: np.ndarray, floor=0.0) -> dict:
    """Every statistic a text prompt is judged on (behaviour/text_targets.py says which, for which prompt).

    floor: the floor height (0 for rollouts) or a (T,) per-frame floor (rolling_floor, for real clips).
        pelvis_range_m        vertical range of the pelvis
        airborne_percent      frames with the lowest sole > 5 cm above the floor
        max_ankle_height_m    highest ankle joint above the floor
        speed_mps             mean horizontal pelvis speed
        forward_m             pelvis travel along the first frame's facing (negative: backwards)
        travel_vs_facing_deg  travel direction against the first frame's facing (travel_vs_facing_deg)
        wave_sd_m             side-to-side sd of a wrist held above its shoulder (wave_measures)
        wave_raised_percent   frames that wrist is above its shoulder
        wrist_sd_m            sd of the wrists' horizontal offsets from the pelvis
        wrist_speed_mps       mean wrist speed
    """
    j = np.asarray(joints, np.float64)
    floor = _per_frame(floor, len(j))
    pelvis = j[:, 0]
    disp = pelvis[-1, :2] - pelvis[0, :2]
    wrist_v = np.linalg.norm(np.diff(j[:, list(WRISTS)], axis=0), axis=-1) * FPS
    lateral = j[:, list(WRISTS), :2] - pelvis[:, None, :2]
    wave_sd, wave_raised = wave_measures(j)
    return {"pelvis_range_m": float(np.ptp(pelvis[:, 2])),
            "airborne_percent": airborne_percent(j, floor),
            "max_ankle_height_m": float((j[:, list(ANKLES), 2] - floor[:, None]).max()),
            "speed_mps": float(np.linalg.norm(np.diff(pelvis[:, :2], axis=0), axis=-1).mean() * FPS),
            "forward_m": float(disp @ hip_facing(j[0])),
            "travel_vs_facing_deg": travel_vs_facing_deg(j),
            "wave_sd_m": wave_sd,
            "wave_raised_percent": wave_raised,
            "wrist_sd_m": float(lateral.std(0).mean()),
            "wrist_speed_mps": float(wrist_v.mean())}


# ----------------------------------------------------------------------------- takes that differ
def canonical_pose(joints: np.ndarray) -> np.ndarray:
    """(T, 22, 3) joints minus each frame's pelvis, turned about +Z so the first frame's hips face -Y (yaw 0):
    where a take starts and which way it starts facing do not count, its poses and later turns do."""
    j = np.asarray(joints, np.float64)
    rel = j - j[:, :1]
    f = hip_facing(j[0])
    ang = -math.pi / 2 - math.atan2(f[1], f[0])          # rotates f onto (0, -1)
    c, s = math.cos(ang), math.sin(ang)
    out = rel.copy()
    out[..., 0], out[..., 1] = c * rel[..., 0] - s * rel[..., 1], s * rel[..., 0] + c * rel[..., 1]
    return out


def pose_distance_m(a: np.ndarray, b: np.ndarray) -> float:
    """Mean over frames and joints of the distance between two takes' canonical poses (m), frame by frame
    from the first, over the shorter take's length."""
    n = min(len(a), len(b))
    return float(np.linalg.norm(canonical_pose(a[:n]) - canonical_pose(b[:n]), axis=-1).mean())


def mean_pairwise_distance(takes: Sequence[np.ndarray]) -> tuple[float, int]:
    """(mean pose_distance_m over every pair of takes, number of pairs); NaN with fewer than two takes."""
    d = [pose_distance_m(takes[i], takes[k]) for i in range(len(takes)) for k in range(i + 1, len(takes))]
    return (float(np.mean(d)) if d else float("nan")), len(d)
