import json

import numpy as np
import torch

from model_runtime import skeleton as sk
from model_runtime.quat import matrix_to_quat_np
from paths import shared_file


def test_fk_reproduces_reference_rest_joints():
    rest = torch.tensor(sk.REST_JOINTS_ZUP)
    joints, glob = sk.forward_kinematics(torch.eye(3).expand(22, 3, 3), rest[0])
    assert torch.allclose(joints, rest, atol=1e-6)
    assert torch.allclose(glob, torch.eye(3).expand(22, 3, 3))


def test_constants_match_the_reference_file():
    path = shared_file("reference/smplx_body22.json")
    ref = json.loads(path.read_text())
    assert tuple(ref["names"]) == sk.JOINT_NAMES
    assert tuple(ref["parents"]) == sk.PARENTS
    assert np.allclose(ref["rest_zup"], sk.REST_JOINTS_ZUP, atol=1e-6)
    # and the Z-up constants are the Y-up ones under x' = x, y' = -z, z' = y
    yup = np.asarray(ref["rest_yup"])
    assert np.allclose(np.stack((yup[:, 0], -yup[:, 2], yup[:, 1]), 1), sk.REST_JOINTS_ZUP, atol=1e-6)


def test_rest_body_faces_minus_y_and_left_is_plus_x():
    j = sk.rest_joints()
    assert j[sk.JOINT_INDEX["left_hip"], 0] > 0 > j[sk.JOINT_INDEX["right_hip"], 0]
    assert j[sk.JOINT_INDEX["head"], 2] > 0.4
    assert 0.9 < sk.standing_pelvis_height() < 1.0


def test_rotation_round_trips():
    g = torch.Generator().manual_seed(0)
    m = sk.axis_angle_to_matrix(torch.randn(500, 3, generator=g) * 2)
    assert torch.allclose(sk.rot6d_to_matrix(sk.matrix_to_rot6d(m)), m, atol=1e-5)
    q = sk.matrix_to_quat(m)
    assert torch.allclose(q.norm(dim=-1), torch.ones(500), atol=1e-5)
    assert (q[:, 0] >= 0).all()
    assert torch.allclose(sk.quat_to_matrix(q), m, atol=1e-5)
    assert torch.allclose(sk.axis_angle_to_matrix(sk.matrix_to_axis_angle(m)), m, atol=1e-4)
    # 6D from a noisy (non-orthonormal) input still gives a rotation
    r = sk.rot6d_to_matrix(torch.randn(100, 6, generator=g))
    assert torch.allclose(r @ r.transpose(-1, -2), torch.eye(3).expand(100, 3, 3), atol=1e-5)
    assert torch.allclose(torch.det(r), torch.ones(100), atol=1e-5)


def test_global_to_local_inverts_fk():
    loc = sk.axis_angle_to_matrix(torch.randn(4, 22, 3))
    _, glob = sk.forward_kinematics(loc, torch.zeros(4, 3))
    assert torch.allclose(sk.global_to_local(glob), loc, atol=1e-5)


def test_numpy_single_pose_path_matches_torch():
    loc = sk.axis_angle_to_matrix(torch.randn(22, 3) * 1.5)
    pel = torch.randn(3)
    joints, _ = sk.forward_kinematics(loc, pel)
    assert np.allclose(sk.forward_kinematics_np(loc.numpy(), pel.numpy()), joints.numpy(), atol=1e-5)
    assert np.allclose(matrix_to_quat_np(loc.numpy()), sk.matrix_to_quat(loc).numpy(), atol=1e-5)
    d6 = torch.randn(22, 6)
    assert np.allclose(sk.rot6d_to_matrix_np(d6.numpy()), sk.rot6d_to_matrix(d6).numpy(), atol=1e-5)


def test_slerp_endpoints_and_midpoint():
    q0 = sk.matrix_to_quat(sk.axis_angle_to_matrix(torch.tensor([0.0, 0.0, 0.0])))
    q1 = sk.matrix_to_quat(sk.axis_angle_to_matrix(torch.tensor([0.0, 0.0, 1.0])))
    assert torch.allclose(sk.quat_slerp(q0, q1, 0.0), q0, atol=1e-6)
    assert torch.allclose(sk.quat_slerp(q0, q1, 1.0), q1, atol=1e-6)
    mid = sk.matrix_to_axis_angle(sk.quat_to_matrix(sk.quat_slerp(q0, q1, 0.5)))
    assert torch.allclose(mid, torch.tensor([0.0, 0.0, 0.5]), atol=1e-5)
