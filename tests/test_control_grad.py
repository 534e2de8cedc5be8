"""The control costs' gradients written out in NumPy (control_grad.py) give what autograd gives on the torch
definitions (control.py), for every cost, on a batch whose rows take different costs and alphas."""
from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from model_runtime.control import ControlConfig, ControlTargets, SegmentCosts
from model_runtime.distance_field import DistanceField
from model_runtime.features import JOINTS, ROOT_T, FeatureStats
from model_runtime.fixtures import BOX_GOAL, box_scene
from model_runtime.navigation import FloorMap, NavigationField
from model_runtime.skeleton import rest_joints, standing_pelvis_height

T, LOOK = 8, 8


def yaw(a: float) -> torch.Tensor:
    c, s = math.cos(a), math.sin(a)
    return torch.tensor([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def walking_segment(gen: torch.Generator, start: tuple[float, float], step: tuple[float, float],
                    frames: int = T) -> torch.Tensor:
    """(frames, 22, 3) a rest body gliding along `step` per frame with jittered joints and toes near the floor."""
    body = rest_joints() + torch.tensor([0.0, 0.0, standing_pelvis_height()])
    k = torch.arange(1, frames + 1, dtype=torch.float32).view(-1, 1, 1)
    moved = body + torch.tensor([start[0], start[1], 0.0]) + k * torch.tensor([step[0], step[1], 0.0])
    return moved + 0.02 * torch.randn(moved.shape, generator=gen)


def features(joints: torch.Tensor) -> torch.Tensor:
    """(B, T, 22, 3) -> (B, T, 276): the joint and pelvis channels set (the only ones the costs read)."""
    f = torch.zeros(joints.shape[:2] + (276,))
    f[..., JOINTS] = joints.reshape(joints.shape[:2] + (-1,))
    f[..., ROOT_T] = joints[..., 0, :]
    return f


@pytest.fixture(scope="module")
def stats() -> FeatureStats:
    s = FeatureStats()
    g = torch.Generator().manual_seed(1)
    s.mean.copy_(0.1 * torch.randn(276, generator=g))
    s.std.copy_(0.5 + torch.rand(276, generator=g))
    return s


def batch(stats: FeatureStats, keep: bool, body_share: float = 0.0):
    g = torch.Generator().manual_seed(7)
    scene = box_scene()
    field, floor = DistanceField(scene), FloorMap(scene)
    cfg = ControlConfig(skate_body_share=body_share, glide_weight=50.0, still_partner_seam_weight=300.0)
    segs = torch.stack([walking_segment(g, (0.1, -0.6), (0.0, -0.08)),     # walks into the box, partner beside
                        walking_segment(g, (1.0, 0.0), (0.01, 0.0)),       # stands near a still partner, near its goal
                        walking_segment(g, (-0.5, 0.5), (0.0, 0.05)),      # no partner, far goal behind
                        walking_segment(g, (2.0, 2.0), (0.0, 0.0))])       # nothing but its feet
    segs[0, 3:, 10, 2] -= 0.08                   # a toe dips under the floor
    segs[1, 5:, :, 0] += 0.3                      # glides 0.3 m sideways between two frames (a partner row)
    hist = torch.stack([walking_segment(g, (0.1, -0.44), (0.0, -0.08), 2), walking_segment(g, (1.0, 0.0), (0.0, 0.0), 2),
                        walking_segment(g, (-0.5, 0.4), (0.0, 0.05), 2), walking_segment(g, (2.0, 2.0), (0.0, 0.0), 2)])
    hist_n = stats.normalize(features(hist))
    to_world = [(yaw(0.3), torch.tensor([0.2, -0.1, 0.0])), (yaw(0.0), torch.zeros(3)),
                (yaw(-1.2), torch.tensor([0.0, 0.3, 0.0])), (yaw(0.0), torch.zeros(3))]
    partner_walk = walking_segment(g, (0.5, -0.2), (0.0, -0.05), T + LOOK)
    partner_still = walking_segment(g, (1.0, -0.55), (0.0, 0.0), T + LOOK)

    def goal(i: int, world_xy: tuple[float, float]) -> dict:
        rot, trans = to_world[i]
        canon = (torch.tensor([world_xy[0], world_xy[1], 0.0]) - trans) @ rot
        return {"goal_xy": canon[:2], "nav": NavigationField(floor, world_xy), "face_xy": canon[:2] + 0.1}

    targets = [
        ControlTargets(partner=partner_walk, pass_away=torch.tensor([1.0, 0.0]), field=field, to_world=to_world[0],
                       alpha_hhi=1.0, alpha_hsi=0.7, **goal(0, BOX_GOAL[:2])),
        ControlTargets(partner=partner_still, partner_still=True, field=field, to_world=to_world[1],
                       alpha_hhi=0.5, alpha_hsi=1.0, **goal(1, (1.2, 0.1))),
        ControlTargets(field=field, to_world=to_world[2], alpha_hhi=1.0, alpha_hsi=1.0, **goal(2, (-0.5, 4.0))),
        ControlTargets(alpha_hhi=0.0, alpha_hsi=0.0),
    ]
    keep_joints = (segs + 0.03 * torch.randn(segs.shape, generator=g)) if keep else None
    costs = SegmentCosts(stats, hist_n, targets, cfg, keep=keep_joints)
    return costs, stats.normalize(features(segs))


@pytest.mark.parametrize("keep", [False, True])
@pytest.mark.parametrize("body_share", [0.0, 0.5, 1.0])
def test_numpy_costs_and_gradients_match_autograd(stats, keep, body_share):
    costs, feat_n = batch(stats, keep, body_share)
    x = feat_n.clone().requires_grad_(True)
    with torch.enable_grad():
        reference = costs(x)
        (grad,) = torch.autograd.grad(reference.sum(), x)
    value, fast = costs.value_and_grad(feat_n)
    assert value.shape == (4,) and fast.shape == feat_n.shape
    assert np.allclose(value, reference.detach().numpy(), rtol=1e-4, atol=1e-5)
    for row in range(4):
        scale = float(grad[row].norm())
        assert scale > 0.0
        assert float((fast[row] - grad[row]).norm()) <= 1e-3 * scale, f"row {row}"


def test_every_cost_is_exercised(stats):
    """The batch above takes each cost on some row: partner, passing, facing a still partner, scene, goal with
    walking distance, resting near a goal, facing a far goal, the feet, the floor, a glide past a partner and a
    heavier seam beside a still partner, blended by alpha_hhi 0.5."""
    costs, feat_n = batch(stats, keep=False)
    assert costs.seam_weights.tolist() == [100.0, 200.0, 100.0, 100.0]
    assert costs.partner.rows == [0, 1] and costs.passes.rows == [0] and costs.still == [False, True]
    assert costs.scene.rows == [0, 1, 2] and costs.field is not None and costs.walk is not None
    assert costs.far == [True, False, True]
    value, _ = costs.value_and_grad(feat_n)
    assert (value > 0.0).all()
    from model_runtime.control import glide_cost
    pelvis = costs.stats.denormalize(feat_n)[..., ROOT_T][..., :2]
    glides = glide_cost(pelvis, costs.history_xy, costs.cfg.glide_accel / 100.0)
    assert glides[1] > 0.0 and glides[3] == 0.0
