"""Several egos stepped as one batch: a group of one is a session, each ego keeps its own settings, each
reacts to the nearest other character, and two egos walking at each other pass with room to spare."""
from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from model_runtime import (EgoSettings, InputError, ModelOutputError, ReactionGroup, ReactionSession, load_model,
                           rest_joints_np)
from model_runtime.checkpoint import DEFAULT_WEIGHTS
from model_runtime.control import ControlConfig, passing_away
from model_runtime.fixtures import BOX_GOAL, approaching_partner, box_scene


def frames_of(outs) -> np.ndarray:
    """Every output of a list of EgoFrames, flat per frame, to compare bit for bit."""
    return np.stack([np.concatenate([f.joints.ravel(), f.root.ravel(), f.local_rotations.ravel(),
                                     f.contacts.astype(np.float32)]) for f in outs])


@pytest.mark.parametrize("control, fwsr", [(True, True), (False, True), (True, False), (False, False)])
def test_a_group_of_one_gives_the_session_frames_bit_for_bit(tiny_model, control, fwsr):
    scene, partner = box_scene(), approaching_partner(20)
    kw = dict(text="walk to the person and wave", seed=4, alpha={"hhi": 1.0, "hsi": 0.5}, guidance=3.0, fwsr=fwsr)
    s = ReactionSession(tiny_model, scene=scene, control=control, **kw)
    s.reset(root_position=(0.5, 0.2, 0.0), yaw=0.3)
    g = ReactionGroup(tiny_model, [EgoSettings(**kw)], scene=scene, control=control)
    g.reset(root_positions=[(0.5, 0.2, 0.0)], yaws=[0.3])
    alone, grouped = [], []
    for i in range(20):
        p = None if i % 6 == 5 else partner[i]
        alone.append(s.step(partner=p, goal=BOX_GOAL))
        grouped.extend(g.step(partner=p, goals=[BOX_GOAL]))
    assert np.array_equal(frames_of(alone), frames_of(grouped))


def test_each_ego_of_a_group_follows_its_own_settings(tiny_model):
    """Three egos with their own text, seed, alpha, guidance (one without classifier-free guidance), FWSR
    switch and goal give, batched, the frames each gives alone. alpha_HHI 0 so that the others are no cue."""
    scene = box_scene()
    egos = [EgoSettings(text="walk", seed=1, alpha={"hhi": 0.0, "hsi": 1.0}, guidance=5.0, fwsr=True),
            EgoSettings(text="wave", seed=2, alpha={"hhi": 0.0, "hsi": 0.0}, guidance=1.0, fwsr=False),
            EgoSettings(text="a person runs", seed=3, alpha={"hhi": 0.0, "hsi": 0.5}, guidance=2.5, fwsr=True,
                        cleanup=False)]
    starts = [(0.0, 0.0, 0.0), (3.0, 1.0, 0.0), (-3.0, 2.0, 0.0)]
    goals = [BOX_GOAL, None, (-3.0, -1.0, 0.0)]
    g = ReactionGroup(tiny_model, egos, scene=scene)
    g.reset(root_positions=starts, yaws=[0.0, 1.0, -0.5])
    grouped = [g.step(goals=goals) for _ in range(20)]
    for i, (e, start, yaw, goal) in enumerate(zip(egos, starts, (0.0, 1.0, -0.5), goals)):
        s = ReactionSession(tiny_model, text=e.text, seed=e.seed, alpha=e.alpha, guidance=e.guidance, fwsr=e.fwsr,
                            cleanup=e.cleanup, scene=scene)
        s.reset(root_position=start, yaw=yaw)
        alone = np.stack([s.step(goal=goal).joints for _ in range(20)])
        np.testing.assert_allclose(np.stack([frames[i].joints for frames in grouped]), alone, atol=1e-4)


def test_each_ego_reacts_to_the_nearest_other_character(tiny_model):
    """The HHI cue is the nearest other character by pelvis distance: another ego or the partner."""
    g = ReactionGroup(tiny_model, [EgoSettings(seed=i) for i in range(3)])
    g.reset(root_positions=[(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (10.0, 0.0, 0.0)], yaws=[0.0] * 3)
    partner = approaching_partner(1)[0] + np.array([10.0, 0.5, 0.0], np.float32)   # 1.5 m from ego 2
    before = [e.trail[-1].copy() for e in g.egos]
    g.step(partner=partner)
    assert [e.cue_id for e in g.egos] == [1, 0, -1]
    assert np.array_equal(g.egos[0].cue[-1], before[1]) and np.array_equal(g.egos[1].cue[-1], before[0])
    assert np.array_equal(g.egos[2].cue[-1], partner)


def test_passing_sides_of_two_characters_are_opposite_and_kept():
    cc = ControlConfig()
    a = np.array([[0.05, 2.0], [0.05, 1.9]])           # walking -Y, a little to +X of the line
    b = np.array([[0.0, -2.0], [0.0, -1.9]])           # walking +Y
    away_a, away_b = passing_away(a, b, None, cc), passing_away(b, a, None, cc)
    assert np.allclose(away_a, -away_b) and abs(away_a[1]) < 1e-6
    head_on = np.array([[0.0, 2.0], [0.0, 1.9]])
    assert passing_away(head_on, b, None, cc)[0] == pytest.approx(-1.0)   # keep right: facing -Y, right is -X
    assert np.allclose(passing_away(a, b, -away_a, cc), -away_a)           # a side once taken is kept
    assert passing_away(a, a, None, cc) is None                              # walking alongside: no pass
    past = np.array([[0.0, -2.0], [0.0, -2.1]])                              # already 2 m beyond the other
    assert passing_away(past, np.array([[0.0, 0.0], [0.0, 0.1]]), away_a, cc) is None


@pytest.fixture(scope="module")
def shipped_model():
    if not DEFAULT_WEIGHTS.is_file():
        pytest.skip("the shipped weights (model_runtime/weights/default.pt) are not in this checkout")
    return load_model(DEFAULT_WEIGHTS)


def _clearance(model, alpha: float, seed: int, frames: int = 50) -> float:
    """Two egos 4 m apart facing each other, told to walk forward: their smallest joint-to-joint distance."""
    text = "a person walks forward"
    g = ReactionGroup(model, [EgoSettings(text=text, seed=seed, alpha={"hhi": alpha, "hsi": 0.0}),
                              EgoSettings(text=text, seed=seed + 100, alpha={"hhi": alpha, "hsi": 0.0})])
    g.reset(root_positions=[(0.0, 2.0, 0.0), (0.0, -2.0, 0.0)], yaws=[0.0, math.pi])   # yaw 0 faces -Y
    closest = np.inf
    for _ in range(frames):
        a, b = g.step()
        closest = min(closest, float(np.linalg.norm(a.joints[:, None] - b.joints[None], axis=-1).min()))
    return closest


SEEDS = range(10)


@pytest.fixture(scope="module")
def clearances(shipped_model):
    """Smallest joint distance of the two egos per seed, at alpha_HHI 1 and 0."""
    return {alpha: [_clearance(shipped_model, alpha, seed) for seed in SEEDS] for alpha in (1.0, 0.0)}


def test_two_egos_walking_toward_each_other_keep_clear(clearances):
    """alpha_HHI 1 (test-time control on, the default): at least 0.10 m between any two joints, every seed."""
    apart = clearances[1.0]
    assert min(apart) >= 0.10, [round(c, 3) for c in apart]


def test_two_egos_ignoring_each_other_come_closer(clearances):
    """alpha_HHI 0 ignores the other ego: over the seeds they come closer than at alpha 1, in most seeds and on
    average (per seed it is not always so: two egos walking past each other by chance can miss at alpha 0)."""
    apart, ignoring = clearances[1.0], clearances[0.0]
    closer = sum(i < a for i, a in zip(ignoring, apart))
    assert closer > len(apart) / 2, (ignoring, apart)
    assert np.mean(ignoring) < np.mean(apart) - 0.2, (ignoring, apart)


def test_bad_group_input_is_one_line_and_changes_nothing(tiny_model):
    for egos, words in (([], "non-empty list"), (EgoSettings(), "non-empty list"), ([{"text": "walk"}], "EgoSettings"),
                        ([EgoSettings(seed=-1)], "seed must be")):
        with pytest.raises(InputError) as err:
            ReactionGroup(tiny_model, egos)
        assert words in str(err.value) and "\n" not in str(err.value)
    g = ReactionGroup(tiny_model, [EgoSettings(seed=0), EgoSettings(seed=1)])
    g.reset(root_positions=[(0.0, 0.0, 0.0), (2.0, 0.0, 0.0)])
    g.step()
    before = [e.hist_world.clone() for e in g.egos]
    for call, words in ((lambda: g.step(goals=[None]), "one entry per ego (2)"),
                        (lambda: g.step(goals=[None, (0.0, float("nan"), 0.0)]), "goals[1]"),
                        (lambda: g.reset(root_positions=[(0.0, 0.0, 0.0)]), "one entry per ego"),
                        (lambda: g.reset(root_positions=[(0.0, 0.0, 0.0), (1.0, 2.0)]), "root_positions[1]")):
        with pytest.raises(InputError) as err:
            call()
        assert words in str(err.value) and "\n" not in str(err.value)
    assert g.frame_index == 1 and all(torch.equal(b, e.hist_world) for b, e in zip(before, g.egos))


def test_a_non_finite_pose_names_the_ego_and_leaves_the_group_as_it_was():
    model = load_model(config="tiny", seed=0)
    settings = [EgoSettings(text="walk", seed=4), EgoSettings(text="wave", seed=5)]
    ref = ReactionGroup(model, settings)
    expected = [ref.step() for _ in range(12)]
    g = ReactionGroup(model, settings)
    for _ in range(9):
        g.step()
    saved = {k: v.clone() for k, v in model.state_dict().items()}
    with torch.no_grad():
        model.vae.out.bias.fill_(3e38)
    with pytest.raises(ModelOutputError) as err:
        g.step()
    assert str(err.value).startswith("ego 0: the model produced non-finite joints at frame 9")
    model.load_state_dict(saved)
    assert g.frame_index == 9
    for want in expected[9:]:
        assert np.array_equal(frames_of(g.step()), frames_of(want))


def test_ego_plans_extrapolate_another_ego_from_the_end_of_its_segment(tiny_model):
    """With ControlConfig.ego_plans, the partner cost sees another ego moved on from the end of the segment it is
    about to play (its plan, known to the group), not from its latest frame."""
    from model_runtime.ego import Ego
    cc = ControlConfig(ego_plans=1)
    ego = Ego(tiny_model, EgoSettings(seed=0, alpha={"hhi": 1.0, "hsi": 0.0}))
    still = np.asarray(approaching_partner(12, start=2.0, stop=2.0, speed=1.0)[-1], np.float32)   # standing 2 m away
    ego.cue.extend([still.copy() for _ in range(tiny_model.cfg.partner_window)])
    ego.cue_id = 1
    lead = tiny_model.cfg.future
    plan = torch.from_numpy(np.stack([still + np.float32([0.0, 0.1 * (k + 1), 0.0]) for k in range(lead)]))
    rot, trans = torch.eye(3), torch.zeros(3)
    seen = ego.control_targets(rot, trans, lead, None, cc).partner
    planned = ego.control_targets(rot, trans, lead, None, cc, cue_plan=plan).partner
    assert torch.allclose(seen[0], torch.from_numpy(still), atol=1e-5)          # standing: it stays where it is
    # from the plan's end, at the plan's own speed (0.1 m a frame along +Y), one frame on
    assert torch.allclose(planned[0, :, 1], plan[-1, :, 1] + 0.1, atol=1e-4)
    assert torch.allclose(planned[0, :, 0], plan[-1, :, 0], atol=1e-4)


def test_two_egos_about_to_walk_at_each_other_pass_from_their_plans(tiny_model):
    """Standing still so far, two egos whose plans walk them at each other already pick their passing sides
    (opposite ways, so they move apart), a segment before their own latest frames would tell."""
    from model_runtime.ego import Ego
    cc = ControlConfig()
    rest = np.asarray(rest_joints_np(), np.float32)

    def body_at(y: float) -> np.ndarray:          # a standing body with its pelvis at (0, y, 0)
        return rest - rest[0] + np.float32([0.0, y, 0.0])

    egos = [Ego(tiny_model, EgoSettings(seed=k, alpha={"hhi": 1.0, "hsi": 0.0})) for k in range(2)]
    starts, steps = (2.0, -2.0), (-0.1, 0.1)
    for k, e in enumerate(egos):
        e.trail.extend([body_at(starts[k]) for _ in range(4)])
        e.cue.extend([body_at(starts[1 - k]) for _ in range(tiny_model.cfg.partner_window)])
        e.cue_id = 1 - k
    lead = tiny_model.cfg.future
    plans = [torch.from_numpy(np.stack([body_at(starts[k] + steps[k] * (f + 1)) for f in range(lead)]))
             for k in range(2)]
    rot, trans = torch.eye(3), torch.zeros(3)
    assert egos[0].control_targets(rot, trans, lead, None, cc).pass_away is None      # standing: no pass yet
    away = [e.control_targets(rot, trans, lead, None, cc, cue_plan=plans[1 - k], own_plan=plans[k]).pass_away
            for k, e in enumerate(egos)]
    assert away[0] is not None and away[1] is not None
    assert torch.allclose(away[0], -away[1], atol=1e-5) and abs(float(away[0][1])) < 0.2    # opposite, across


def test_ego_plans_on_by_default(tiny_model):
    def run(cc):
        g = ReactionGroup(tiny_model, [EgoSettings(seed=0, alpha={"hhi": 1.0, "hsi": 0.0}),
                                       EgoSettings(seed=1, alpha={"hhi": 1.0, "hsi": 0.0})], control_config=cc)
        g.reset(root_positions=[(0.0, 0.35, 0.0), (0.0, -0.35, 0.0)], yaws=[0.0, math.pi])   # within the margin
        return np.stack([np.stack([f.joints for f in g.step()]) for _ in range(20)])
    default, off, on = run(None), run(ControlConfig(ego_plans=0)), run(ControlConfig(ego_plans=1))
    assert np.array_equal(default, on)
    assert not np.array_equal(default, off)       # the plans reach the control from the second segment's job on


def test_a_segment_start_takes_more_seam_steps_where_an_ego_reacts_to_someone(tiny_model):
    """partner_seam_steers where some ego has a cue and alpha_HHI above 0, seam_steers elsewhere (and none
    without control)."""
    partner = approaching_partner(12)
    cc = ControlConfig(seam_steers=2, partner_seam_steers=3)

    def steps_taken(alpha_hhi: float, with_partner: bool, control: bool = True) -> set[int]:
        g = ReactionGroup(tiny_model, [EgoSettings(seed=1, alpha={"hhi": alpha_hhi, "hsi": 0.0})], control=control,
                          control_config=cc)
        g.reset(root_positions=[(0.0, 0.0, 0.0)], yaws=[0.0])
        taken = set()
        for i in range(12):
            g.step(partner=partner[i] if with_partner else None)
            taken.add(g._seg["seam_steers"])
        return taken

    assert steps_taken(1.0, with_partner=True) == {3}
    assert steps_taken(0.0, with_partner=True) == {2}       # alpha_HHI 0 ignores the partner
    assert steps_taken(1.0, with_partner=False) == {2}
    assert steps_taken(1.0, with_partner=True, control=False) == {0}


def test_cue_windows_of_several_egos_equal_each_frame_moved_one_by_one():
    """The batched cue windows give each present frame moved into its ego's own frame alone (bit for bit on some
    CPUs, within a unit in the last place on others, whose batched kernels sum in another order), zeros where a
    frame is missing or the cue is hidden."""
    from model_runtime.ego import cue_windows
    from model_runtime.features import world_points_to_canonical
    from model_runtime.skeleton import yaw_matrix

    class Cued:
        def __init__(self, cue):
            self.cue = cue
    rng = np.random.default_rng(3)
    egos = [Cued([None if rng.random() < 0.3 else (3.0 * rng.normal(size=(22, 3))).astype(np.float32)
                  for _ in range(10)]) for _ in range(4)]
    rots = [yaw_matrix(torch.tensor(float(a))) for a in rng.normal(size=4) * 3.0]
    transes = [torch.tensor(t, dtype=torch.float32) for t in rng.normal(size=(4, 3)) * 5.0]
    hidden = [False, True, False, False]
    for n in (2, 10):
        pts, present = cue_windows(egos, rots, transes, n, hidden)
        assert pts.shape == (4, n, 22, 3) and present.shape == (4, n)
        for i, e in enumerate(egos):
            for k, frame in enumerate(e.cue[-n:]):
                if frame is None or hidden[i]:
                    assert not present[i, k] and not pts[i, k].any()
                else:
                    want = world_points_to_canonical(torch.from_numpy(frame), rots[i], transes[i])
                    assert present[i, k] and torch.allclose(pts[i, k], want, rtol=0.0, atol=1e-5)
