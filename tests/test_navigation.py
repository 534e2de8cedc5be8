"""The walking-distance field that test-time control measures progress to a goal with."""
from __future__ import annotations

import numpy as np
import torch

from model_runtime.control import ControlConfig, goal_cost
from model_runtime.navigation import FloorMap, NavigationField, solve_eikonal
from model_runtime.voxel import OccupancyGrid


def wall_with_door(door: float = 1.0) -> OccupancyGrid:
    """A 0.15 m thick, 1.5 m high wall along x at y = 2 m, from x = -3 to 3, with a `door` m gap at x = 1."""
    vs = 0.05
    xs = -3.0 + (np.arange(120) + 0.5) * vs
    occ = np.zeros((120, 3, 30), bool)
    occ[:, :, :] = (np.abs(xs - 1.0) > door / 2)[:, None, None]
    return OccupancyGrid((-3.0, 1.925, 0.0), vs, occ)


def box(centre=(0.0, 2.0), half=0.5) -> OccupancyGrid:
    vs = 0.05
    n = int(round(2 * half / vs))
    return OccupancyGrid((centre[0] - half, centre[1] - half, 0.0), vs, np.ones((n, n, 20), bool))


def test_eikonal_solution_is_the_straight_distance_on_open_floor():
    u = solve_eikonal(np.ones((41, 41)), (20.5, 20.5), 0.1)
    i, j = np.meshgrid(np.arange(41), np.arange(41), indexing="ij")
    exact = np.hypot(i - 20, j - 20) * 0.1
    # first-order upwind: within a few per cent of the straight distance in every direction
    assert np.abs(u - exact).max() < 0.05 * exact.max()
    assert u[20, 20] == 0.0


def test_walking_distance_goes_through_the_door_and_heads_for_it():
    nav = NavigationField(FloorMap(wall_with_door()), (0.0, 4.0))
    assert nav.blocks
    start = np.array([0.0, 0.0])
    straight = 4.0
    through_door = np.hypot(1.0, 2.0) * 2            # 0,0 -> door at (1, 2) -> 0,4
    walked = float(nav(torch.tensor(start, dtype=torch.float32)))
    assert straight + 0.2 < walked < through_door * 1.15
    heading = nav.heading(start)
    assert heading[0] > 0.3 and heading[1] > 0.3     # toward the door up and to the right, not straight up
    # the goal itself: zero up to the bilinear sampling of a cone (at most half a 0.1 m cell's diagonal);
    # a metre from it: about the straight distance
    assert float(nav(torch.tensor([0.0, 4.0]))) < 0.075
    assert abs(float(nav(torch.tensor([0.0, 5.0]))) - 1.0) < 0.1


def test_walking_distance_is_continuous_beyond_the_map_and_has_gradients():
    nav = NavigationField(FloorMap(box()), (0.0, 4.0))
    p = torch.tensor([[30.0, -20.0], [0.0, 0.0]], requires_grad=True)
    d = nav(p)
    assert float(d[0].detach()) > 30.0 and torch.isfinite(d).all()
    d.sum().backward()
    assert torch.isfinite(p.grad).all() and float(p.grad.norm()) > 0
    # an open floor (the box far away from the way) measures like the straight line
    far_box = NavigationField(FloorMap(box(centre=(8.0, 8.0))), (0.0, 4.0))
    assert abs(float(far_box(torch.zeros(2))) - 4.0) < 0.3


def test_goal_cost_with_walking_distance_steers_around_a_box_in_the_way():
    nav = NavigationField(FloorMap(box(centre=(0.0, 2.0), half=0.5)), (0.0, 4.0))
    start = torch.zeros(2)
    goal = torch.tensor([0.0, 4.0])
    pelvis = torch.zeros(8, 3)
    pelvis[:, 1] = torch.linspace(0.1, 0.9, 8)
    pelvis[:, 0] = 0.05                              # a little right of the line through the box
    pelvis.requires_grad_(True)
    goal_cost(pelvis, start, goal, ControlConfig(), walk=nav).backward()
    pull = -pelvis.grad[-1, :2]
    assert pull[0] > 0.2 * abs(float(pull[1]))        # sideways around the box, not only into it
    # heading from the start also leaves the straight line to go round
    assert abs(nav.heading(np.array([0.05, 0.0]))[0]) > 0.2


def test_waypoint_walks_along_the_field_and_stops_at_the_goal():
    nav = NavigationField(FloorMap(wall_with_door()), (0.0, 4.0))
    w = nav.waypoint(np.array([0.0, 0.0]), 1.5)
    assert 1.2 < float(np.hypot(*w)) < 1.6 and w[0] > 0.3
    assert np.allclose(nav.waypoint(np.array([0.0, 3.9]), 1.5), (0.0, 4.0))


def test_numpy_sampling_matches_the_differentiable_one():
    nav = NavigationField(FloorMap(wall_with_door()), (0.0, 4.0))
    rng = np.random.default_rng(0)
    pts = rng.uniform(-6.0, 8.0, (50, 2))
    torch_vals = nav(torch.tensor(pts, dtype=torch.float32)).numpy()
    np_vals = np.array([nav._sample(p) for p in pts])
    assert np.allclose(torch_vals, np_vals, atol=1e-3)
