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


def test_a_model_file_with_training_captions_reads_prompts_blended(tmp_path):
    """The record survives save and load; the runtime's encode_text blends, training's text_encoder does not."""
    from model_runtime import load_model, save_model
    from model_runtime.text_blend import blend_meta
    model = load_model(config="default", seed=0)
    assert model.prompt_blend is None                      # no record: prompts are read as they are
    path = save_model(model, tmp_path / "m.pt", meta={"prompt_blend": blend_meta(CAPTIONS, keep=0.8)})
    loaded = load_model(path, warn_untrained=False)
    assert loaded.meta["prompt_blend"] == {"keep": 0.8, "captions": sorted(CAPTIONS)}
    text = "someone sprints across the room"
    plain, read = loaded.text_encoder.encode([text])[0], loaded.encode_text(text)[0]
    assert torch.equal(plain, model.text_encoder.encode([text])[0])
    assert 0.9 < float(read @ plain) < 0.9999
    assert float(loaded.encode_text("a person runs")[0] @ loaded.text_encoder.encode(["a person runs"])[0]) > 0.999


def test_the_writer_keeps_the_weights_and_adds_the_train_split_captions(tmp_path):
    from model_runtime import load_model, save_model
    from model_runtime.text_blend import main
    from synthetic import synthetic_library
    lib = synthetic_library(20, 40)
    lib.save(tmp_path / "lib.npz")
    src = save_model(load_model(config="tiny", seed=0), tmp_path / "in.pt")
    assert main(["--model", str(src), "--library", str(tmp_path / "lib.npz"), "--out", str(tmp_path / "out.pt"),
                 "--keep", "0.7"]) == 0
    a, b = load_model(src, warn_untrained=False), load_model(tmp_path / "out.pt", warn_untrained=False)
    assert all(torch.equal(x, y) for x, y in zip(a.state_dict().values(), b.state_dict().values()))
    assert b.meta["prompt_blend"]["captions"] == sorted({lib.captions[i] for i in lib.split("train")})
    assert b.prompt_blend.keep == 0.7
    with pytest.raises(SystemExit):
        main(["--model", str(src), "--library", str(tmp_path / "lib.npz"), "--out", str(tmp_path / "x.pt"),
              "--keep", "2"])
    assert not (tmp_path / "x.pt").exists()


def test_warming_builds_the_phrasing_vectors_once(base):
    blend = PhrasingBlend(base, training_phrasings(CAPTIONS), keep=0.8)
    assert blend._bank is None                       # nothing encoded when a model loads
    blend.warm()
    bank = blend._bank
    assert bank is not None and bank.shape == (len(blend.phrasings), base.dim)
    blend.encode(["someone sprints across the room"])
    assert blend._bank is bank


def test_the_phrasings_do_not_fill_the_prompt_cache(base):
    """Thousands of phrasings would push a live rig's prompts out of the encoder's cache."""
    fresh = StaticSubwordEncoder(load_table())
    fresh.encode(["a person waves"])
    blend = PhrasingBlend(fresh, training_phrasings(CAPTIONS), keep=0.8)
    blend.warm()
    assert list(fresh._cache) == ["a person waves"]
    assert torch.equal(fresh.encode_uncached(["a person runs"])[0], base.encode(["a person runs"])[0])


def test_the_model_names_the_phrasing_a_prompt_leans_toward(tmp_path):
    from model_runtime import load_model, save_model
    from model_runtime.text_blend import blend_meta
    plain = load_model(config="default", seed=0)
    assert plain.nearest_phrasing("someone sprints across the room") is None      # no record: read as written
    path = save_model(plain, tmp_path / "m.pt", meta={"prompt_blend": blend_meta(CAPTIONS)})
    model = load_model(path, warn_untrained=False)
    phrasing, cos = model.nearest_phrasing("someone sprints across the room")
    assert phrasing in training_phrasings(CAPTIONS) and "run" in phrasing and 0.5 < cos < 0.9
    assert model.nearest_phrasing("a person runs")[1] > 0.999
    assert model.nearest_phrasing("\u4f60\u597d") is None


@pytest.mark.parametrize("record", [{"keep": 0.8}, {"keep": 0.8, "captions": [1, 2]}, {"keep": 2.0, "captions": ["a"]},
                                    {"keep": "x", "captions": ["a"]}, ["a person runs"]])
def test_a_damaged_record_is_refused_in_one_line(tmp_path, record):
    from model_runtime import load_model, save_model
    from model_runtime.errors import ModelFileError
    path = save_model(load_model(config="tiny", seed=0), tmp_path / "m.pt", meta={"prompt_blend": record})
    with pytest.raises(ModelFileError, match=r"meta\['prompt_blend'\] is damaged"):
        load_model(path, warn_untrained=False)
