"""Copies of the controlled runtime's own reactions (model_runtime.training.controlled_copies)."""
import numpy as np
import pytest

from model_runtime.checkpoint import load_model
from model_runtime.data.face_arrivals import ARRIVE_DISTANCE
from model_runtime.data.library import derived_kind
from model_runtime.data.pairs import ClipCache
from model_runtime.data.pairs.hhi import AVOID_CLEARANCE, COPY_KINDS, build_hhi_pairs
from model_runtime.data.stretches import WalkPool, calm_standing, clearance, walks
from model_runtime.data.detours import BLEND_FRAMES, STAND_FRAMES
from model_runtime.behaviour.scenarios import CROSS_FRAMES, CROSS_MISS
from model_runtime.training import controlled_copies as cc
from synthetic import library_of, rigid_clip, walking_clip


@pytest.fixture(scope="module")
def lib():
    moving = [(f"walk{k}", "a person walks forward", "cmu", walking_clip(90, 1.2, 0.0, yaw0=0.7 * k, phase=k))
              for k in range(5)]
    still = [(f"stand{k}", "a person stands", "cmu", rigid_clip(np.tile([[0.0, 0.0]], (60, 1)), 0.3 * k))
             for k in range(3)]
    return library_of(moving + still)


@pytest.fixture(scope="module")
def pools(lib):
    train = [i for i in range(len(lib)) if not lib.is_held_out(i)]
    clips = ClipCache(lib, train)
    stands = [i for i in calm_standing(lib, clips, train, 20) if lib.frames(i) >= STAND_FRAMES[1] + BLEND_FRAMES]
    return clips, WalkPool.of(clips, walks(lib, clips, train)), stands


def test_a_crossing_walker_passes_where_the_ego_would_be(lib, pools):
    clips, pool, _ = pools
    seen = set()
    for k in range(12):
        ep = cc.draw_crossing(lib, clips, pool, np.random.default_rng([5, k]))
        assert ep is not None and ep.kind == cc.KIND and ep.frames == CROSS_FRAMES
        walking = ep.text == cc.WALK_TEXT
        seen.add(walking)
        meet = np.array([0.0, -2.5 if walking else 0.0])
        # at 2.5 s its pelvis is within MISS of the meeting point, and it came from (and goes on) well away
        assert np.linalg.norm(ep.pelvis[cc.CROSS_FRAME, :2] - meet) <= CROSS_MISS + 1e-5
        assert np.linalg.norm(ep.pelvis[0, :2] - meet) > 1.5 and np.linalg.norm(ep.pelvis[-1, :2] - meet) > 1.5
        assert not lib.is_held_out(ep.source)
        assert np.allclose(ep.joints[:, 0], ep.pelvis, atol=1e-4)
    assert seen == {True, False}          # standing and walking egos both drawn


def test_an_approaching_walker_comes_to_rest_near_the_ego(lib, pools):
    clips, pool, stands = pools
    assert stands
    got = [cc.draw_approach(lib, clips, pool, stands, np.random.default_rng([6, k])) for k in range(8)]
    got = [g for g in got if g is not None]
    assert got
    for ep in got:
        assert ep.kind == cc.APPROACH_KIND and ep.text == cc.STAND_TEXT
        end = np.linalg.norm(ep.pelvis[-1, :2])
        assert ARRIVE_DISTANCE[0] - 0.05 <= end <= ARRIVE_DISTANCE[1] + 0.05
        assert np.linalg.norm(ep.pelvis[0, :2]) > end + 1.0          # it walked up from farther away
        # and stood still for the frames the copy keeps after it came to rest
        assert np.linalg.norm(ep.pelvis[-1, :2] - ep.pelvis[-10, :2]) < 0.05


def test_the_copies_are_the_controlled_runtime_s_own_motion_and_become_hhi_pairs(lib):
    model = load_model()
    made, counts = cc.controlled_copies(model, lib, 4, seed=11)
    assert counts["drawn"] == 4 and counts["kept"] + counts["too_close"] + counts["no_walk"] == 4
    assert counts["kept"] >= 1 and len(made) == 2 * counts["kept"]
    egos, partners = made[0::2], made[1::2]
    for ego, partner in zip(egos, partners):
        assert "#ctlavoid" in ego.name and partner.name == ego.name.replace("#ctlavoid", "#ctlavoidpartner")
        assert ego.ego and not partner.ego
        assert ego.source == cc.model_licence_tag(model) == "bandai"    # the shipped weights are non-commercial
        assert ego.caption in (cc.STAND_TEXT, cc.WALK_TEXT)
        assert np.isfinite(ego.rotations).all() and np.isfinite(ego.pelvis).all()
        assert np.allclose(np.linalg.norm(ego.rotations, axis=-1), 1.0, atol=1e-4)
    from model_runtime.data.new_clips import extend_library
    out, ids = extend_library(lib, made)
    assert COPY_KINDS[cc.KIND] == "avoid_walker" and COPY_KINDS[cc.APPROACH_KIND] == "face_arrival"
    pairs = build_hhi_pairs(out, ids, seed=0)
    assert {p.kind for p in pairs} == {"avoid_walker"} and len(pairs) == len(ids)
    clips = ClipCache(out, ids)
    for p in pairs:
        assert derived_kind(out.names[p.ego]) == cc.KIND and not out.is_held_out(p.ego)
        assert clearance(clips.joints(p.ego), p.partner) >= AVOID_CLEARANCE


def test_the_copies_can_pin_the_control_they_are_made_with(lib, monkeypatch):
    """A recipe's copies stay what an earlier runtime made when its control settings are given."""
    from model_runtime.behaviour import suite
    from model_runtime.control import ControlConfig
    seen, real = [], suite.roll_out_frames

    def spy(model, ep, alpha, **options):
        seen.append(options.get("control_config"))
        return real(model, ep, alpha, **options)
    monkeypatch.setattr(suite, "roll_out_frames", spy)
    pinned = ControlConfig(still_partner_seam_weight=100.0)
    cc.controlled_copies(load_model(), lib, 1, seed=11, control_config=pinned)
    assert seen == [pinned] and seen[0] is pinned


def test_the_licence_tag_follows_the_model_s_data():
    class Meta:
        def __init__(self, meta):
            self.meta = meta
    assert cc.model_licence_tag(Meta({"sources": ["cmu"], "non_commercial": False})) == "cmu"
    assert cc.model_licence_tag(Meta({"sources": ["bandai", "cmu"]})) == "bandai"
    assert cc.model_licence_tag(Meta({"non_commercial": True})) == "bandai"


@pytest.mark.parametrize("args, word", [(["--seed", "1001"], "behaviour-suite split"),
                                        (["--episodes", "0"], "--episodes"),
                                        (["--approach-share", "1.5"], "--approach-share"),
                                        (["--control-set", "no_such_setting=1"], "--control-set"),
                                        (["--control-set", "seam_weight=heavy"], "not a number")])
def test_the_command_refuses_bad_input_in_one_line_and_writes_nothing(tmp_path, lib, capsys, args, word):
    src = lib.save(tmp_path / "lib.npz")
    out = tmp_path / "out.npz"
    assert cc.main(["--library", str(src), "--out", str(out)] + args) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error:") and word in err and "\n" not in err
    assert not out.exists()


def test_suite_seeds_are_not_the_copies_seed():
    from model_runtime.behaviour.scenarios import SPLIT_SEEDS
    assert cc.SEED not in SPLIT_SEEDS.values()


def test_set_off_windows_have_a_still_history_and_a_moving_future_and_are_drawn_their_share():
    from model_runtime.data.pairs import HHIPair
    from model_runtime.training import samples
    from model_runtime.training.recipe import WINDOW_RECIPES
    # stands 25 frames, then walks off at 1.2 m/s
    stand = rigid_clip(np.zeros((25, 2)), 0.0)
    walk = walking_clip(35, 1.2, 0.0)
    walk[1][:, :2] += stand[1][-1, :2] - walk[1][0, :2] + np.array([0.0, -0.12])
    clip = (np.concatenate([stand[0], walk[0]]), np.concatenate([stand[1], walk[1]]))
    lib = library_of([("setoff", "a person stands", "cmu", clip)])
    model = load_model(config="tiny")
    partner = np.full((60, 22, 3), 50.0, np.float32)
    s = samples.SegmentSampler(lib, [0], model.cfg, model.stats, seed=0, pairs=[HHIPair(0, partner, "step_aside")],
                               setoff_share=WINDOW_RECIPES["setoffs"].setoff_share)
    h, span = model.cfg.history, model.cfg.history + model.cfg.future
    xy = lib.pelvis[:, :2].astype(np.float64)
    starts = s._setoff_starts[0].tolist()
    assert starts
    for st in range(60 - span):
        still = np.linalg.norm(xy[st + h] - xy[st]) < samples.SETOFF_STILL
        moves = np.linalg.norm(xy[st + span] - xy[st + h]) > samples.SETOFF_MOVE
        assert (st in starts) == (still and moves)
    # the partner is never near, so only the set-off share draws from them (and the uniform draws now and then)
    drawn = [s._window_start(0, lib.features(0).shape[0]) for _ in range(4000)]
    share = np.isin(drawn, starts).mean()
    uniform = len(starts) / (60 - 1 - span + 1)
    expect = 0.5 + 0.5 * uniform
    assert abs(share - expect) < 0.03
    # without the share (every shipped recipe) no set-off window is looked for
    assert samples.SegmentSampler(lib, [0], model.cfg, model.stats, seed=0,
                                  pairs=[HHIPair(0, partner, "step_aside")])._setoff_starts is None
