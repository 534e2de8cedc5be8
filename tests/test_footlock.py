"""Planted feet: contacts from the motion, and leg IK that holds a planted toe within 5 mm."""
import math

import numpy as np
import pytest

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


def test_a_stretched_stance_leg_lifts_its_heel_about_the_planted_toe():
    """Straight legs and a pelvis moving on: the foot rolls about the planted toe (the heel lifts, as in a
    push-off) so the toe stays put; without the roll the same toe is dragged along."""
    from model_runtime.footlock import FootLockConfig
    rot = np.tile(np.eye(3), (22, 1, 1))                   # the rest pose: legs straight
    probe = forward_kinematics_np(rot, np.zeros(3))
    forward = probe[10] - probe[7]
    forward[2] = 0.0
    forward /= np.linalg.norm(forward)
    lift = -(probe[[10, 11], 2].min() - 0.02)
    pelvis = np.array([k * 0.025 * forward + (0.0, 0.0, lift) for k in range(8)])    # 17.5 cm on

    def run(config):
        lock = FootLock(config)
        out = []
        for p in pelvis:
            cleaned, c = lock.apply(rot, *forward_kinematics_np(rot, p, world_rotations=True))
            out.append((forward_kinematics_np(cleaned, p), c))
        joints = np.array([j for j, _ in out])
        return joints, np.array([c for _, c in out])

    joints, contacts = run(FootLockConfig())
    assert contacts.all()
    assert np.linalg.norm(joints[:, 10] - joints[0, 10], axis=-1).max() < 0.005
    assert joints[-1, 7, 2] - joints[0, 7, 2] > 0.01                      # the left heel (ankle) rose
    length = np.linalg.norm(probe[4] - probe[1]) + np.linalg.norm(probe[7] - probe[4])
    leg = np.linalg.norm(joints[:, 7] - joints[:, 1], axis=-1)
    assert np.all(leg <= FootLockConfig().reach * length + 1e-6)         # the leg is never stretched past reach
    stiff, stiff_contacts = run(FootLockConfig(max_roll_deg=0.0))
    assert np.linalg.norm(stiff[:, 10] - stiff[0, 10], axis=-1).max() > 0.02
    assert np.array_equal(stiff_contacts, contacts)                       # the roll does not make contacts longer


def test_a_roll_never_holds_a_toe_the_model_has_moved_on_from():
    """Whether a contact holds is judged on the foot as generated: a pelvis that runs away releases the toe at
    the same frame with the roll as without it."""
    from model_runtime.footlock import FootLockConfig
    rot, pelvis = _sliding_stance(frames=30, slide=0.05)                 # 1.5 m: no leg reaches that far back

    def contacts(config):
        lock = FootLock(config)
        return np.array([lock.apply(rot, *forward_kinematics_np(rot, p, world_rotations=True))[1] for p in pelvis])

    rolled, stiff = contacts(FootLockConfig()), contacts(FootLockConfig(max_roll_deg=0.0))
    assert not rolled.all(axis=1).all()                                  # the far pelvis lets a foot go ...
    assert np.array_equal(rolled, stiff)                                 # ... exactly when it would without the roll


def test_a_lifting_foot_lets_go_at_its_generated_height():
    """After lift-off the toe eases back to where the model put it across the floor, but rises as generated at
    once: it is not dragged along near the floor while it catches up."""
    rot, pelvis = _sliding_stance(frames=8, slide=0.01)
    pelvis[4:, 2] += 0.08                                  # the body (so both toes) rises 8 cm at frame 4
    lock = FootLock()
    for k, p in enumerate(pelvis):
        joints, glob = forward_kinematics_np(rot, p, world_rotations=True)
        cleaned, c = lock.apply(rot, joints, glob)
        toes = forward_kinematics_np(cleaned, p)[[10, 11]]
        if k < 4:
            assert c.all()
            anchor = toes.copy()
        elif k < 6:                                        # the fade frames
            assert not c.any()
            assert np.allclose(toes[:, 2], joints[[10, 11], 2], atol=1e-6)
            gap = np.linalg.norm(toes[:, :2] - joints[[10, 11], :2], axis=-1)
            assert np.all(gap > 0.001) and np.all(gap < np.linalg.norm(anchor[:, :2] - joints[[10, 11], :2], axis=-1))


def test_toe_roll_brings_the_ankle_within_reach_turning_no_further_than_allowed():
    from model_runtime import toe_roll
    toe_to_ankle, toe_to_hip = np.array([0.0, 0.15, 0.05]), np.array([0.0, 0.45, 0.85])
    assert np.array_equal(toe_roll(toe_to_ankle, toe_to_hip, 1.0, 0.5), np.eye(3))     # within reach: no turn
    reach = np.linalg.norm(toe_to_hip - toe_to_ankle) - 0.02
    turn = toe_roll(toe_to_ankle, toe_to_hip, reach, 0.5)
    assert np.allclose(turn @ turn.T, np.eye(3)) and np.linalg.det(turn) > 0.99
    assert np.linalg.norm(toe_to_hip - turn @ toe_to_ankle) == pytest.approx(reach, abs=1e-9)
    capped = toe_roll(toe_to_ankle, toe_to_hip, reach, 0.01)
    assert np.degrees(np.arccos((np.trace(capped) - 1) / 2)) == pytest.approx(np.degrees(0.01), abs=1e-6)


def test_toe_roll_needs_no_pytorch():
    import subprocess
    import sys
    code = "import sys, model_runtime; model_runtime.toe_roll; print('torch' in sys.modules)"
    assert subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip() \
        == "False"


def _toe_sweeps(config, rot: np.ndarray, pelvis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(generated joints, handed-out joints), each (T, 22, 3), of a body moved along `pelvis` through a FootLock."""
    lock = FootLock(config)
    generated, out = [], []
    for p in pelvis:
        joints, glob = forward_kinematics_np(rot, p, world_rotations=True)
        cleaned, _ = lock.apply(rot, joints, glob)
        generated.append(joints)
        out.append(forward_kinematics_np(cleaned, p))
    return np.array(generated), np.array(out)


def _dragged_steps(joints: np.ndarray) -> int:
    """The behaviour suite's dragged toe steps: planted toe steps at DRAGGED_TOE_SPEED or faster."""
    from model_runtime.behaviour.metrics import DRAGGED_TOE_SPEED, planted_toe_speed
    return int((planted_toe_speed(joints) >= DRAGGED_TOE_SPEED).sum())


def test_a_toe_swept_fast_across_the_floor_is_lifted_into_a_swing_on_its_own_path():
    from model_runtime.footlock import FootLockConfig
    from model_runtime.joints import SOLE_BELOW_FOOT_JOINT
    cfg = FootLockConfig()
    rot, pelvis = _sliding_stance(frames=12, slide=0.15)           # 1.5 m/s: too fast to plant, soles on the floor
    generated, out = _toe_sweeps(cfg, rot, pelvis)
    assert _dragged_steps(generated) > 0
    assert _dragged_steps(out) == 0
    swept = slice(2 + cfg.fade_frames, None)      # after the first frame's contact (nothing moved yet) has faded
    toes = [10, 11]
    np.testing.assert_allclose(out[swept][:, toes, :2], generated[swept][:, toes, :2], atol=1e-6)    # path kept
    sole = out[swept][:, toes, 2] - SOLE_BELOW_FOOT_JOINT
    assert sole == pytest.approx(cfg.swing_lift * 0.15, abs=1e-6)               # raised in proportion to the travel
    _, never = _toe_sweeps(FootLockConfig(swing_speed=math.inf), rot, pelvis)
    assert _dragged_steps(never) > 0                                             # without the lift they skate


def test_a_held_toe_catching_up_after_release_steps_instead_of_skating():
    """A pelvis creeping away (0.5 m/s: slow enough to plant) holds the toe until the leg runs out of reach; the
    catch-up that follows is lifted, and a new contact lands only once the toe has caught up."""
    from model_runtime.footlock import FootLockConfig
    rot, pelvis = _sliding_stance(frames=40, slide=0.05)
    generated, out = _toe_sweeps(FootLockConfig(), rot, pelvis)
    _, never = _toe_sweeps(FootLockConfig(swing_speed=math.inf), rot, pelvis)
    assert _dragged_steps(generated) == 0                                        # the model's toes only creep ...
    assert _dragged_steps(never) > 0                                             # ... the catch-ups skated ...
    assert _dragged_steps(out) == 0                                              # ... and now step
    held = np.linalg.norm(np.diff(out[:, [10, 11], :2], axis=0), axis=-1) < 1e-6
    assert held.mean() > 0.5                                                     # the toes are still held most frames


@pytest.mark.parametrize("sole_height", [0.02, -0.01])
def test_a_planted_foot_rests_on_the_floor_wherever_its_toe_touched_down(sole_height: float):
    """A crouched body whose soles hover 2 cm above the floor or sink 1 cm into it, sliding slowly: its held feet
    are put on the floor (the lower of toe and heel at the floor's height), not held where they touched down."""
    from model_runtime.footlock import FootLockConfig
    from model_runtime.joints import ANKLE_ABOVE_SOLE, SOLE_BELOW_FOOT_JOINT
    rot, pelvis = _sliding_stance(frames=6, slide=0.005)
    pelvis[:, 2] += sole_height
    floor = 0.0

    def lowest(joints: np.ndarray) -> np.ndarray:            # each foot's toe or heel, whichever is lower
        return np.minimum(joints[[10, 11], 2] - SOLE_BELOW_FOOT_JOINT, joints[[7, 8], 2] - ANKLE_ABOVE_SOLE)

    for ground in (True, False):
        lock = FootLock(FootLockConfig(ground=ground))
        for p in pelvis:
            joints, glob = forward_kinematics_np(rot, p, world_rotations=True)
            cleaned, contacts = lock.apply(rot, joints, glob, floor)
            assert contacts.all()
            expected = np.full(2, floor) if ground else lowest(joints)          # without it: as generated
            assert lowest(forward_kinematics_np(cleaned, p)) == pytest.approx(expected, abs=1e-6)
    assert np.abs(lowest(joints) - floor).min() > 0.005                         # the body was off the floor
