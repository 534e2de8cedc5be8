import numpy as np
import pytest
import torch

from model_runtime.model import Contexts
from model_runtime.nets.interaction import compose_residuals
from model_runtime.session import ReactionSession
from model_runtime.skeleton import rest_joints


def test_clamp_never_exceeds_largest_branch_norm():
    g = torch.Generator().manual_seed(0)
    for _ in range(200):
        n = int(torch.randint(1, 4, (1,), generator=g))
        deltas = [torch.randn(3, 5, 8, generator=g) * float(torch.rand(1, generator=g) * 4) for _ in range(n)]
        alphas = [float(a) for a in torch.rand(n, generator=g) * 3]
        out = compose_residuals(deltas, alphas)
        largest = torch.stack([d.flatten(1).norm(dim=1) for d in deltas]).max(0).values
        assert (out.flatten(1).norm(dim=1) <= largest * (1 + 1e-5)).all()


def test_clamp_leaves_small_sums_unchanged():
    a = torch.randn(2, 4, 6)
    b = -0.5 * a  # opposing branches: the sum is smaller than either
    out = compose_residuals([a, b], [1.0, 1.0])
    assert torch.equal(out, a + b)
    half = compose_residuals([a], [0.5])
    assert torch.equal(half, 0.5 * a)


def test_clamp_scales_large_sums_to_the_largest_branch():
    a = torch.randn(2, 4, 6)
    out = compose_residuals([a, a.clone()], [1.0, 1.0])
    assert torch.allclose(out.flatten(1).norm(dim=1), a.flatten(1).norm(dim=1), rtol=1e-5)


def test_no_branches_is_no_residual():
    assert compose_residuals([], []) is None


def test_alpha_zero_everywhere_gives_exactly_the_prior(tiny_model):
    m = tiny_model
    cfg = m.cfg
    g = torch.Generator().manual_seed(1)
    z = torch.randn(1, cfg.latent_tokens, cfg.latent_dim, generator=g)
    hist = torch.randn(1, cfg.history, cfg.feature_dim, generator=g)
    te = m.encode_text("walk forward")
    partner = torch.randn(1, cfg.partner_window, 22, 3, generator=g)
    present = torch.ones(1, cfg.partner_window, dtype=torch.bool)
    occ = (torch.rand(1, 32, 32, 32, generator=g) > 0.8).float()
    with torch.inference_mode():
        ctx = m.encode_contexts(partner, present, occ, torch.zeros(1, 3), {"hhi": 1, "hsi": 1})
        prior = m.predict_x0(z, 4, hist, te, Contexts({}), {}, 5.0)
        zero = m.predict_x0(z, 4, hist, te, ctx, {"hhi": 0.0, "hsi": 0.0}, 5.0)
        on = m.predict_x0(z, 4, hist, te, ctx, {"hhi": 1.0, "hsi": 1.0}, 5.0)
    assert torch.equal(prior, zero)
    assert not torch.allclose(prior, on)


@pytest.mark.parametrize("cleanup", [False, True])
def test_session_with_alpha_zero_matches_prior_only_session(tiny_model, cleanup):
    """With control and cleanup off, alpha 0 is the prior bit for bit; with test-time control and the
    planted-foot cleanup on, alpha 0 still reads no partner (the frames equal those of a run without one)."""
    from model_runtime.bench import approaching_partner
    partner = approaching_partner(20)
    frames = {}
    for name, alpha, use_partner in (("prior", {"hhi": 1.0, "hsi": 1.0}, False),
                                     ("zero", {"hhi": 0.0, "hsi": 0.0}, True),
                                     ("on", {"hhi": 1.0, "hsi": 0.0}, True)):
        s = ReactionSession(tiny_model, text="walk", seed=3, alpha=alpha, fwsr=False, cleanup=cleanup, control=cleanup)
        s.reset()
        frames[name] = np.stack([s.step(partner=partner[i] if use_partner else None).joints for i in range(20)])
    assert np.array_equal(frames["prior"], frames["zero"])
    assert not np.allclose(frames["prior"], frames["on"])


def test_gradient_flows_through_the_clamp_at_zero_residual():
    """Zero-initialised modules start at Delta = 0; the clamp must not cut their gradient there."""
    d = torch.zeros(2, 3, 4, requires_grad=True)
    out = compose_residuals([d], [1.0])
    (out * torch.randn(2, 3, 4)).sum().backward()
    assert d.grad.abs().sum() > 0


def test_zero_initialised_module_learns(tiny_model):
    """One optimiser step on a zero-initialised module changes its output (end to end through the clamp)."""
    import copy
    m = copy.deepcopy(tiny_model)
    mim = m.mims["hhi"]
    mim.zero_init()
    cfg = m.cfg
    g = torch.Generator().manual_seed(0)
    z = torch.randn(4, cfg.latent_tokens, cfg.latent_dim, generator=g)
    hist = torch.randn(4, cfg.history, cfg.feature_dim, generator=g)
    partner = torch.randn(4, cfg.partner_window, 22, 3, generator=g)
    present = torch.ones(4, cfg.partner_window, dtype=torch.bool)
    text = m.denoiser.text_tokens(torch.randn(4, cfg.text_dim, generator=g), torch.zeros(4, dtype=torch.bool))
    t = torch.full((4,), 3)

    def run():
        ctx = m.encode_contexts(partner, present, None, None, {"hhi": 1.0})
        return m.denoiser(z, t, hist, text, m.injector(ctx, {"hhi": 1.0}))

    before = run().detach()
    opt = torch.optim.SGD(mim.parameters(), lr=0.1)
    run().pow(2).mean().backward()
    opt.step()
    assert not torch.allclose(run().detach(), before)


def test_line_cues_say_where_a_walker_passes_and_when():
    from model_runtime.nets.interaction import MAX_ARRIVAL_S, line_cues
    w = 10
    x = -3.0 + 0.1 * torch.arange(w, dtype=torch.float32)        # 1 m/s along +x ...
    partner = torch.zeros(1, w, 22, 3)
    partner[0, :, :, 0] = x[:, None]
    partner[0, :, :, 1] = 0.3                                     # ... on a line 0.3 m to the ego's left
    present = torch.ones(1, w, dtype=torch.bool)
    cues = line_cues(partner, present)[0]
    assert torch.allclose(cues[1:, 0], torch.full((w - 1,), 0.3), atol=1e-5)   # the ego is on the walker's right
    assert torch.allclose(cues[1:, 1] * MAX_ARRIVAL_S, -x[1:], atol=1e-4)      # seconds to the closest point
    assert torch.allclose(cues[1:, 2], torch.ones(w - 1), atol=1e-4)           # m/s
    assert torch.equal(cues[0], torch.zeros(3))                   # no velocity on the first frame
    mirrored = partner.clone()
    mirrored[..., 1] = -0.3
    assert torch.allclose(line_cues(mirrored, present)[0, 1:, 0], torch.full((w - 1,), -0.3), atol=1e-5)
    gaps = present.clone()
    gaps[0, 4] = False
    assert torch.equal(line_cues(partner, gaps)[0, 4:6], torch.zeros(2, 3))    # absent frames and the one after


def test_a_model_with_line_cues_encodes_partners_and_old_files_load_without_them(tmp_path):
    import dataclasses
    from model_runtime import load_model
    from model_runtime.checkpoint import save_model
    from model_runtime.model import ReMoGenModel
    plain = load_model(config="tiny")
    assert not plain.cfg.partner_line_cues                        # the default, and what older files hold
    cued = ReMoGenModel(dataclasses.replace(plain.cfg, partner_line_cues=True))
    assert cued.mims["hhi"].encoder.inp.in_channels == plain.mims["hhi"].encoder.inp.in_channels + 3
    partner = torch.randn(2, plain.cfg.partner_window, 22, 3)
    present = torch.ones(2, plain.cfg.partner_window, dtype=torch.bool)
    assert cued.mims["hhi"].encoder(partner, present).shape == plain.mims["hhi"].encoder(partner, present).shape
    save_model(cued, tmp_path / "cued.pt")
    assert load_model(tmp_path / "cued.pt", warn_untrained=False).cfg.partner_line_cues
