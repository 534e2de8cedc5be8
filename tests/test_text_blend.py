"""Prompt vectors moved toward their nearest training phrasing (model_runtime/text_blend.py)."""
import pytest
import torch

from model_runtime.text import StaticSubwordEncoder, load_table
from model_runtime.text_blend import PhrasingBlend, training_phrasings

CAPTIONS = ["a person runs", "a person walks forward", "a person waves the right hand"]


@pytest.fixture(scope="module")
def base():
    return StaticSubwordEncoder(load_table())


def test_a_training_phrasing_keeps_its_own_vector(base):
    """Even at keep 0.5: its nearest phrasings are itself and near-copies ("the person runs")."""
    blend = PhrasingBlend(base, training_phrasings(CAPTIONS), keep=0.5)
    for text in ("a person runs", "someone is walking forward", "a person stands still"):
        assert float(blend.encode([text])[0] @ base.encode([text])[0]) > 0.999, text


def test_a_paraphrase_moves_toward_its_nearest_phrasing_by_the_share_asked(base):
    phrasings = training_phrasings(CAPTIONS)
    text = "someone sprints across the room"
    own = base.encode([text])[0]
    nearest = base.encode(phrasings)[(base.encode(phrasings) @ own).argmax()]
    moved = {keep: PhrasingBlend(base, phrasings, keep=keep).encode([text])[0] for keep in (1.0, 0.8, 0.0)}
    assert torch.allclose(moved[1.0], own, atol=1e-5)
    assert torch.allclose(moved[0.0], nearest, atol=1e-3)
    assert float(moved[0.8] @ nearest) > float(own @ nearest)
    assert abs(float(moved[0.8].norm()) - 1.0) < 1e-5


def test_unknown_prompt_stays_zero_and_bad_settings_are_refused(base):
    blend = PhrasingBlend(base, training_phrasings(CAPTIONS), keep=0.8)
    assert float(blend.encode(["\u4f60\u597d"])[0].abs().sum()) == 0.0
    with pytest.raises(ValueError, match="outside 0-1"):
        PhrasingBlend(base, CAPTIONS, keep=1.5)
    with pytest.raises(ValueError, match="no phrasings"):
        PhrasingBlend(base, [], keep=0.8)


def test_training_phrasings_hold_the_added_captions():
    ph = training_phrasings(["a person runs"])
    assert {"a person runs", "a person stands still", "a person walks slowly", "a person walks backwards"} <= set(ph)
    assert len(ph) == len(set(ph))
