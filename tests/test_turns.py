"""Synthetic in-place turns (model_runtime.data.turns) and the turn_to_face HHI pairs built on them."""
import math

import numpy as np
import pytest
import torch

from model_runtime.data.library import ClipLibrary
from model_runtime.data.pairs import build_hhi_pairs, clip_joints, facing_xy
from model_runtime.data.turns import TURN_SPEED, add_pivot_turns, pivot_turn, turn_profile
from model_runtime.skeleton import yaw_matrix
from synthetic import library_of, rigid_clip


@pytest.fixture(scope="module")
def lib():
    stand = np.tile([[2.0, 1.0]], (40, 1)) + np.random.default_rng(0).normal(0, 0.01, (40, 2))
    walk = np.outer(np.arange(40) * 0.12, [0.0, -1.0])
    return library_of([("wave", "a person waves the right hand", "cmu", rigid_clip(stand, 0.3)),
                       ("walk", "a person walks forward", "cmu", rigid_clip(walk, 0.0)),
                       ("bow", "a person bows", "bandai", rigid_clip(np.tile([[-3.0, 0.0]], (30, 1)), -1.0))])


def test_turn_profile_is_smooth_and_reaches_the_angle():
    y = turn_profile(30, onset=3, angle=math.pi / 2)
    assert np.all(y[:4] == 0) and y[-1] == pytest.approx(math.pi / 2)
    assert np.all(np.diff(y) >= -1e-12)
    duration = math.pi / 2 / TURN_SPEED * 10                 # frames
    assert np.argmax(y >= math.pi / 2 - 1e-9) == pytest.approx(3 + duration, abs=1)


def test_pivot_turn_rotates_the_body_rigidly_about_the_first_pelvis(lib):
    a, b = lib.offsets[0], lib.offsets[1]
    rot, pel = lib.rotations[a:b], lib.pelvis[a:b]
    yaw = turn_profile(len(pel), 2, -2.0)
    rot2, pel2 = pivot_turn(rot, pel, yaw)
    assert np.allclose(rot2[:, 1:], rot[:, 1:])                  # every joint but the root: the real clip
    tmp = ClipLibrary(["x", "y"], ["", ""], ["cmu"] * 2, np.concatenate((rot, rot2)), np.concatenate((pel, pel2)),
                      np.array([0, len(pel), 2 * len(pel)]), [])
    j0, j1 = clip_joints(tmp, 0), clip_joints(tmp, 1)
    r = yaw_matrix(torch.tensor(yaw)).numpy()
    pivot = np.array([pel[0, 0], pel[0, 1], 0.0])
    expect = np.einsum("tij,tkj->tki", r, j0 - pivot) + pivot
    assert np.abs(j1 - expect).max() < 1e-4
    turned = math.degrees(math.atan2(np.cross(facing_xy(j0[-1]), facing_xy(j1[-1])),
                                     float(facing_xy(j0[-1]) @ facing_xy(j1[-1]))))
    assert turned == pytest.approx(math.degrees(-2.0), abs=0.5)


def test_only_standing_clips_get_copies_named_after_their_source(lib):
    out, new = add_pivot_turns(lib, [0, 1, 2], seed=0, per_clip=2)
    assert out.names[:3] == lib.names and np.array_equal(out.rotations[:len(lib.rotations)], lib.rotations)
    assert [out.names[i] for i in new] == ["wave#turn0", "wave#turn1", "bow#turn0", "bow#turn1"]
    assert [out.sources[i] for i in new] == ["cmu", "cmu", "bandai", "bandai"]        # licence follows the source
    assert all(out.captions[i].startswith("a person turns ") and "to face someone" in out.captions[i] for i in new)
    assert "and waves the right hand" in out.captions[new[0]]
    # a copy falls on its source's side of the held-out split
    assert all(out.is_held_out(i) == out.is_held_out(out.names.index(out.names[i].split("#")[0])) for i in new)
    again, _ = add_pivot_turns(lib, [0, 1, 2], seed=0, per_clip=2)
    assert np.array_equal(again.rotations, out.rotations)                            # deterministic


def test_turned_clips_get_a_partner_where_the_turn_ends(lib):
    out, new = add_pivot_turns(lib, [0, 1, 2], seed=1)
    pairs = build_hhi_pairs(out, list(range(len(out))), seed=0, per_clip=1)
    turn = [p for p in pairs if p.kind == "turn_to_face"]
    assert sorted(p.ego for p in turn) == new and all(p.ego in new for p in turn)
    for p in turn:
        ego = clip_joints(out, p.ego)
        to_partner = p.partner[-1, 0, :2] - ego[-1, 0, :2]
        dist = float(np.linalg.norm(to_partner))
        assert 0.9 < dist < 2.6
        assert float(facing_xy(ego[-1]) @ to_partner) / dist > math.cos(math.radians(15))   # turned to face it
        assert float(facing_xy(ego[0]) @ to_partner) / dist < math.cos(math.radians(40))    # not at the start
        assert float(facing_xy(p.partner[-1]) @ -to_partner) / dist > 0.9                   # it faces the ego
