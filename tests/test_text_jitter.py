"""Caption embeddings turned by a random angle (training/text_jitter.py) for the prior's training."""
import torch

from model_runtime.training.recipe import TEXT_JITTER_COS, WINDOW_RECIPES
from model_runtime.training.text_jitter import jitter_text


def _units(n: int = 2000, d: int = 64) -> torch.Tensor:
    return torch.nn.functional.normalize(torch.randn(n, d, generator=torch.Generator().manual_seed(3)), dim=-1)


def test_turned_rows_keep_unit_length_and_a_cosine_in_range():
    emb = _units()
    out = jitter_text(emb, 0.6, 0.5, torch.Generator().manual_seed(0))
    cos = (out * emb).sum(-1)
    turned = cos < 1.0 - 1e-5
    assert torch.allclose(out.norm(dim=-1), torch.ones(len(emb)), atol=1e-5)
    assert float(cos.min()) >= 0.6 - 1e-5
    assert 0.45 < float(turned.float().mean()) < 0.55          # the share asked for
    assert torch.equal(out[~turned], emb[~turned])              # the others untouched
    # the cosines spread over [0.6, 1], not bunched at one end
    assert 0.75 < float(cos[turned].mean()) < 0.85


def test_a_turned_vector_keeps_its_nearest_caption():
    """In many dimensions the random direction is nearly orthogonal to the other captions as well."""
    caps = _units(300, 256)
    out = jitter_text(caps, 0.6, 1.0, torch.Generator().manual_seed(1))
    assert bool(((out @ caps.T).argmax(1) == torch.arange(300)).all())


def test_switched_off_the_unknown_prompt_and_determinism():
    emb = _units(50)
    assert jitter_text(emb, 1.0, 0.5, torch.Generator().manual_seed(0)) is emb     # 1: no jitter
    emb[0] = 0.0                                                                    # the unknown prompt's vector
    a = jitter_text(emb, 0.6, 1.0, torch.Generator().manual_seed(5))
    b = jitter_text(emb, 0.6, 1.0, torch.Generator().manual_seed(5))
    assert torch.equal(a, b) and float(a[0].abs().sum()) == 0.0


def test_only_the_jitter_recipe_turns_captions():
    assert WINDOW_RECIPES["kicks_slowed_light_jitter"].text_jitter_cos == TEXT_JITTER_COS < 1.0
    assert all(r.text_jitter_cos == 1.0 for k, r in WINDOW_RECIPES.items() if k != "kicks_slowed_light_jitter")
