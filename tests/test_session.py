import numpy as np
import pytest
import torch

from model_runtime import DEFAULT_GUIDANCE, EgoFrame, InputError, ReactionSession
from model_runtime.bench import approaching_partner
from model_runtime.features import canonical_frame, feature_joints, self_consistent, to_canonical, to_world


def rollout(model, n=20, seed=0, **kw):
    s = ReactionSession(model, text="walk to the person and wave", seed=seed, **kw)
    s.reset(root_position=(1.0, 2.0, 0.0), yaw=0.3)
    partner = approaching_partner(n)
    return [s.step(partner=partner[i], goal=(0.0, -3.0, 0.0)) for i in range(n)]


def test_step_outputs_shapes_and_types(tiny_model):
    f = rollout(tiny_model, 3)[-1]
    assert isinstance(f, EgoFrame)
    assert f.joints.shape == (22, 3) and f.root.shape == (4, 4) and f.local_rotations.shape == (22, 4)
    assert f.joints.dtype == np.float32 and np.isfinite(f.joints).all()
    assert np.allclose(np.linalg.norm(f.local_rotations, axis=1), 1, atol=1e-5)
    assert np.allclose(f.root[:3, 3], f.joints[0], atol=1e-5)


def test_same_seed_same_frames_other_seed_differs(tiny_model):
    a = np.stack([f.joints for f in rollout(tiny_model, 20, seed=5)])
    b = np.stack([f.joints for f in rollout(tiny_model, 20, seed=5)])
    c = np.stack([f.joints for f in rollout(tiny_model, 20, seed=6)])
    assert np.array_equal(a, b)
    assert not np.allclose(a, c)


def test_reset_restarts_identically(tiny_model):
    s = ReactionSession(tiny_model, text="walk", seed=2)
    s.reset()
    first = [s.step().joints for _ in range(12)]
    s.reset()
    again = [s.step().joints for _ in range(12)]
    assert all(np.array_equal(x, y) for x, y in zip(first, again))


def test_reset_places_a_standing_body(tiny_model):
    s = ReactionSession(tiny_model, seed=0)
    s.reset(root_position=(1.0, -2.0, 0.0), yaw=np.pi / 2)
    hist = s.history_world_features()
    joints = feature_joints(hist[-1])
    assert torch.allclose(joints[0, :2], torch.tensor([1.0, -2.0]), atol=1e-5)
    assert float(joints[:, 2].min()) == pytest.approx(0.02, abs=0.01)           # soles on the floor
    rot, _ = canonical_frame(joints)
    assert torch.allclose(rot[:, 1], torch.tensor([1.0, 0.0, 0.0]), atol=0.05)   # yaw 90 deg: -Y -> +X


def test_fwsr_off_emits_exactly_the_segment_decodes(tiny_model):
    """Reference rollout from model primitives: full diffusion, decode, slide history; same RNG order."""
    m = tiny_model
    cfg = m.cfg
    s = ReactionSession(m, text="walk", seed=11, fwsr=False, alpha={"hhi": 0.0, "hsi": 0.0}, cleanup=False,
                        control=False)
    s.reset()
    hist_world = s.history_world_features()
    got = [s.step() for _ in range(2 * cfg.future)]
    gen = torch.Generator().manual_seed(11)
    te = m.encode_text("walk")
    ref = []
    with torch.inference_mode():
        from model_runtime.model import Contexts
        for _ in range(2):
            hist_world = self_consistent(hist_world)      # generated history as real frames are (features.py)
            rot, trans = canonical_frame(feature_joints(hist_world[0]))
            hist_n = m.stats.normalize(to_canonical(hist_world, rot, trans)).unsqueeze(0)
            z0 = m.sample_latent(hist_n, te, Contexts({}), {"hhi": 0.0, "hsi": 0.0}, DEFAULT_GUIDANCE, gen)
            fut = to_world(m.stats.denormalize(m.decode(hist_n, z0)[0]), rot, trans)
            ref.extend(fut)
            hist_world = fut[-cfg.history:]
    for f, r in zip(got, ref):
        assert np.allclose(f.root[:3, 3], r[:3].numpy(), atol=1e-5)


def test_fwsr_changes_frames_after_the_first_of_a_segment(tiny_model):
    on = rollout(tiny_model, 8, fwsr=True)
    off = rollout(tiny_model, 8, fwsr=False)
    assert np.array_equal(on[0].joints, off[0].joints)   # frame 0 of a segment is the initial decode
    assert not np.allclose(on[3].joints, off[3].joints)


def test_alpha_hhi_zero_ignores_the_partner_with_fwsr_on(tiny_model):
    """alpha_HHI = 0 hides the partner from FWSR's refiner too: the frames are those of no partner at all."""
    def run(alpha, partner):
        s = ReactionSession(tiny_model, text="walk", seed=0, alpha={"hhi": alpha, "hsi": 0.0}, fwsr=True)
        s.reset(yaw=0.3)
        return np.stack([s.step(partner=None if partner is None else partner[i]).joints for i in range(12)])
    walk = approaching_partner(12)
    assert np.array_equal(run(0.0, walk), run(0.0, None))
    assert not np.allclose(run(1.0, walk), run(1.0, None))


def test_slide_mode_runs(tiny_model):
    frames = rollout(tiny_model, 3, slide=True)
    assert all(np.isfinite(f.joints).all() for f in frames)


def test_settings_change_between_steps(tiny_model):
    """Text, alpha and guidance are read when a segment's diffusion starts (one segment ahead of the frame
    shown), so a change at frame 5 shows from frame 16 (F = 8); FWSR switches at the next frame."""
    def run(changes):
        s = ReactionSession(tiny_model, text="walk", seed=0)
        s.reset()
        partner = approaching_partner(24)
        out = []
        for i in range(24):
            for name, value in changes.get(i, {}).items():
                setattr(s, name, value)
            out.append(s.step(partner=partner[i]).joints)
        return np.stack(out)
    same = run({})
    diffusion = run({5: {"text": "wave", "alpha": {"hhi": 0.5, "hsi": 0.0}, "guidance": 2.0}})
    fwsr = run({5: {"fwsr": False}})
    assert np.array_equal(diffusion[:16], same[:16])
    assert not np.allclose(diffusion[16:], same[16:])
    assert np.array_equal(fwsr[:5], same[:5])
    assert not np.allclose(fwsr[5], same[5])


def test_reset_from_frame(tiny_model):
    frames = rollout(tiny_model, 5)
    s = ReactionSession(tiny_model, seed=0)
    s.reset(frame=frames[-1])
    assert torch.allclose(feature_joints(s.history_world_features()[-1]), torch.from_numpy(frames[-1].joints),
                          atol=1e-4)


def test_reset_from_latest_frames_continues_their_motion(tiny_model):
    """A list of frames (oldest first) starts the ego moving: its history holds them, so their pace is kept."""
    frames = rollout(tiny_model, 6)
    h = tiny_model.cfg.history
    s = ReactionSession(tiny_model, seed=0)
    s.reset(frame=frames[-h:])
    hist = s.history_world_features()
    assert hist.shape[0] == h
    for k in range(h):     # the history's rows are the frames given, the latest last (as after a step)
        assert torch.allclose(feature_joints(hist[k]), torch.from_numpy(frames[-h + k].joints), atol=1e-4)
    # each row's step to the next frame: the real one, and for the last frame its previous step again
    steps = hist[:, 135:138]                                # the pelvis step (features.py)
    assert torch.allclose(steps[0], torch.from_numpy(frames[-1].root[:3, 3] - frames[-2].root[:3, 3]), atol=1e-4)
    assert torch.allclose(steps[-1], steps[-2], atol=1e-5)
    # the same frames held still give a standing history: a different start
    s.reset(frame=frames[-1])
    still = s.history_world_features()
    assert torch.allclose(feature_joints(still[0]), feature_joints(still[-1]), atol=1e-5)
    assert not torch.allclose(feature_joints(hist[0]), feature_joints(hist[-1]), atol=1e-3)
    # more frames than the history: the latest are used; fewer: the first is held in front of them
    s.reset(frame=frames)
    assert torch.allclose(s.history_world_features(), hist, atol=1e-5)
    s.reset(frame=frames[-1:])
    assert torch.allclose(s.history_world_features(), still, atol=1e-5)
    assert s.step().joints.shape == (22, 3)


@pytest.mark.parametrize("bad", [[], ["frame"], "frame", 3])
def test_reset_from_bad_frames_says_what_to_pass_and_changes_nothing(tiny_model, bad):
    s = ReactionSession(tiny_model, seed=0)
    s.reset(root_position=(1.0, 2.0, 0.0), yaw=0.3)
    before = s.history_world_features()
    with pytest.raises(InputError, match="EgoFrame") as err:
        s.reset(frame=bad)
    assert "\n" not in str(err.value)
    assert torch.equal(s.history_world_features(), before)


@pytest.mark.parametrize("partner, words", [
    (np.full((22, 3), np.nan), "NaN"),
    (np.full((22, 3), 3.4e38), "beyond"),
    (np.zeros((21, 3)), "shape (22, 3)"),
    (np.zeros((22, 4)), "shape (22, 3)"),
    (np.random.default_rng(0).normal(size=(22, 3)) * 100, "centimetres"),
    ("left", "partner"),
])
def test_bad_partner_raises_one_line_and_changes_nothing(tiny_model, partner, words):
    s = ReactionSession(tiny_model, seed=0)
    s.reset()
    s.step()
    before = s.history_world_features()
    with pytest.raises(InputError) as err:
        s.step(partner=partner)
    assert words in str(err.value) and "\n" not in str(err.value)
    assert s.frame_index == 1 and torch.equal(before, s.history_world_features())


@pytest.mark.parametrize("kwargs, words", [
    ({"alpha": {"hhi": 1.0, "xyz": 1.0}}, "unknown alpha"),
    ({"alpha": {"hhi": float("nan")}}, "finite"),
    ({"alpha": {"hhi": "abc"}}, "alpha['hhi'] must be a finite number >= 0, got 'abc'"),
    ({"alpha": {"hsi": None}}, "alpha['hsi'] must be a finite number >= 0, got None"),
    ({"alpha": "abc"}, "alpha must be a dict"),
    ({"guidance": -1.0}, "guidance must be a number in 0..20"),
    ({"guidance": 1e30}, "guidance must be a number in 0..20"),
    ({"guidance": "abc"}, "guidance"),
    ({"guidance": None}, "guidance"),
    ({"seed": 2 ** 64}, "seed must be an integer in 0..2**64-1"),
    ({"seed": -1}, "seed must be"),
    ({"seed": None}, "seed must be"),
    ({"seed": 1.5}, "seed must be"),
    ({"seed": "3"}, "seed must be"),
    ({"text": 3}, "text must be a string"),
    ({"scene": "table"}, "OccupancyGrid"),
])
def test_bad_settings_raise_one_line(tiny_model, kwargs, words):
    with pytest.raises(InputError) as err:
        ReactionSession(tiny_model, **kwargs)
    assert words in str(err.value) and "\n" not in str(err.value)


def test_bad_settings_on_a_running_session_change_nothing(tiny_model):
    s = ReactionSession(tiny_model, seed=3, guidance=2.0)
    for name, value in (("guidance", 1e30), ("seed", 2 ** 64), ("alpha", {"hhi": "abc"})):
        with pytest.raises(InputError):
            setattr(s, name, value)
    assert (s.guidance, s.seed, s.alpha) == (2.0, 3, {"hhi": 1.0, "hsi": 1.0})
    s.seed = np.uint64(2 ** 63)                      # NumPy integers are seeds too
    assert s.seed == 2 ** 63


def test_bad_goal_and_reset_raise(tiny_model):
    s = ReactionSession(tiny_model)
    with pytest.raises(InputError, match="goal"):
        s.step(goal=(0.0, float("inf"), 0.0))
    with pytest.raises(InputError, match="root_position"):
        s.reset(root_position=(0.0, 0.0))


def test_a_goal_of_many_points_gets_a_one_line_message(tiny_model):
    s = ReactionSession(tiny_model)
    with pytest.raises(InputError) as err:
        s.step(goal=np.arange(12.0).reshape(4, 3))
    assert "got 12 values (shape (4, 3))" in str(err.value) and "\n" not in str(err.value)


def break_model_at(session, frame, breaker):
    """Step `session` to `frame`, then let `breaker(model)` spoil the model; returns the undo."""
    model = session.model
    saved = {k: v.clone() for k, v in model.state_dict().items()}
    for _ in range(frame):
        session.step()
    with torch.no_grad():
        breaker(model)
    return lambda: model.load_state_dict(saved)


@pytest.mark.parametrize("breaker, words", [
    (lambda m: m.vae.out.weight.fill_(float("nan")), "non-finite joints at frame 9: its weight vae.out.weight "
                                                      "holds NaN or inf"),
    (lambda m: m.vae.out.bias.fill_(3e38), "non-finite joints at frame 9 with guidance 6"),  # finite weights
    (lambda m: m.vae.out.bias.fill_(1e30), "joints beyond 1e+05 m at frame 9 with guidance 6"),
])
def test_a_non_finite_pose_raises_and_leaves_the_session_as_it_was(breaker, words):
    """The first non-finite frame raises ModelOutputError in one line naming the cause and the frame; the
    session changes nothing, so with the model repaired it goes on exactly as if nothing had happened."""
    from model_runtime import ModelOutputError, load_model
    model = load_model(config="tiny", seed=0)
    ref = ReactionSession(model, text="walk", seed=4)
    ref.reset()
    expected = [ref.step().joints for _ in range(12)]
    s = ReactionSession(model, text="walk", seed=4)
    s.reset()
    repair = break_model_at(s, 9, breaker)           # mid-segment, with a diffusion job in flight
    before = s.history_world_features()
    for _ in range(2):                               # failing again changes nothing either
        with pytest.raises(ModelOutputError) as err:
            s.step()
        msg = str(err.value)
        assert words in msg and "\n" not in msg
    assert s.frame_index == 9 and torch.equal(before, s.history_world_features())
    repair()
    assert all(np.array_equal(s.step().joints, e) for e in expected[9:])


def test_the_scene_is_read_only_on_steps_that_start_a_segment(tiny_model):
    """reads_scene_next is what the extension relies on to check the scene meshes only when they are read."""
    from model_runtime.fixtures import BOX_GOAL, box_scene
    s = ReactionSession(tiny_model, text="a person walks", scene=box_scene())
    f = tiny_model.cfg.future
    reads = []
    for _ in range(2 * f + 1):
        reads.append(s.reads_scene_next)
        s.step(goal=BOX_GOAL)
    assert reads == [i % f == 0 for i in range(2 * f + 1)]
    slide = ReactionSession(tiny_model, slide=True)
    assert slide.reads_scene_next and (slide.step() is not None) and slide.reads_scene_next
