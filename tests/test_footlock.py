"""Planted feet: contacts from the motion, and leg IK that holds a planted toe within 5 mm."""
import math

import numpy as np

from model_runtime.footlock import LEGS, FootLock, global_rotations, solve_leg
from model_runtime.joints import standing_pelvis_height
from model_runtime.skeleton import forward_kinematics_np


def _rot_x(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _crouched_rest(knee_bend: float = 0.5) -> np.ndarray:
    """(22, 3, 3) local rotations: knees bent, hips flexed to match, so both legs have slack for the IK."""
    rot = np.tile(np.eye(3), (22, 1, 1))
    for side in LEGS.values():
        hip, knee, ankle, _ = side
        rot[hip] = _rot_x(-knee_bend / 2)
        rot[knee] = _rot_x(knee_bend)
        rot[ankle] = _rot_x(-knee_bend / 2)
    return rot


def _sliding_stance(frames: int = 12, slide: float = 0.01) -> tuple[np.ndarray, np.ndarray]:
    """A crouched body whose pelvis (and so its feet) slides `slide` m a frame along x, soles on the floor."""
    rot = _crouched_rest()
    probe = forward_kinematics_np(rot, np.zeros(3))
    lowest = probe[[10, 11], 2].min() - 0.02          # sole 2 cm below the toe joint, on z = 0
    pelvis = np.array([[k * slide, 0.0, -lowest] for k in range(frames)])
    return rot, pelvis


def test_solve_leg_reaches_target_and_keeps_the_foot_rotation():
    rot = _crouched_rest()
    pelvis = np.array([0.0, 0.0, 0.9])
    joints = forward_kinematics_np(rot, pelvis)
    glob = global_rotations(rot)
    hip, knee, ankle, toe = LEGS["left"]
    target = joints[ankle] + np.array([0.05, -0.03, 0.02])
    foot = glob[ankle].copy()
    assert solve_leg(glob, joints, LEGS["left"], target, foot, reach=0.999)
    local = rot.copy()
    for i in (hip, knee, ankle):
        from model_runtime.joints import PARENTS
        local[i] = glob[PARENTS[i]].T @ glob[i]
    after = forward_kinematics_np(local, pelvis)
    assert np.linalg.norm(after[ankle] - target) < 1e-6
    assert np.allclose(global_rotations(local)[ankle], foot, atol=1e-9)
    assert np.allclose(after[hip], joints[hip])        # the hip does not move


def test_planted_toe_stays_within_5mm_while_the_body_slides():
    rot, pelvis = _sliding_stance(frames=12, slide=0.01)
    lock = FootLock()
    toes, contacts = [], []
    for p in pelvis:
        cleaned, c = lock.apply(rot, *forward_kinematics_np(rot, p, world_rotations=True))
        toes.append(forward_kinematics_np(cleaned, p)[[10, 11]])
        contacts.append(c)
    toes, contacts = np.array(toes), np.array(contacts)
    assert contacts[1:].all()                           # both soles on the floor: both feet planted
    drift = np.linalg.norm(toes - toes[0], axis=-1).max()
    assert drift < 0.005, drift                         # the raw toes slid 11 cm
    raw = [forward_kinematics_np(rot, p)[10] for p in pelvis]
    assert np.linalg.norm(raw[-1] - raw[0]) > 0.1


def test_lifted_feet_are_not_locked_and_a_far_pelvis_lets_go():
    rot, pelvis = _sliding_stance(frames=30, slide=0.05)   # 1.5 m: no leg reaches that far back
    lock = FootLock()
    contacts = np.array([lock.apply(rot, *forward_kinematics_np(rot, p, world_rotations=True))[1] for p in pelvis])
    assert contacts[:3].all()
    assert not contacts.all(axis=1).all()               # out of reach, a foot lets go (and plants again later)
    air = _crouched_rest()
    lock.reset()
    _, c = lock.apply(air, *forward_kinematics_np(air, np.array([0.0, 0.0, standing_pelvis_height() + 0.3]),
                                                world_rotations=True))
    assert not c.any()
