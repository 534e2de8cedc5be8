"""Retargeting any humanoid's world joint positions onto the SMPL-X 22-joint skeleton.

Steps (`retarget`): find the source's up axis and unit, turn it Z-up and into metres, scale it so its
legs are as long as SMPL-X's, rebuild the joints rigs disagree on, solve 22 global rotations joint by
joint from the root outwards, then put the soles on the floor.

- Landmarks: rigs place the pelvis and spine joints very differently, so those targets are rebuilt
  from the source's own geometry at SMPL-X's landmarks: the pelvis at SMPL-X's offset from the hip
  midpoint in the source's pelvis frame, spine1..3 spaced along the source spine at SMPL-X's
  proportions. Everything else is the bone map's joint.
- Bone directions: the spine, neck, head and arms copy the source's bone directions; the legs aim
  from where FK has put each joint at the child's target, so the feet land where the source's do
  (contacts survive the change of proportions); collars aim at the source shoulder as placed
  relative to spine3 (rigs put the collar joint anywhere between sternum and shoulder).
- Twist about each bone: pelvis from the exact left-right hip axis; spine1..3 and neck from the hip
  and shoulder axes, shared out along the spine; hips / shoulders from the plane the limb bends in
  (knees bend backwards, elbows forwards; a straight leg falls back on where the toes point);
  collars, knees, elbows and ankles take the smallest swing from their parent (hinges stay hinges);
  head, wrists and feet (no child to aim at) follow their parent.

The fit error compares FK of the result with these targets (the scaled source) after aligning the
pelvis; most of what remains is the difference in proportions, which no rotation can remove.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from ..errors import InputError
from ..skeleton import (FOOT_JOINTS, JOINT_INDEX, JOINT_NAMES, NUM_JOINTS, PARENTS, SOLE_BELOW_FOOT_JOINT,
                        forward_kinematics, global_to_local, rest_joints, rest_offsets)
from .bone_maps import NameIndex, parse_spec
from .geometry import axis_angle_rotation, normalized, perpendicular_part, rotation_between, two_vector_rotation

# Y-up source -> Blender Z-up: x' = x, y' = -z, z' = y
Y_UP_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])

J = JOINT_INDEX
_REST = rest_joints(torch.float64).numpy()
_OFF = rest_offsets(torch.float64).numpy()
_SPINE = [J["pelvis"], J["spine1"], J["spine2"], J["spine3"], J["neck"]]


# ------------------------------------------------------------------------------ bone map -> targets

def mapped_positions(positions: np.ndarray, ends: np.ndarray | None, names: list[str],
                     mapping: dict[str, str]) -> np.ndarray:
    """Source joints (T, J, 3) (+ End Site / tail points, NaN where none) -> the 22 SMPL-X joint
    targets (T, 22, 3) through a bone map."""
    index = NameIndex(names)
    col = {n: k for k, n in enumerate(names)}

    def pick(bone: str) -> int:
        real = index.find(bone)
        if real is None:
            raise InputError(f"bone map names '{bone}', which the source skeleton does not have; fix the map")
        return col[real]

    out = np.zeros(positions.shape[:1] + (NUM_JOINTS, 3))
    for j, name in enumerate(JOINT_NAMES):
        kind, bones, t = parse_spec(mapping[name])
        if kind == "lerp":
            out[:, j] = (1 - t) * positions[:, pick(bones[0])] + t * positions[:, pick(bones[1])]
        elif kind == "end":
            k = pick(bones[0])
            if ends is None or np.isnan(ends[:, k]).any():
                raise InputError(f"bone '{bones[0]}' has no end site to use for {name}; map {name} to a bone")
            out[:, j] = ends[:, k]
        else:
            out[:, j] = positions[:, pick(bones[0])]
    return out


# ------------------------------------------------------------------------------ axes, units, scale

def up_axis_rotation(targets: np.ndarray) -> tuple[np.ndarray, str]:
    """The rotation taking the source's up axis to +Z, and its name ('+Y', '+Z', ...).

    Up is the axis the neck is furthest along from the ankles (medians over the clip)."""
    v = np.median(targets[:, J["neck"]] - 0.5 * (targets[:, J["left_ankle"]] + targets[:, J["right_ankle"]]), 0)
    k = int(np.argmax(np.abs(v)))
    sign = 1.0 if v[k] > 0 else -1.0
    name = ("+" if sign > 0 else "-") + "XYZ"[k]
    if name == "+Y":
        return Y_UP_TO_Z_UP.copy(), name        # the convention the rest of the project uses
    up = np.zeros(3)
    up[k] = sign
    return rotation_between(up[None], np.array([[0.0, 0.0, 1.0]]))[0], name


# hip height above the soles -> metres per file unit
_UNITS = ((0.5, 1.5, 1.0, "m"), (50.0, 150.0, 0.01, "cm"), (500.0, 1500.0, 0.001, "mm"),
          (10.0, 25.0, 0.0254 / 0.45, "CMU ASF units"), (25.0, 50.0, 0.0254, "inches"))


def _hip_height(targets_zup: np.ndarray) -> float:
    """Median height of the hips over the lowest foot joint."""
    hips = 0.5 * (targets_zup[:, J["left_hip"]] + targets_zup[:, J["right_hip"]])[:, 2]
    floor = targets_zup[:, list(FOOT_JOINTS), 2].min(axis=1)
    return float(np.median(hips - floor))


def detect_unit(targets_zup: np.ndarray) -> tuple[float, str]:
    """Metres per file unit, from the median standing hip height (hips over the lowest foot joint)."""
    h = _hip_height(targets_zup)
    for lo, hi, metres, name in _UNITS:
        if lo <= h < hi:
            return metres, name
    raise InputError(f"cannot tell the unit of a skeleton whose hips are {h:.3g} units above its feet; "
                     "pass the unit (metres per file unit) explicitly")


def leg_length(joints: np.ndarray) -> float:
    """Mean hip-knee-ankle length of both legs over a clip (T, 22, 3)."""
    total = 0.0
    for side in ("left", "right"):
        h, k, a = (J[f"{side}_{n}"] for n in ("hip", "knee", "ankle"))
        total += np.linalg.norm(joints[:, h] - joints[:, k], axis=-1).mean()
        total += np.linalg.norm(joints[:, k] - joints[:, a], axis=-1).mean()
    return total / 2


# ------------------------------------------------------------------------------ IK targets

_REST_HIP_MID = 0.5 * (_REST[J["left_hip"]] + _REST[J["right_hip"]])


def _pelvis_frame(side: np.ndarray, torso: np.ndarray) -> np.ndarray:
    """Rotation from the rest pelvis frame to the one given by the hip axis (exact) and an up vector
    in the torso's terms (rest: hip midpoint -> neck; see `_pelvis_up`)."""
    rest_side = _REST[J["left_hip"]] - _REST[J["right_hip"]]
    return two_vector_rotation(rest_side, _REST[J["neck"]] - _REST_HIP_MID, side, torso)


def _pelvis_up(src: np.ndarray, hip_mid: np.ndarray, neck: np.ndarray) -> np.ndarray:
    """The pelvis's up direction, in the torso's terms (rest: hip midpoint -> neck).

    The torso alone says nothing about how the pelvis tilts while the spine bends, but the first spine
    joint usually rides on the pelvis. So the tilt follows the line hip midpoint -> lowest spine joint,
    turned about the hip axis by the clip's median angle between that line and the torso (which
    removes where the rig happens to put that joint). Without such a joint: the torso itself."""
    torso = neck - hip_mid
    side = normalized(src[:, J["left_hip"]] - src[:, J["right_hip"]])
    for j in (J["spine1"], J["spine2"], J["spine3"]):
        low = src[:, j] - hip_mid
        if np.median(np.linalg.norm(low, axis=-1)) > 0.03:
            break
    else:
        return torso
    a, _ = perpendicular_part(low, side)
    b, _ = perpendicular_part(torso, side)
    theta = np.arctan2((np.cross(a, b) * side).sum(-1), (a * b).sum(-1))      # about the hip axis
    mid = np.median(theta)
    turn = axis_angle_rotation(side, np.full(len(side), mid))
    return (turn @ normalized(a)[..., None])[..., 0] * np.linalg.norm(torso, axis=-1, keepdims=True)


def ik_targets(src: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Scaled Z-up source joints (T, 22, 3) -> IK targets with the pelvis and spine1..3 rebuilt at
    SMPL-X's landmarks from the source's hips and spine (rigs place those joints very differently),
    and the pelvis orientation (T, 3, 3) they were built with."""
    out = src.copy()
    lh, rh = src[:, J["left_hip"]], src[:, J["right_hip"]]
    hip_mid = 0.5 * (lh + rh)
    neck = src[:, J["neck"]]
    rot = _pelvis_frame(lh - rh, _pelvis_up(src, hip_mid, neck))
    out[:, J["pelvis"]] = hip_mid + rot @ (_REST[J["pelvis"]] - _REST_HIP_MID)
    # spine polyline: pelvis, the source's spine points that lie between pelvis and neck, neck
    pel = out[:, J["pelvis"]]
    axis = neck - pel
    pts, last = [pel], 0.05
    for j in (J["spine1"], J["spine2"], J["spine3"]):
        t = np.median(((src[:, j] - pel) * axis).sum(-1) / np.maximum((axis * axis).sum(-1), 1e-12))
        if last < t < 0.95:
            pts.append(src[:, j])
            last = t + 0.02
    pts.append(neck)
    poly = np.stack(pts, 1)                                               # (T, K, 3)
    seg = np.linalg.norm(np.diff(poly, axis=1), axis=-1)                  # (T, K-1)
    cum = np.concatenate([np.zeros((len(src), 1)), np.cumsum(seg, 1)], 1)
    rest_seg = np.linalg.norm(np.diff(_REST[_SPINE], axis=0), axis=-1)
    rest_frac = np.cumsum(rest_seg)[:-1] / rest_seg.sum()                 # spine1..3 along pelvis->neck
    for j, f in zip(_SPINE[1:4], rest_frac):
        s = f * cum[:, -1]
        k = np.clip((cum[:, 1:] < s[:, None]).sum(1), 0, poly.shape[1] - 2)
        w = (s - cum[np.arange(len(src)), k]) / np.maximum(seg[np.arange(len(src)), k], 1e-12)
        out[:, j] = poly[np.arange(len(src)), k] + w[:, None] * (poly[np.arange(len(src)), k + 1]
                                                                 - poly[np.arange(len(src)), k])
    return out, rot


# ------------------------------------------------------------------------------ the solver

def _bend_weight(rel: np.ndarray) -> np.ndarray:
    """Trust in a bend plane: 0 for a straight limb, 1 once it bends by ~15 degrees or more."""
    return np.clip(rel / np.sin(np.radians(15.0)), 0.0, 1.0)[:, None]


def solve_rotations(targets: np.ndarray, pelvis_rot: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """IK targets (T, 22, 3), Z-up metres at SMPL-X scale -> global rotations (T, 22, 3, 3) and the
    pelvis position (T, 3). pelvis_rot: the pelvis orientation when `ik_targets` already chose it."""
    t = targets.shape[0]
    glob = np.zeros((t, NUM_JOINTS, 3, 3))
    pos = np.zeros((t, NUM_JOINTS, 3))
    tg = targets
    side_hips = tg[:, J["left_hip"]] - tg[:, J["right_hip"]]
    side_chest = tg[:, J["left_shoulder"]] - tg[:, J["right_shoulder"]]
    rest_side_hips = _REST[J["left_hip"]] - _REST[J["right_hip"]]
    rest_side_chest = _REST[J["left_shoulder"]] - _REST[J["right_shoulder"]]
    hips_u, chest_u = normalized(side_hips), normalized(side_chest)
    rest_hips_u, rest_chest_u = normalized(rest_side_hips), normalized(rest_side_chest)
    # twist shared out along the spine: spine1 mostly hips, spine3 and neck the shoulders
    side_mix = {J["spine1"]: 2 / 3, J["spine2"]: 1 / 3, J["spine3"]: 0.0, J["neck"]: 0.0}

    hip_mid = 0.5 * (tg[:, J["left_hip"]] + tg[:, J["right_hip"]])
    glob[:, 0] = _pelvis_frame(side_hips, tg[:, J["neck"]] - hip_mid) if pelvis_rot is None else pelvis_rot
    pos[:, 0] = tg[:, J["pelvis"]]
    for j in range(1, NUM_JOINTS):   # SMPL-X order lists parents before children
        p = PARENTS[j]
        pos[:, j] = pos[:, p] + glob[:, p] @ _OFF[j]
        kids = [c for c in range(NUM_JOINTS) if PARENTS[c] == j]
        if not kids:
            glob[:, j] = glob[:, p]
            continue
        c = kids[0] if len(kids) == 1 else J["neck"]
        aim = _aim(j, c, tg, pos)
        rest_aim = _OFF[c]
        swing = rotation_between(glob[:, p] @ rest_aim, aim) @ glob[:, p]
        if j in side_mix:
            w = side_mix[j]
            glob[:, j] = two_vector_rotation(rest_aim, w * rest_hips_u + (1 - w) * rest_chest_u,
                                     aim, w * hips_u + (1 - w) * chest_u)
        elif JOINT_NAMES[j].endswith(("_hip", "_shoulder")):
            glob[:, j] = _limb_root(c, aim, rest_aim, swing, tg)
        else:
            glob[:, j] = swing
    return glob, pos[:, 0]


_LEGS = {J[f"{s}_{n}"] for s in ("left", "right") for n in ("hip", "knee", "ankle")}
_COLLARS = {J["left_collar"], J["right_collar"]}


def _aim(j: int, c: int, tg: np.ndarray, pos: np.ndarray) -> np.ndarray:
    """Where bone j -> c should point.

    Legs aim from where FK put the joint at the child's target, so feet land where the source's do
    (contacts survive the change of proportions). The spine, neck and arms copy the source bone's
    direction (aiming the short spine bones at positions would fold the spine wherever the torso
    lengths differ). Collars, whose joint rigs place anywhere between the sternum and the shoulder,
    aim at the source shoulder as placed relative to spine3."""
    if j in _LEGS:
        return tg[:, c] - pos[:, j]
    if j in _COLLARS:
        s3 = J["spine3"]
        return pos[:, s3] + (tg[:, c] - tg[:, s3]) - pos[:, j]
    return tg[:, c] - tg[:, j]


def _limb_root(c: int, aim: np.ndarray, rest_aim: np.ndarray, swing: np.ndarray,
               tg: np.ndarray) -> np.ndarray:
    """Hip or shoulder: aimed at its child c (knee / elbow), twisted so the limb bends in its hinge plane."""
    g = JOINT_NAMES[c]
    end = J[g.replace("knee", "ankle").replace("elbow", "wrist")]
    a = normalized(aim)
    bend, rel = perpendicular_part(tg[:, end] - tg[:, c], a)
    # knees bend backwards (+Y on the rest body, which faces -Y); elbows forwards
    rest_bend = np.array([0.0, 1.0, 0.0]) if g.endswith("knee") else np.array([0.0, -1.0, 0.0])
    fallback = swing @ rest_bend                        # the twist the plain swing would give
    if g.endswith("knee"):
        toes = tg[:, J[g.replace("knee", "foot")]] - tg[:, end]
        back, rel_t = perpendicular_part(-toes, a)
        wt = _bend_weight(rel_t)
        fallback = wt * normalized(back) + (1 - wt) * fallback
    w = _bend_weight(rel)
    second = w * normalized(bend) + (1 - w) * perpendicular_part(fallback, a)[0]
    ok = (np.linalg.norm(second, axis=-1) > 1e-6)[:, None, None]
    return np.where(ok, two_vector_rotation(rest_aim, rest_bend, aim, second), swing)


# ------------------------------------------------------------------------------ the whole step

@dataclass
class Retargeted:
    local_rot: torch.Tensor      # (T, 22, 3, 3) float32
    pelvis: torch.Tensor         # (T, 3) float32, soles on z = 0
    fit_error_mm: dict           # mean, max (mm), dir_deg, scale, unit, up
    targets: np.ndarray          # (T, 22, 3) the IK targets (scaled source, Z-up, floor-aligned)


@dataclass
class SourceFrame:
    """How a source's coordinates become Z-up metres at SMPL-X's size."""
    rotation: np.ndarray         # (3, 3) file axes -> Z up
    up: str                      # '+Y', '+Z', ...
    unit: float                  # metres per file unit
    unit_name: str               # how the unit was found: "given", "declared" or the detected unit's name
    scale: float                 # SMPL-X leg length / the source's leg length (in metres)


def source_frame(source: np.ndarray, unit: float | None = None, up: str | None = None,
                 unit_hint: float | None = None) -> SourceFrame:
    """The up axis, unit and leg scale of mapped source joints (T, 22, 3); see `retarget`."""
    if source.ndim != 3 or source.shape[1:] != (NUM_JOINTS, 3) or source.shape[0] < 1:
        raise InputError(f"retarget needs source joints of shape (T, 22, 3), got {source.shape}")
    if not np.isfinite(source).all():
        raise InputError("source joints contain NaN or inf; check the file's channels")
    if up is None:
        rot, up = up_axis_rotation(source)
    else:
        v = np.zeros(3)
        v["XYZ".index(up[-1].upper())] = -1.0 if up.startswith("-") else 1.0
        rot = Y_UP_TO_Z_UP if up.upper() in ("Y", "+Y") else rotation_between(v[None], np.array([[0, 0, 1.0]]))[0]
    pts = source @ rot.T
    unit_name = "given"
    if unit is None and unit_hint is not None and 0.5 <= _hip_height(pts * unit_hint) < 1.5:
        unit, unit_name = unit_hint, "declared"
    if unit is None:
        unit, unit_name = detect_unit(pts)
    scale = leg_length(_REST[None]) / max(leg_length(pts * unit), 1e-9)
    return SourceFrame(rot, up, float(unit), unit_name, float(scale))


def retarget(source: np.ndarray, unit: float | None = None, up: str | None = None,
             unit_hint: float | None = None, scale: float | None = None) -> Retargeted:
    """Mapped source joints (T, 22, 3) in the file's axes and unit -> SMPL-X local rotations and pelvis.

    unit: metres per file unit (detected from the hip height when None; `unit_hint`, e.g. an ASF
    file's declared unit, is taken when it gives a plausible hip height); up: '+Y', '+Z', ...
    (detected when None); scale: the factor from source metres to the result (default: legs as long
    as SMPL-X's). Several actors of one capture keep their placement when given one common scale."""
    frame = source_frame(source, unit, up, unit_hint)
    unit, up, unit_name = frame.unit, frame.up, frame.unit_name
    if scale is None:
        scale = frame.scale
    elif not (np.isfinite(scale) and scale > 0):
        raise InputError(f"retarget scale {scale} is not a positive number")
    pts = (source @ frame.rotation.T) * unit * scale
    targets, pelvis_rot = ik_targets(pts)
    glob, pelvis = solve_rotations(targets, pelvis_rot)
    local = global_to_local(torch.from_numpy(glob)).float()
    pel = torch.from_numpy(pelvis).float()
    joints, _ = forward_kinematics(local, pel)
    # soles on the floor: the lowest foot joint of the clip sits at the sole offset above z = 0
    floor = float(joints[:, list(FOOT_JOINTS), 2].min()) - SOLE_BELOW_FOOT_JOINT
    pel[:, 2] -= floor
    joints[..., 2] -= floor
    targets = targets - np.array([0.0, 0.0, floor])
    return Retargeted(local, pel, fit_error(joints.double().numpy(), targets) | {
        "scale": float(scale), "unit": float(unit), "unit_name": unit_name, "up": up}, targets)


def fit_error(joints: np.ndarray, targets: np.ndarray) -> dict:
    """How well FK of the result (T, 22, 3) matches the targets (the scaled source), pelvis aligned.

    mean / max: joint position error (mm) over all joints and frames; most of it is the difference in
    proportions (SMPL-X's shoulders and head sit higher over its hips than most rigs'), which no
    rotation can remove. legs_mean: the same over hips, knees, ankles and feet, where the solver
    aims at positions (foot contacts). dir_deg: mean angle between FK and target bones, the part the
    solver controls everywhere else."""
    d = (joints - joints[:, :1]) - (targets - targets[:, :1])
    err = np.linalg.norm(d, axis=-1) * 1000.0
    legs = sorted(_LEGS | {J["left_foot"], J["right_foot"]})
    par = list(PARENTS[1:])
    a = normalized(joints[:, 1:] - joints[:, par])
    b = normalized(targets[:, 1:] - targets[:, par])
    ang = np.degrees(np.arccos(np.clip((a * b).sum(-1), -1.0, 1.0)))
    return {"mean": float(err.mean()), "max": float(err.max()), "legs_mean": float(err[:, legs].mean()),
            "dir_deg": float(ang.mean())}
