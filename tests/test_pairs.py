"""Interaction pair builders (stand-ins for Inter-X and LINGO) on a tiny synthetic library: what they guarantee."""
import math

import numpy as np
import pytest
import torch

from model_runtime.data.library import ClipLibrary
from model_runtime.data.mirror import add_mirrors
from model_runtime.data.pairs import (GOAL_LEAD, GOAL_LEAD_MAX, HHI_KINDS, HSI_KINDS, STOPPED_SPEED, ClipCache,
                                      analyse_path, build_hhi_pairs, build_hsi_scenes, clip_joints, facing_xy)
from model_runtime.skeleton import matrix_to_quat, standing_pelvis_height, yaw_matrix

TURN_AT = (0.0, -2.0)      # where the L-shaped walk turns
HEADING0 = (0.0, -1.0)     # its initial heading (the rest body faces -Y)


def _rest_clip(xy: np.ndarray, yaw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rest body whose pelvis follows xy (T, 2) and whose yaw (T,) turns it (0 = facing -Y)."""
    t = len(xy)
    rot = torch.eye(3).repeat(t, 22, 1, 1)
    rot[:, 0] = yaw_matrix(torch.tensor(yaw, dtype=torch.float32))
    pel = np.concatenate((xy, np.full((t, 1), standing_pelvis_height())), 1).astype(np.float32)
    return matrix_to_quat(rot).numpy(), pel


def _straight(frames=40, speed=1.2, start=(3.0, 0.0)):
    xy = np.asarray(start) + np.outer(np.arange(frames) * speed / 10, HEADING0)
    return _rest_clip(xy, np.zeros(frames))


def _l_turn(speed=1.2):
    """Walk 2 m along -Y, turn left 90 degrees on a 0.5 m arc, walk 2 m along +X (facing +X: yaw pi/2)."""
    pts, yaws = [], []
    for s in np.arange(0.0, 2.0, speed / 10):
        pts.append((0.0, -s))
        yaws.append(0.0)
    r = 0.5
    arc = math.pi / 2 * r
    for s in np.arange(0.0, arc, speed / 10):
        a = s / r
        pts.append((r - r * math.cos(a), -2.0 - r * math.sin(a)))
        yaws.append(a)
    for s in np.arange(0.0, 2.0, speed / 10):
        pts.append((r + s, -2.0 - r))
        yaws.append(math.pi / 2)
    return _rest_clip(np.asarray(pts), np.asarray(yaws))


def _standing(frames=30, at=(-3.0, 3.0), yaw=0.0):
    return _rest_clip(np.tile(np.asarray(at, np.float64), (frames, 1)), np.full(frames, yaw))


@pytest.fixture(scope="module")
def lib():
    clips = [("walk", "a person walks forward", _straight()),
             ("turn", "a person walks and turns left", _l_turn()),
             ("wave", "a person waves the right hand", _standing(35, (5.0, 5.0), 0.7)),
             ("stand", "a person bows", _standing(25)),
             ("walk2", "a person walks forward", _straight(50, 1.0, (-4.0, 6.0)))]
    rot = np.concatenate([c[2][0] for c in clips])
    pel = np.concatenate([c[2][1] for c in clips])
    off = np.cumsum([0] + [len(c[2][1]) for c in clips])
    return ClipLibrary([c[0] for c in clips], [c[1] for c in clips], ["cmu"] * len(clips), rot, pel,
                       off.astype(np.int64), [0.0] * len(clips))


def test_path_analysis_finds_the_turn(lib):
    p = analyse_path(clip_joints(lib, 1))
    assert p.turning and abs(math.degrees(p.turn) - 90) < 10
    assert np.allclose(p.h_start, HEADING0, atol=0.05)
    assert np.linalg.norm(p.xy[p.onset] - np.asarray(TURN_AT)) < 0.6
    straight = analyse_path(clip_joints(lib, 0))
    assert straight.moving and not straight.turning
    assert analyse_path(clip_joints(lib, 3)).standing


def test_hhi_pairs_shapes_kinds_and_clearance(lib):
    pairs = build_hhi_pairs(lib, list(range(len(lib))), seed=0, per_clip=3)
    kinds = {(p.ego, p.kind) for p in pairs}
    assert {(0, "approach_face"), (1, "avoid_blocker"), (2, "greet")} <= kinds
    assert all(p.kind in HHI_KINDS for p in pairs)
    for p in pairs:
        ego = clip_joints(lib, p.ego)
        assert p.partner.shape == ego.shape and p.partner.dtype == np.float32
        assert np.isfinite(p.partner).all()
        gap = np.linalg.norm(ego[:, :, None] - p.partner[:, None], axis=-1).min(axis=(1, 2))
        assert gap.min() > 0.3, (p.kind, gap.min())
        # body scale within [0.9, 1.1] of the rest body (its standing height)
        height = p.partner[:, 15, 2].max() - p.partner[:, 10:12, 2].min()
        rest = ego[0, 15, 2] - ego[0, 10:12, 2].min()
        assert 0.85 * rest < height < 1.15 * rest


def test_approach_partner_faces_the_ego_near_the_walk_end(lib):
    pairs = [p for p in build_hhi_pairs(lib, [0, 1, 4], seed=3, per_clip=3) if p.kind == "approach_face"]
    assert pairs
    for p in pairs:
        ego = clip_joints(lib, p.ego)
        to_ego = ego[-1, 0, :2] - p.partner[-1, 0, :2]
        dist = np.linalg.norm(to_ego)
        cos = float(facing_xy(p.partner[-1]) @ (to_ego / dist))
        assert cos > math.cos(math.radians(45))
        assert 0.6 < dist < 2.0
        walk_dir = ego[-1, 0, :2] - ego[-5, 0, :2]
        assert float(walk_dir @ -to_ego) > 0          # beyond the end point, not behind the walker


def test_greet_and_blocker_partners_stand_in_front(lib):
    pairs = build_hhi_pairs(lib, [1, 2], seed=1, per_clip=3)
    greet = next(p for p in pairs if p.kind == "greet")
    ego = clip_joints(lib, greet.ego)
    ahead = greet.partner[:, 0, :2].mean(0) - ego[:, 0, :2].mean(0)
    assert 1.2 < np.linalg.norm(ahead) < 1.8
    assert float(facing_xy(ego[0]) @ ahead) / np.linalg.norm(ahead) > 0.9
    block = next(p for p in pairs if p.kind == "avoid_blocker")
    rel = block.partner[0, 0, :2] - np.asarray(TURN_AT)
    assert abs(rel[0]) < 0.3 and rel[1] < 0          # on the straight-ahead (-Y) line past the turn


def test_real_clips_get_only_the_real_clip_kinds(lib):
    """The dropped "follow" rule (a leader walking ahead on the ego's real walk) stays dropped: a real clip gets
    no follow pair; the follow kind only comes with follow copies whose partner keeps walking (test_hhi_copies)."""
    kinds = {p.kind for p in build_hhi_pairs(lib, list(range(len(lib))), seed=2, per_clip=3)}
    assert kinds == {"approach_face", "avoid_blocker", "greet"}


def test_hsi_scenes_keep_the_real_path_free(lib):
    scenes = build_hsi_scenes(lib, list(range(len(lib))), seed=0, per_clip=3)
    assert {s.ego for s in scenes} == set(range(len(lib)))
    for s in scenes:
        assert s.kind in HSI_KINDS and s.vertices.shape[1] == 3 and s.faces.shape[1] == 3
        joints = clip_joints(lib, s.ego)
        grid = s.grid()
        assert grid is s.grid()                                # cached
        assert not grid.occupied(joints).any(), s.kind         # every joint, every frame
        # the goal: where the clip ends if it stops there, else ahead along its final heading (walks end mid-stride)
        path = analyse_path(joints)
        ahead = s.goal[:2] - joints[-1, 0, :2]
        assert s.goal[2] == 0
        if path.end_speed < STOPPED_SPEED:
            assert np.allclose(ahead, 0.0)
        else:
            assert float(ahead @ path.h_end) == pytest.approx(min(GOAL_LEAD_MAX, GOAL_LEAD * path.end_speed), abs=1e-4)


def test_turning_clip_gets_an_obstacle_on_the_straight_ahead_line(lib):
    scenes = [s for s in build_hsi_scenes(lib, [1], seed=5, per_clip=3) if s.kind == "block_turn"]
    assert scenes
    d = np.arange(0.0, 4.0, 0.02)
    for s in scenes:
        hit = False
        for z in np.arange(0.05, 1.2, 0.05):   # boxes, walls, and table tops at 0.7-0.8 m
            ray = np.stack([np.full_like(d, TURN_AT[0]) + d * HEADING0[0], TURN_AT[1] + d * HEADING0[1],
                            np.full_like(d, z)], -1)
            hit |= bool(s.grid().occupied(ray).any())
        assert hit


def test_builders_are_deterministic_and_seeded(lib):
    ids = list(range(len(lib)))
    a, b = build_hhi_pairs(lib, ids, seed=7), build_hhi_pairs(lib, ids, seed=7)
    c = build_hhi_pairs(lib, ids, seed=8)
    assert [(p.ego, p.kind) for p in a] == [(p.ego, p.kind) for p in b]
    assert all(np.array_equal(p.partner, q.partner) for p, q in zip(a, b))
    assert any(not np.array_equal(p.partner, q.partner) for p, q in zip(a, c) if p.kind == q.kind)
    # a clip's pairs do not depend on which other clips are built with it
    alone = build_hhi_pairs(lib, [1], seed=7)
    assert all(np.array_equal(p.partner, q.partner) for p, q in zip(alone, [p for p in a if p.ego == 1]))
    s1, s2 = build_hsi_scenes(lib, ids, seed=7), build_hsi_scenes(lib, ids, seed=7)
    assert all(np.array_equal(x.vertices, y.vertices) and x.kind == y.kind for x, y in zip(s1, s2))
    s3 = build_hsi_scenes(lib, ids, seed=8)
    assert any(x.vertices.shape != y.vertices.shape or not np.array_equal(x.vertices, y.vertices)
               for x, y in zip(s1, s3))


def test_hhi_pairs_can_be_limited_to_some_kinds(lib):
    everything = build_hhi_pairs(lib, list(range(len(lib))), seed=0, per_clip=3)
    some = build_hhi_pairs(lib, list(range(len(lib))), seed=0, per_clip=3, kinds=("approach_face", "greet"))
    assert some and {p.kind for p in some} <= {"approach_face", "greet"}
    assert {p.ego for p in some} >= {0, 2}          # a walk still gets approach_face, a gesture greet
    assert "avoid_blocker" in {p.kind for p in everything}   # so the filter did leave something out


def test_mirrored_copies_get_the_pair_kinds_of_real_clips(lib):
    """A mirrored copy is a real motion reflected, so it gets its source's pair kinds (it used to get
    turn_to_face, the rule of turned standing clips, whatever its motion)."""
    out, mirrored = add_mirrors(lib, list(range(len(lib))))
    kinds = {(out.names[p.ego], p.kind) for p in build_hhi_pairs(out, mirrored, seed=0, per_clip=3)}
    assert {k for _, k in kinds} == {"approach_face", "avoid_blocker", "greet"}
    assert {("walk#mirror0", "approach_face"), ("turn#mirror0", "avoid_blocker"), ("wave#mirror0", "greet")} <= kinds


def test_clip_cache_for_some_clips_gives_every_clip(lib):
    cache = ClipCache(lib, [1, 3])
    for i in range(len(lib)):
        assert np.allclose(cache.joints(i), clip_joints(lib, i), atol=1e-5)
