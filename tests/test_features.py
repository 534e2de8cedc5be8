import math

import torch

from model_runtime import features as ft
from model_runtime import skeleton as sk


def random_motion(t=9, b=(), seed=0):
    g = torch.Generator().manual_seed(seed)
    loc = sk.axis_angle_to_matrix(0.4 * torch.randn(*b, t, 22, 3, generator=g))
    pel = torch.randn(*b, t, 3, generator=g) * 0.3 + torch.tensor([0.0, 0.0, 0.95])
    return loc, pel


def test_layout_is_276():
    loc, pel = random_motion()
    f = ft.features_from_pose(loc, pel)
    assert f.shape == (8, ft.FEATURE_DIM) and ft.FEATURE_DIM == 276
    assert ft.JOINT_DELTA.stop == 276


def test_features_pose_features_round_trip():
    loc, pel = random_motion()
    f = ft.features_from_pose(loc, pel)
    rot, pelvis = ft.features_to_pose(f)
    assert torch.allclose(rot, loc[:-1], atol=1e-5) and torch.allclose(pelvis, pel[:-1])
    # rebuild the features from the recovered poses (+ the last frame for deltas)
    f2 = ft.features_from_pose(torch.cat((rot, loc[-1:])), torch.cat((pelvis, pel[-1:])))
    assert torch.allclose(f, f2, atol=1e-5)
    joints, _ = sk.forward_kinematics(rot, pelvis)
    assert torch.allclose(ft.feature_joints(f), joints, atol=1e-5)


def world_move(loc, pel, yaw, shift):
    r = sk.yaw_matrix(torch.tensor(yaw))
    loc2 = loc.clone()
    loc2[..., 0, :, :] = r @ loc[..., 0, :, :]
    return loc2, pel @ r.T + torch.tensor(shift)


def test_rigid_transform_equals_features_of_moved_motion():
    loc, pel = random_motion()
    loc2, pel2 = world_move(loc, pel, 1.1, (2.0, -3.0, 0.25))
    f, f2 = ft.features_from_pose(loc, pel), ft.features_from_pose(loc2, pel2)
    moved = ft.rigid_transform(f, sk.yaw_matrix(torch.tensor(1.1)), torch.tensor([2.0, -3.0, 0.25]))
    assert torch.allclose(moved, f2, atol=1e-5)


def test_canonicalisation_invariant_to_world_yaw_and_translation():
    loc, pel = random_motion(b=(3,))
    f = ft.features_from_pose(loc, pel)
    for yaw, shift in ((0.5, (1.0, 2.0, 0.0)), (math.pi, (-4.0, 0.5, 0.0)), (-2.3, (0.0, 0.0, 0.0))):
        loc2, pel2 = world_move(loc, pel, yaw, shift)
        c1, _, _ = ft.canonicalize(f)
        c2, _, _ = ft.canonicalize(ft.features_from_pose(loc2, pel2))
        assert torch.allclose(c1, c2, atol=2e-5)


def test_canonical_frame_faces_plus_y_and_round_trips():
    loc, pel = random_motion()
    f = ft.features_from_pose(loc, pel)
    c, rot, trans = ft.canonicalize(f)
    j0 = ft.feature_joints(c[0])
    assert abs(float(j0[0, 0])) < 1e-5 and abs(float(j0[0, 1])) < 1e-5          # pelvis above the origin
    across = j0[sk.RIGHT_HIP] - j0[sk.LEFT_HIP]
    assert across[0] > 0 and abs(float(across[1])) < 1e-5                       # hips along +X
    assert torch.allclose(ft.to_world(c, rot, trans), f, atol=1e-5)
    assert abs(float(c[0, ft.ROOT_T][2] - pel[0, 2])) < 1e-5                     # height kept


def test_rest_body_canonical_facing_is_its_forward():
    j = sk.rest_joints()
    rot, _ = ft.canonical_frame(j)
    # rest faces -Y; the reference hips are 4.9 mm apart in y, so the hip-based facing is 2.2 deg off
    assert torch.allclose(rot[:, 1], torch.tensor([0.0, -1.0, 0.0]), atol=0.05)


def test_normalisation_round_trip():
    stats = ft.FeatureStats()
    x = torch.randn(100, 276) * 3 + 1
    stats.fit(x)
    assert torch.allclose(stats.denormalize(stats.normalize(x)), x, atol=1e-4)
    assert stats.normalize(x).mean(0).abs().max() < 1e-4
