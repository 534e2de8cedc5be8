"""Test-time control: each cost's gradient points the right way, the distance field is a distance, steering
lowers the cost, and the alpha sliders switch the interaction costs off."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch

from model_runtime.control import (ControlConfig, ControlTargets, LatentSteer, SegmentCosts, facing_cost,
                                   foot_cost, goal_cost, partner_cost, partner_future, scene_cost, seam_cost)
from model_runtime.distance_field import DistanceField, signed_distance
from model_runtime.features import canonical_frame, feature_joints, to_canonical
from model_runtime.fixtures import approaching_partner, box_scene
from model_runtime.joints import JOINT_INDEX, SOLE_BELOW_FOOT_JOINT
from model_runtime.session import STEERED_STEP_COST, ReactionSession, steps_per_frame
from model_runtime.skeleton import rest_joints, standing_pelvis_height

CFG = ControlConfig()
TOE = JOINT_INDEX["left_foot"]


def standing_body(x: float = 0.0, y: float = 0.0) -> torch.Tensor:
    """(22, 3) rest body standing on the floor at (x, y), facing -Y."""
    return rest_joints() + torch.tensor([x, y, standing_pelvis_height()])


def grad_of(cost_fn, x: torch.Tensor) -> torch.Tensor:
    x = x.clone().requires_grad_(True)
    (g,) = torch.autograd.grad(cost_fn(x), x)
    return g


def test_partner_cost_pushes_the_ego_away_from_the_partner():
    ego = standing_body().expand(4, -1, -1)
    partner = standing_body(0.2, 0.0).expand(4, -1, -1)
    g = grad_of(lambda j: partner_cost(j, partner, 0.35), ego)
    # descending the gradient moves the ego's pelvis toward -x, away from the partner at +x
    assert -g[..., 0, 0].sum() < 0
    assert partner_cost(ego, standing_body(3.0, 0.0).expand(4, -1, -1), 0.35) == 0.0


def test_partner_cost_counts_the_partner_after_the_segment_against_its_last_pose():
    ego = standing_body().expand(4, -1, -1)
    far = standing_body(3.0, 0.0).expand(4, -1, -1)
    later_here = torch.cat((far, standing_body().expand(4, -1, -1)), 0)
    assert partner_cost(ego, far, 0.35) == 0.0
    assert partner_cost(ego, later_here, 0.35) > 0.0


def test_facing_cost_turns_toward_the_target():
    body = standing_body().unsqueeze(0)       # faces -Y
    ahead, behind = torch.tensor([0.0, -2.0]), torch.tensor([0.0, 2.0])
    assert facing_cost(body, ahead) < 1e-3 < facing_cost(body, behind)


def test_scene_distance_field_matches_an_exact_transform_and_pushes_out_of_a_box():
    scipy_ndimage = pytest.importorskip("scipy.ndimage")
    occ = np.zeros((30, 30, 20), bool)
    occ[10:18, 12:20, 0:10] = True
    sdf = signed_distance(occ, 0.05, reach=0.5)
    exact = scipy_ndimage.distance_transform_edt(~occ) * 0.05 - scipy_ndimage.distance_transform_edt(occ) * 0.05
    # the exact transform counts an inside cell's distance to the nearest free cell; so do we (as negative)
    outside_near = (exact > 0) & (exact < 0.45)
    assert np.abs(sdf[outside_near] - exact[outside_near]).max() < 1e-5
    assert (sdf[occ] < 0).all() and (sdf[~occ] > 0).all()

    field = DistanceField(box_scene())          # a 0.8 m box spanning x -0.4..0.4, y -1.9..-1.1, z 0..0.8
    inside = torch.tensor([[0.3, -1.5, 0.4]])
    outside = torch.tensor([[0.6, -1.5, 0.4]])
    assert float(field(inside)) < 0 < float(field(outside)) < 0.3
    g = grad_of(lambda p: scene_cost(p, field, 0.12), inside)
    assert -g[0, 0] > 0                          # out through the nearest face (+x)
    assert float(field(torch.tensor([[50.0, 50.0, 1.0]]))) == field.reach   # beyond the grid: far


def test_goal_cost_pulls_toward_the_goal_then_holds_still_on_it():
    start = torch.zeros(2)
    goal = torch.tensor([0.0, -3.0])
    pelvis = torch.zeros(8, 3)
    g = grad_of(lambda p: goal_cost(p, start, goal, CFG), pelvis)
    assert -g[-1, 1] < 0                         # the last frame is pulled toward -Y, where the goal is
    wandering = torch.zeros(8, 3)
    wandering[:, 0] = torch.linspace(0.0, 0.4, 8)
    on_goal = goal_cost(torch.zeros(8, 3), start, torch.tensor([0.05, 0.0]), CFG)
    moving = goal_cost(wandering, start, torch.tensor([0.05, 0.0]), CFG)
    assert on_goal < moving                      # near the goal, standing still on it costs least


def test_foot_cost_stops_a_planted_toe_sliding_and_lifts_joints_out_of_the_floor():
    body = standing_body()
    frames = body.expand(4, -1, -1).clone()
    frames[:, TOE, 0] = torch.tensor([0.0, 0.05, 0.10, 0.15])       # a planted toe sliding along +x
    g = grad_of(lambda j: foot_cost(j, body, CFG), frames)
    assert -g[-1, TOE, 0] < 0                                       # pulled back against the slide
    sunk = body.expand(2, -1, -1).clone()
    sunk[:, TOE, 2] = SOLE_BELOW_FOOT_JOINT - 0.03                  # sole 3 cm under the floor
    g = grad_of(lambda j: foot_cost(j, body, CFG), sunk)
    assert -g[:, TOE, 2].sum() > 0                                  # pushed up


def test_foot_cost_fixes_a_slide_with_the_legs_not_by_slowing_the_body():
    body = standing_body()
    frames = body.expand(4, -1, -1).clone()
    frames[:, :, 1] += torch.tensor([0.1, 0.2, 0.3, 0.4]).view(4, 1)   # the whole body moving along +y ...
    frames[:, TOE, 1] = body[TOE, 1]                                  # ... but for one toe
    frames[1:, TOE, 1] += torch.tensor([0.02, 0.04, 0.06])            # which slides a little while planted
    g = grad_of(lambda j: foot_cost(j, body, CFG), frames)
    assert g[:, TOE, 1].abs().sum() > 0                               # the toe is pulled back against its slide
    assert torch.allclose(g[..., :2].sum(-2), torch.zeros(4, 2), atol=1e-6)   # the body as a whole is not
    whole = ControlConfig(skate_body_share=1.0)
    g = grad_of(lambda j: foot_cost(j, body, whole), frames)
    assert g[:, :, 1].sum() > 0                                       # share 1: slowing the body lowers it too


def test_partner_future_extrapolates_a_walk_and_spots_a_standing_partner():
    walk = torch.as_tensor(approaching_partner(10, start=4.0, stop=1.0, speed=1.0))
    future, still = partner_future(walk, torch.ones(10, dtype=torch.bool), lead=1, frames=3, cfg=CFG)
    step = float(walk[-1, 0, 1] - walk[-2, 0, 1])
    assert torch.allclose(future[0, 0, 1], walk[-1, 0, 1] + step, atol=1e-4) and not still
    standing = torch.as_tensor(approaching_partner(40, start=4.0, stop=1.0, speed=1.0))[-10:]   # stopped 1 m away
    _, still = partner_future(standing, torch.ones(10, dtype=torch.bool), lead=1, frames=3, cfg=CFG)
    assert still
    none, _ = partner_future(walk, torch.zeros(10, dtype=torch.bool), lead=1, frames=3, cfg=CFG)
    assert none is None


def _steer_near_a_partner(m, cfg):
    s = ReactionSession(m, text="walk", seed=0, control=False)
    s.reset()
    hist_world = s.history_world_features()
    rot, trans = canonical_frame(feature_joints(hist_world[0]))
    hist_n = m.stats.normalize(to_canonical(hist_world, rot, trans)).unsqueeze(0)
    partner = standing_body(0.1, 0.0).expand(m.cfg.future + 4, -1, -1)
    costs = SegmentCosts(m.stats, hist_n, ControlTargets(partner=partner, alpha_hhi=1.0), cfg)
    z = torch.randn(1, m.cfg.latent_tokens, m.cfg.latent_dim, generator=torch.Generator().manual_seed(0))
    return LatentSteer(m, hist_n, costs, cfg), z


def test_steering_lowers_the_segment_cost(tiny_model):
    m = tiny_model
    steer, z = _steer_near_a_partner(m, CFG)
    costs, hist_n = steer.costs, steer.hist
    with torch.no_grad():
        before = float(costs(m.decode(hist_n, z)))
        after = float(costs(m.decode(hist_n, steer(z))))
    assert after < before


def test_seam_cost_is_zero_for_a_steady_motion_and_grows_with_a_jump(tiny_model):
    m = tiny_model
    hist = torch.zeros(1, 2, m.cfg.feature_dim)
    hist[0, 1, 144:210] = 0.1             # joints moved 0.1 m along every axis between the two history frames
    costs = SegmentCosts(m.stats, m.stats.normalize(hist), ControlTargets(), replace(CFG, skate_weight=0.0, keep_weight=0.0),
                         keep=torch.zeros(m.cfg.future, 22, 3))
    steady = torch.zeros(1, m.cfg.future, m.cfg.feature_dim)
    steady[0, :, 144:210] = 0.1 * torch.arange(2, 2 + m.cfg.future).view(-1, 1)
    jumped = steady.clone()
    jumped[0, 0, 144:210] += 0.3
    assert float(costs(m.stats.normalize(steady))) < 1e-6 < float(costs(m.stats.normalize(jumped)))
    g = grad_of(lambda j: seam_cost(j, torch.full((22, 3), 0.1), torch.zeros(22, 3)), feature_joints(jumped[0]))
    assert -g[0].sum() < 0                # the jumped first frame is pulled back toward the steady path


def test_glide_guard_takes_back_half_of_a_step_that_made_a_glide(tiny_model, monkeypatch):
    """With glide_guard, a step after which the pelvis steps faster than the guard (and 0.5 m/s faster than before
    it) is replaced by half of it, from where it started; settle() checks the last step the same way."""
    cfg = replace(CFG, glide_guard=3.0)
    steer, z = _steer_near_a_partner(tiny_model, cfg)
    plain, _ = _steer_near_a_partner(tiny_model, replace(CFG, glide_guard=0.0))
    peaks = iter([1.0, 5.0, 1.2])                     # the pelvis's peak speed at each decode, m/s
    monkeypatch.setattr(LatentSteer, "_peak_speed", lambda self, decoded: torch.tensor([next(peaks)]))
    first = steer(z)
    assert torch.equal(first, plain(z))              # nothing to check before the first step
    taken = z - first
    second = steer(first)                            # the first step glided (5 m/s): back, half of it
    assert torch.allclose(second, z - 0.5 * taken)
    third = steer.settle(second)                     # half the step does not glide (1.2 m/s): kept
    assert torch.equal(third, second)
    peaks = iter([1.0, 1.3])
    monkeypatch.setattr(LatentSteer, "_peak_speed", lambda self, decoded: torch.tensor([next(peaks)]))
    steer, z = _steer_near_a_partner(tiny_model, cfg)
    moved = steer(z)
    assert torch.equal(steer.settle(moved), moved)   # no glide: the step stands


def test_without_the_glide_guard_settle_changes_nothing(tiny_model):
    steer, z = _steer_near_a_partner(tiny_model, replace(CFG, glide_guard=0.0))
    moved = steer(z)
    assert steer.settle(moved) is moved


def test_glide_cost_is_zero_for_walking_and_turning_and_grows_with_a_glide():
    """Accelerations under the limit cost nothing; a 0.3 m jump between two frames costs its excess at both of its
    accelerations (in, then out), and its gradient pulls the jumped frames back."""
    from model_runtime.control import glide_cost
    limit = 0.1                                                       # 10 m/s^2 at 10 fps
    history = torch.tensor([[0.0, 0.0], [0.0, -0.12]])
    walk = torch.stack([torch.zeros(8), -0.12 * torch.arange(2, 10)], -1)
    turning = walk.clone()
    turning[:, 0] = 0.01 * torch.arange(1, 9) ** 2 / 2               # 1 m/s^2 sideways
    assert float(glide_cost(walk, history, limit)) == 0.0 == float(glide_cost(turning, history, limit))
    glided = walk.clone()
    glided[4:, 0] += 0.3
    assert float(glide_cost(glided, history, limit)) == pytest.approx(2 * 0.2 ** 2, rel=1e-5)
    x = glided.clone().requires_grad_(True)
    (g,) = torch.autograd.grad(glide_cost(x, history, limit), x)
    assert g[4, 0] > 0.0 > g[3, 0]           # the glide's two sides are pulled toward each other


def test_steps_per_frame_spreads_every_step_and_evens_out_steered_ones():
    assert steps_per_frame(10, 8, 0) in ((1, 1, 1, 1, 1, 1, 2, 2), (0, 1, 1, 1, 1, 2, 2, 2))
    split = steps_per_frame(18, 8, 12)          # 6 plain steps, then 12 steered ones (2.5 plain steps each)
    costs = [1.0] * 6 + [STEERED_STEP_COST] * 12
    loads, i = [], 0
    for n in split:
        loads.append(sum(costs[i:i + n]))
        i += n
    assert i == 18 and max(loads) <= 2 * STEERED_STEP_COST      # never more than two steered steps a frame
    assert sum(steps_per_frame(1000, 64, 4)) == 1000


def test_alpha_zero_applies_no_partner_scene_or_goal_cost(tiny_model):
    """With control on, alpha 0 gives the frames of a run without partner, scene and goal; alpha 1 does not."""
    def run(alpha, with_cues):
        s = ReactionSession(tiny_model, text="walk", seed=5, alpha={"hhi": alpha, "hsi": alpha}, control=True,
                            scene=box_scene() if with_cues else None)
        s.reset()
        partner = approaching_partner(18, start=1.5, stop=0.3)
        return np.stack([s.step(partner=partner[i] if with_cues else None,
                                goal=(0.0, -2.0, 0.0) if with_cues else None).joints for i in range(18)])
    assert np.array_equal(run(0.0, True), run(0.0, False))
    assert not np.allclose(run(1.0, True), run(1.0, False))


def test_control_on_changes_the_motion_and_stays_deterministic(tiny_model):
    def run(control):
        s = ReactionSession(tiny_model, text="walk", seed=2, control=control)
        s.reset()
        partner = approaching_partner(18, start=1.5, stop=0.2)
        return np.stack([s.step(partner=partner[i], goal=(0.0, 2.0, 0.0)).joints for i in range(18)])
    on = run(True)
    assert np.array_equal(on, run(True))
    assert not np.allclose(on, run(False))


def test_bad_control_config_is_one_line(tiny_model):
    from model_runtime.errors import InputError
    with pytest.raises(InputError, match="step_size"):
        ControlConfig(step_size=-1.0)
    with pytest.raises(InputError, match="control_config"):
        ReactionSession(tiny_model, control=False).control_config = {"step_size": 1}
