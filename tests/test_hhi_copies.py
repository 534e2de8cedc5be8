"""HHI copies built from real clips (avoid, step aside, arrive and face, follow) and their pairs, on hand-made
clips: what each kind guarantees, and that copies keep their source's split and licence."""
import math

import numpy as np
import pytest
import torch

from model_runtime.data.avoidance import KEEP_RIGHT_WITHIN, YIELD_RULE
from model_runtime.data.detours import bend_pelvis
from model_runtime.data.face_arrivals import ARRIVE_DISTANCE, ROOM_DISTANCE, ROOM_START_S
from model_runtime.data.walk_aside import LINE_OFFSET, ONSET_FRAMES
from model_runtime.data.hhi_copies import add_hhi_copies
from model_runtime.data.library import derived_kind, held_out, is_derived, source_name
from model_runtime.data.new_clips import partner_clip_name
from model_runtime.data.stretches import clearance, straight_caption
from model_runtime.data.pairs import MIN_CLEARANCE, build_hhi_pairs, clip_joints, facing_xy, min_clearance
from model_runtime.data.pairs.hhi import AVOID_CLEARANCE, FOLLOW_MIN_GAP
from model_runtime.skeleton import (JOINT_INDEX, axis_angle_to_matrix, matrix_to_quat, quat_to_matrix,
                                    standing_pelvis_height, yaw_matrix)
from synthetic import library_of, walking_clip

# clip names on each side of the held-out split; the style in a walk's caption tells its side, and every clip
# has a dataset tag (licence) of its own, so that a copy's tag tells where its motion comes from
HELD = [n for n in (f"walk_h{k}" for k in range(400)) if held_out(n)][:3]
TRAIN = [n for n in (f"walk_t{k}" for k in range(400)) if not held_out(n)][:6]
HELD_STAND = [n for n in (f"stand_h{k}" for k in range(400)) if held_out(n)][:2]
TRAIN_STAND = [n for n in (f"stand_t{k}" for k in range(400)) if not held_out(n)][:3]
STYLE = {False: "happily", True: "sadly"}
SPEEDS = (1.2, 1.9, 0.75, 1.0, 1.4, 1.1)   # m/s: the fast and slow ones are re-timed as partners


def _standing(frames: int, at: np.ndarray, yaw: float) -> tuple[np.ndarray, np.ndarray]:
    """A body standing at `at` facing `yaw` with its arms down, the right one swinging a little."""
    aa = torch.zeros(frames, 22, 3)
    aa[:, JOINT_INDEX["left_shoulder"], 1] = 1.3
    aa[:, JOINT_INDEX["right_shoulder"], 1] = -1.3 + 0.2 * torch.sin(torch.arange(frames) / 3.0)
    rot = axis_angle_to_matrix(aa)
    rot[:, 0] = yaw_matrix(torch.full((frames,), yaw)) @ rot[:, 0]
    pel = np.concatenate((np.tile(at, (frames, 1)), np.full((frames, 1), standing_pelvis_height())), 1)
    return matrix_to_quat(rot).numpy(), pel.astype(np.float32)


def _library():
    rng = np.random.default_rng(0)
    clips = []
    for k, name in enumerate(TRAIN + HELD):
        side = name in HELD
        walk = walking_clip(60, SPEEDS[k % len(SPEEDS)], 0.0, start=tuple(rng.uniform(-3, 3, 2)),
                            yaw0=float(rng.uniform(-3, 3)), phase=float(rng.uniform(0, 6)))
        clips.append((name, f"a person walks forward, {STYLE[side]}", f"walkset{k}", walk))
    for k, name in enumerate(TRAIN_STAND + HELD_STAND):
        stand = _standing(45, rng.uniform(-3, 3, 2), float(rng.uniform(-3, 3)))
        clips.append((name, "a person waves the right hand", f"standset{k}", stand))
    return library_of(clips)


@pytest.fixture(scope="module")
def built():
    lib = _library()
    out, new = add_hhi_copies(lib, list(range(len(lib))), seed=3)
    pairs = build_hhi_pairs(out, new, seed=3)
    return lib, out, new, pairs


def _of(built, kind):
    pairs = [p for p in built[3] if p.kind == kind]
    assert pairs, kind
    return pairs


def _root_yaw(lib, i):
    a, b = lib.offsets[i], lib.offsets[i + 1]
    r = quat_to_matrix(torch.from_numpy(lib.rotations[a:b, 0].astype(np.float64))).numpy()
    return np.arctan2(r[:, 1, 0], r[:, 0, 0])


def _unbent(lib, i):
    """(un-bent joints, un-bent pelvis xy, bent pelvis xy) of an avoid copy of a straight synthetic walk, whose
    own root yaw is constant: the swerve is the copy's root yaw change."""
    swerve = np.angle(np.exp(1j * (_root_yaw(lib, i) - _root_yaw(lib, i)[0])))
    j = clip_joints(lib, i).astype(np.float64)
    pel = lib.pelvis[lib.offsets[i]:lib.offsets[i + 1]].astype(np.float64)
    back = bend_pelvis(pel, -swerve)
    c, s = np.cos(-swerve)[:, None], np.sin(-swerve)[:, None]
    rel = j - pel[:, None]
    rel[..., 0], rel[..., 1] = c * rel[..., 0] - s * rel[..., 1], s * rel[..., 0] + c * rel[..., 1]
    return rel + back[:, None], back[:, :2], pel[:, :2]


def _left(v):
    return np.array([-v[1], v[0]])


def test_every_kind_is_made_and_paired(built):
    lib, out, new, pairs = built
    kinds = {derived_kind(out.names[i]) for i in new}
    assert {"avoid", "stepaside", "arriveface", "follow", "turn"} <= kinds
    assert {p.kind for p in pairs} >= {"avoid_walker", "step_aside", "arrive_face", "follow", "turn_to_face"}
    partners = [i for i in range(len(lib), len(out)) if derived_kind(out.names[i]).endswith("partner")]
    assert partners and not set(partners) & set(new)                       # partner clips are never egos


def test_avoid_pairs_keep_clearance_and_would_have_collided(built):
    out = built[1]
    for p in _of(built, "avoid_walker"):
        ego = clip_joints(out, p.ego)
        assert min_clearance(ego, p.partner) >= AVOID_CLEARANCE
        unbent, path, _ = _unbent(out, p.ego)
        assert np.linalg.norm(path - p.partner[:, 0, :2], axis=1).min() <= 0.3 + 1e-3
        assert min_clearance(unbent, p.partner) < AVOID_CLEARANCE
        speed = np.linalg.norm(p.partner[-1, 0, :2] - p.partner[0, 0, :2]) * 10 / (len(ego) - 1)
        assert 0.78 <= speed <= 1.62                                      # partners re-timed to walking pace


def test_avoid_bend_goes_away_from_the_partner(built):
    out = built[1]
    for p in _of(built, "avoid_walker"):
        _, path, bent = _unbent(out, p.ego)
        partner = p.partner[:, 0, :2]
        heading = (path[-1] - path[0]) / np.linalg.norm(path[-1] - path[0])
        t = int(np.argmin(np.linalg.norm(bent - partner, axis=1)))
        moved = float((bent[t] - path[t]) @ _left(heading))
        assert abs(moved) > 0.1
        assert moved * float((partner[t] - bent[t]) @ _left(heading)) < 0      # the partner passes on the other side
        walking = (partner[-1] - partner[0]) / np.linalg.norm(partner[-1] - partner[0])
        across = float(walking @ _left(heading))
        if abs(across) >= 0.5:                                                # a crossing partner: passed behind
            assert np.sign(moved) == -np.sign(across)


def test_step_aside_moves_the_ego_off_the_partners_line(built):
    out = built[1]
    for p in _of(built, "step_aside"):
        ego = out.pelvis[out.offsets[p.ego]:out.offsets[p.ego + 1], :2].astype(np.float64)
        partner = p.partner[:, 0, :2].astype(np.float64)
        line = (partner[-1] - partner[0]) / np.linalg.norm(partner[-1] - partner[0])

        def off_line(x):
            return abs(float((x - partner[0]) @ _left(line)))
        assert off_line(ego[0]) <= 0.2 + 1e-3                             # it walks through the ego's spot
        assert off_line(ego[-1]) >= 0.5 + off_line(ego[0]) - 1e-3         # the ego stepped off its line
        dist = np.linalg.norm(partner - ego[0], axis=1)
        still = ((dist > 3.0 + 1e-3) | (np.arange(len(dist)) < 4)) & (np.arange(len(dist)) < np.argmin(dist))
        assert np.allclose(ego[still], ego[0], atol=1e-4)                 # standing until it is near (and 0.4 s)
        assert min_clearance(clip_joints(out, p.ego), p.partner) >= AVOID_CLEARANCE
        assert out.captions[p.ego].startswith("a person steps aside and ")


@pytest.fixture(scope="module")
def yielding():
    lib = _library()
    out, new = add_hhi_copies(lib, list(range(len(lib))), seed=3, step_rule=YIELD_RULE, face_arrivals=True)
    return lib, out, new, build_hhi_pairs(out, new, seed=3)


def test_yield_rule_steps_away_from_the_partners_line_when_it_would_arrive(yielding):
    lib, out = yielding[0], yielding[1]
    pairs = _of(yielding, "step_aside")
    for p in pairs:
        ego = out.pelvis[out.offsets[p.ego]:out.offsets[p.ego + 1], :2].astype(np.float64)
        partner = p.partner[:, 0, :2].astype(np.float64)
        line = (partner[-1] - partner[0]) / np.linalg.norm(partner[-1] - partner[0])

        def side(x):   # + : on the partner's left of its line
            return float((x - partner[0]) @ _left(line))
        start, end = side(ego[0]), side(ego[-1])
        assert abs(start) <= 0.3 + 1e-3                                   # it walks (nearly) through the ego's spot
        if abs(start) >= KEEP_RIGHT_WITHIN + 1e-3:
            assert np.sign(end) == np.sign(start) and abs(end) >= abs(start) + 0.5 - 1e-3   # away from the line
        else:
            assert end <= -0.5 + 1e-3 - abs(start)                          # keeps to the partner's right
        # still until the partner is at most YIELD_RULE.start_s[1] (and a frame) from the ego's spot
        speed = np.linalg.norm(np.diff(partner, axis=0), axis=1).mean() * 10.0
        arrive = np.linalg.norm(partner - ego[0], axis=1) / speed
        moving = np.flatnonzero(np.linalg.norm(ego - ego[0], axis=1) > 1e-4)
        assert len(moving) and arrive[moving[0]] <= YIELD_RULE.start_s[1] + 0.1 + 1e-3
        assert min_clearance(clip_joints(out, p.ego), p.partner) >= AVOID_CLEARANCE
        assert out.captions[p.ego] == lib.captions[lib.names.index(source_name(out.names[p.ego]))]


def test_a_partner_walks_up_and_stops_the_standing_ego_makes_room_then_faces_it(yielding):
    lib, out = yielding[0], yielding[1]
    pairs = _of(yielding, "face_arrival")
    for p in pairs:
        ej = clip_joints(out, p.ego).astype(np.float64)
        partner = p.partner.astype(np.float64)
        spot = ej[0, 0, :2]
        speed = np.linalg.norm(np.diff(partner[:, 0, :2], axis=0), axis=1) * 10.0
        assert speed[:5].mean() >= 0.5 and speed[-3:].max() <= 0.2           # walks up, then stands
        rest = partner[-1, 0, :2]
        assert ARRIVE_DISTANCE[0] - 0.15 <= np.linalg.norm(rest - spot) <= ARRIVE_DISTANCE[1] + 0.15
        to_ego = (spot - rest) / np.linalg.norm(spot - rest)
        assert facing_xy(partner[-1:])[0] @ to_ego >= math.cos(math.radians(30))    # it faces the ego
        walk = (rest - partner[0, 0, :2]) / np.linalg.norm(rest - partner[0, 0, :2])
        right = np.array([walk[1], -walk[0]])
        assert (ej[-1, 0, :2] - spot) @ right >= ROOM_DISTANCE[0] - 0.05        # made room, to the walker's right
        to_partner = (partner[-1, 0, :2] - ej[-1, 0, :2]) / np.linalg.norm(partner[-1, 0, :2] - ej[-1, 0, :2])
        assert facing_xy(ej[-1:])[0] @ to_partner >= math.cos(math.radians(25))   # and ends facing it
        # still until the walker is at most ROOM_START_S[1] s (and a frame) from its spot at the pace it came on at
        pace = np.linalg.norm(partner[5, 0, :2] - partner[0, 0, :2]) * 10.0 / 5.0
        moving = np.flatnonzero(np.linalg.norm(ej[:, 0, :2] - spot, axis=1) > 0.02)
        assert np.linalg.norm(partner[moving[0], 0, :2] - spot) / pace <= ROOM_START_S[1] + 0.1
        assert min_clearance(ej, partner) >= AVOID_CLEARANCE
        assert out.captions[p.ego] == lib.captions[lib.names.index(source_name(out.names[p.ego]))]


@pytest.fixture(scope="module")
def walking_aside():
    lib = _library()
    out, new = add_hhi_copies(lib, list(range(len(lib))), seed=3, walk_aside=True)
    return lib, out, new, build_hhi_pairs(out, new, seed=3)


def test_walk_aside_copies_turn_and_walk_off_the_walkers_line(walking_aside):
    lib, out, new = walking_aside[0], walking_aside[1], walking_aside[2]
    assert not any("#stepaside" in out.names[i] for i in new)           # they replace the sliding copies
    pairs = [p for p in _of(walking_aside, "step_aside") if "#walkaside" in out.names[p.ego]]
    assert pairs
    for p in pairs:
        ej = clip_joints(out, p.ego).astype(np.float64)
        partner = p.partner[:, 0, :2].astype(np.float64)
        line = (partner[-1] - partner[0]) / np.linalg.norm(partner[-1] - partner[0])

        def side(x):   # + : on the walker's left of its line
            return float((x - partner[0]) @ _left(line))
        start, end = side(ej[0, 0, :2]), side(ej[-1, 0, :2])
        assert abs(start) <= LINE_OFFSET[1] + 0.05                          # it walks at the ego's spot
        away = np.sign(end) == np.sign(start) and abs(end) >= abs(start) + 0.3
        right = end <= -0.3 + abs(start)
        # the line's drawn offset decides the rule; the ego's first pelvis sits within a few cm of where it was drawn
        if abs(start) >= KEEP_RIGHT_WITHIN + 0.05:
            assert away                                                         # away from the line
        elif abs(start) <= KEEP_RIGHT_WITHIN - 0.05:
            assert right                                                        # to the walker's right
        else:
            assert away or right
        assert np.linalg.norm(ej[:ONSET_FRAMES[0], 0, :2] - ej[0, 0, :2], axis=1).max() <= 0.05   # stands first
        assert min_clearance(ej, p.partner) >= AVOID_CLEARANCE
        stand_captions = {lib.captions[i] for i in range(len(lib)) if "stand" in lib.names[i]}
        assert out.captions[p.ego] in stand_captions                          # the standing clip's caption


def test_the_step_rules_and_face_arrivals_leave_the_other_copies_as_they_were(built, yielding):
    a, b = built[1], yielding[1]
    assert {n for n in a.names if "#stepaside" not in n} == \
        {n for n in b.names if "#stepaside" not in n and "#greeted" not in n}
    for i, n in enumerate(a.names):
        if "stepaside" not in n and n in b.names:
            j = b.names.index(n)
            assert np.array_equal(a.pelvis[a.offsets[i]:a.offsets[i + 1]], b.pelvis[b.offsets[j]:b.offsets[j + 1]])


def test_follow_keeps_its_distance_behind_a_walking_partner(built):
    out = built[1]
    for p in _of(built, "follow"):
        ego = out.pelvis[out.offsets[p.ego]:out.offsets[p.ego + 1], :2].astype(np.float64)
        partner = p.partner[:, 0, :2].astype(np.float64)
        gap = np.linalg.norm(partner - ego, axis=1)
        assert gap.min() >= FOLLOW_MIN_GAP and gap.max() <= 2.3
        heading = ego[-1] - ego[0]
        assert np.all((partner - ego) @ heading > 0)                      # ahead, on the same line
        speed = np.linalg.norm(partner[2:] - partner[:-2], axis=1) * 5
        assert speed.min() > 0.6                                          # the partner keeps walking
        assert min_clearance(clip_joints(out, p.ego), p.partner) >= MIN_CLEARANCE


def test_arrive_face_stops_in_front_of_a_partner_facing_it(built):
    out = built[1]
    for p in _of(built, "arrive_face"):
        ego = clip_joints(out, p.ego)
        end = np.linalg.norm(ego[-1, 0, :2] - ego[-4, 0, :2]) * 10 / 3
        assert end < 0.1                                                  # at rest
        to_partner = p.partner[-1, 0, :2] - ego[-1, 0, :2]
        dist = float(np.linalg.norm(to_partner))
        assert 0.8 < dist < 1.3
        assert float(facing_xy(ego[-1]) @ to_partner) / dist > math.cos(math.radians(20))
        assert float(facing_xy(p.partner[-1]) @ -to_partner) / dist > math.cos(math.radians(20))


def test_copies_keep_the_source_split_and_licence(built):
    lib, out, new, _ = built
    for i in range(len(lib), len(out)):
        src = lib.names.index(source_name(out.names[i]))
        assert out.is_held_out(i) == lib.is_held_out(src)
        if i in new:
            assert out.sources[i] == lib.sources[src]                      # the ego's motion is its source's
    for i in new:
        if derived_kind(out.names[i]) in ("avoid", "follow", "stepaside"):
            k = out.names.index(partner_clip_name(out.names[i]))
            walk = lib.sources.index(out.sources[k])                       # the walk the partner's motion is from
            assert walk != lib.names.index(source_name(out.names[i]))
            assert lib.is_held_out(walk) == out.is_held_out(i) and out.captions[k] == lib.captions[walk]
        if derived_kind(out.names[i]) == "follow":
            assert out.captions[i] == f"a person follows someone, {STYLE[out.is_held_out(i)]}"


def test_copies_are_deterministic_per_seed_and_per_clip(built):
    lib, out, new, _ = built
    again, new2 = add_hhi_copies(lib, list(range(len(lib))), seed=3)
    assert again.names == out.names and np.array_equal(again.rotations, out.rotations)
    other, _ = add_hhi_copies(lib, list(range(len(lib))), seed=4)
    assert other.names != out.names or not np.array_equal(other.pelvis, out.pelvis)
    # a clip's copies do not depend on which other clips are copied
    walk = lib.names.index(TRAIN[0])
    alone, only = add_hhi_copies(lib, [walk], seed=3)
    for i in only:
        j = out.names.index(alone.names[i])
        a, b = alone.offsets[i], alone.offsets[i + 1]
        assert np.array_equal(alone.pelvis[a:b], out.pelvis[out.offsets[j]:out.offsets[j + 1]])
    assert {source_name(alone.names[i]) for i in only} == {TRAIN[0]}
    assert all(not is_derived(n) for n in alone.names[:len(lib)])


def test_clearance_is_the_smallest_joint_distance():
    rng = np.random.default_rng(0)
    for _ in range(20):
        a = rng.normal(0, 0.4, (30, 22, 3)) + [0.0, 0.0, 1.0]
        b = a[::-1] + np.r_[rng.normal(0, 1.0, 2), 0.0]
        assert clearance(a, b) == pytest.approx(min_clearance(a, b))


def test_a_straight_stretch_of_a_walk_and_turn_clip_is_captioned_as_a_walk():
    assert straight_caption("a person walks and turns left, sadly") == "a person walks forward, sadly"
    assert straight_caption("a person walks and turns right") == "a person walks forward"
    assert straight_caption("a person runs forward, happily") == "a person runs forward, happily"
