"""The last denoising step's eased guidance: which scale each step and each ego gets, and that sessions carry
the model's settings (tests/test_pipeline.py: the helper process's jobs too)."""
import pytest
import torch

from model_runtime import DEFAULT_FINAL_GUIDANCE_MIN_SPEED, DEFAULT_FINAL_GUIDANCE_SHARE, InputError
from model_runtime.checks import check_final_guidance_share
from model_runtime.features import ROOT_T
from model_runtime.model import (Contexts, DiffusionJob, ReMoGenModel, final_step_guidance, history_speed,
                                  noise)
from model_runtime.session import ReactionSession


def test_final_step_guidance_keeps_a_share_of_the_push_past_the_conditional_pass():
    assert final_step_guidance(6.0, 0.4) == pytest.approx(3.0)
    assert final_step_guidance(6.0, 1.0) == 6.0
    assert final_step_guidance(0.3, 1.0) == 0.3          # a share of 1 is the scale itself, bit for bit
    assert final_step_guidance(6.0, 0.0) == 1.0
    assert final_step_guidance(1.0, 0.4) == 1.0          # no guidance stays none
    assert final_step_guidance([5.0, 1.0, 2.0], 0.5) == pytest.approx([3.0, 1.0, 1.5])
    # only the rows marked eased: the others keep their scale; rows that agree stay one scale
    assert final_step_guidance(6.0, 0.4, [True, False]) == pytest.approx([3.0, 6.0])
    assert final_step_guidance(6.0, 0.4, [False, False]) == 6.0
    assert final_step_guidance(6.0, 0.4, [True, True]) == pytest.approx(3.0)
    assert final_step_guidance([5.0, 2.0], 0.5, [False, True]) == pytest.approx([5.0, 1.5])


def _guidance_per_step(model: ReMoGenModel, monkeypatch, guidance, share) -> dict[int, object]:
    seen: dict[int, object] = {}
    original = ReMoGenModel.predict_x0

    def recording(self, z_t, t, hist, text_emb, contexts, alpha, guidance, cache=None):
        seen[t] = guidance
        return original(self, z_t, t, hist, text_emb, contexts, alpha, guidance, cache)

    monkeypatch.setattr(ReMoGenModel, "predict_x0", recording)
    cfg = model.cfg
    hist = torch.zeros(1, cfg.history, cfg.feature_dim)
    job = DiffusionJob(model, hist, model.encode_text("a person walks"), Contexts({}), {}, guidance,
                       torch.Generator().manual_seed(0), final_guidance_share=share, final_guidance_min_speed=0.0)
    job.advance(job.total_steps)
    assert job.done and torch.isfinite(job.result).all()
    return seen


def test_only_the_last_step_takes_the_eased_guidance(tiny_model, monkeypatch):
    steps = tiny_model.cfg.diffusion_steps
    seen = _guidance_per_step(tiny_model, monkeypatch, 6.0, 0.4)
    assert sorted(seen) == list(range(steps))
    assert all(seen[t] == 6.0 for t in range(1, steps))
    assert seen[0] == pytest.approx(3.0)
    full = _guidance_per_step(tiny_model, monkeypatch, 6.0, 1.0)
    assert all(g == 6.0 for g in full.values())


def test_a_share_of_one_gives_the_former_full_guidance_result(tiny_model):
    cfg = tiny_model.cfg
    hist = torch.randn(1, cfg.history, cfg.feature_dim, generator=torch.Generator().manual_seed(3))
    text = tiny_model.encode_text("a person waves")

    def sample(share):
        job = DiffusionJob(tiny_model, hist, text, Contexts({}), {}, 4.0, torch.Generator().manual_seed(5),
                           final_guidance_share=share, final_guidance_min_speed=0.0)
        job.advance(job.total_steps)
        return job.result

    full, eased = sample(1.0), sample(0.25)
    # by hand: full guidance on every step, as sampling was before the share
    gen = torch.Generator().manual_seed(5)
    z = noise((1, cfg.latent_tokens, cfg.latent_dim), gen, hist.device)
    for t in range(cfg.diffusion_steps - 1, -1, -1):
        x0 = tiny_model.predict_x0(z, t, hist, text, Contexts({}), {}, 4.0)
        z = x0 if t == 0 else tiny_model.schedule.step(z, t, x0, noise(z.shape, gen, hist.device))
    assert torch.allclose(full, z, atol=1e-6)
    assert not torch.allclose(full, eased, atol=1e-4)     # the last step's guidance is visible in the latent


def _history_moving_at(model: ReMoGenModel, speeds: list[float]) -> torch.Tensor:
    """Normalised histories (B, H, D) whose pelvis moves straight along x at each speed (m/s)."""
    cfg = model.cfg
    feats = model.stats.denormalize(torch.zeros(len(speeds), cfg.history, cfg.feature_dim))
    frames = torch.arange(cfg.history, dtype=torch.float32) / model.fps
    feats[..., ROOT_T.start] = torch.tensor(speeds)[:, None] * frames
    return model.stats.normalize(feats)


def test_history_speed_reads_the_pelvis_of_normalised_histories(tiny_model):
    hist = _history_moving_at(tiny_model, [0.0, 0.15, 1.2])
    assert history_speed(tiny_model, hist) == pytest.approx([0.0, 0.15, 1.2], abs=1e-4)


def test_only_egos_that_move_get_the_eased_last_step(tiny_model):
    hist = _history_moving_at(tiny_model, [0.0, 0.1, 0.5, 1.2])
    job = DiffusionJob(tiny_model, hist, tiny_model.encode_text("a person walks"), Contexts({}), {}, 6.0,
                       [torch.Generator().manual_seed(i) for i in range(4)], final_guidance_share=0.4,
                       final_guidance_min_speed=0.2)
    assert job.final_guidance == pytest.approx([6.0, 6.0, 3.0, 3.0])
    job.advance(job.total_steps)
    assert torch.isfinite(job.result).all()


def test_sessions_follow_the_models_share(tiny_model):
    def frames(share):
        tiny_model.final_guidance_share = share
        tiny_model.final_guidance_min_speed = 0.0        # every ego, the standing start too
        try:
            s = ReactionSession(tiny_model, text="a person walks", seed=2, guidance=5.0)
            s.reset()
            return [s.step().joints for _ in range(12)]
        finally:
            tiny_model.final_guidance_share = DEFAULT_FINAL_GUIDANCE_SHARE
            tiny_model.final_guidance_min_speed = DEFAULT_FINAL_GUIDANCE_MIN_SPEED

    a, b, c = frames(0.4), frames(0.4), frames(1.0)
    assert all((x == y).all() for x, y in zip(a, b))          # deterministic for one share
    assert any(not (x == z).all() for x, z in zip(a, c))       # and the share reaches the session's jobs


@pytest.mark.parametrize("bad", [-0.1, 1.5, "half", True, float("nan")])
def test_a_share_outside_zero_to_one_is_refused(bad):
    with pytest.raises(InputError, match="final guidance share must be a number in 0..1"):
        check_final_guidance_share(bad)


def test_the_models_settings_refuse_a_bad_value_and_keep_their_own(tiny_model):
    before = tiny_model.final_guidance_share, tiny_model.final_guidance_min_speed
    with pytest.raises(InputError, match="final guidance share"):
        tiny_model.final_guidance_share = 1.5
    for bad in (-0.1, float("inf"), "fast"):
        with pytest.raises(InputError, match="final guidance min speed must be a finite number"):
            tiny_model.final_guidance_min_speed = bad
    assert (tiny_model.final_guidance_share, tiny_model.final_guidance_min_speed) == before
