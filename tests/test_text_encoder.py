"""The static sub-word text encoder (distilled from all-MiniLM-L6-v2, shipped as a table), its tokeniser, the
checkpoints that name an encoder."""
from __future__ import annotations

import pytest
import torch

from model_runtime import ModelFileError, load_model, save_model
from model_runtime.config import PRESETS, STATIC_TEXT, TEXT_TABLE_ID, ModelConfig
from model_runtime.errors import InputError
from model_runtime.text import (STATIC_TABLE, CachedEncoder, HashedNgramEncoder, StaticSubwordEncoder,
                                build_text_encoder, load_table)
from model_runtime.wordpiece import basic_tokens, token_ids, wordpiece


@pytest.fixture(scope="module")
def static():
    return build_text_encoder(STATIC_TEXT)


def cos(enc, a: str, b: str) -> float:
    v = enc.encode([a, b])
    return float(v[0] @ v[1])


# ------------------------------------------------------------------------------ tokeniser

def test_basic_tokens_follow_bert_uncased():
    assert basic_tokens("Hello, World!") == ["hello", ",", "world", "!"]
    assert basic_tokens("  Café\tRÉSUMÉ\n") == ["cafe", "resume"]               # lower-cased, accents stripped
    assert basic_tokens("跳舞ok") == ["跳", "舞", "ok"]                           # CJK characters stand alone
    assert basic_tokens("a\u200bb\x00c") == ["abc"]                               # format and control chars dropped
    assert basic_tokens("it's 3:45") == ["it", "'", "s", "3", ":", "45"]


def test_wordpiece_is_greedy_longest_match():
    vocab = {"walk": 0, "##ing": 1, "##s": 2, "wal": 3, "##k": 4, "un": 5}
    assert wordpiece("walking", vocab) == [0, 1]      # "walk" beats "wal"
    assert wordpiece("walks", vocab) == [0, 2]
    assert wordpiece("unwalk", vocab) is None         # "##walk" is not in the vocabulary: the word is unknown
    assert wordpiece("w" * 101, {"w": 0, "##w": 1}) is None
    assert token_ids("walks, xyz walking", vocab) == [0, 2, 0, 1]   # unknown words and punctuation left out


# ------------------------------------------------------------------------------ the shipped table

def test_shipped_table_is_the_presets_table_and_small():
    table = load_table()
    assert table.id == TEXT_TABLE_ID, ("the shipped text table's id differs from config.TEXT_TABLE_ID: set it to "
                                       f"{table.id!r} (printed by python -m model_runtime.text_build)")
    assert table.dim == STATIC_TEXT["dim"] and table.vectors.dtype == torch.float16
    assert STATIC_TABLE.stat().st_size <= 40 * 2 ** 20
    for preset in ("default", "paper"):
        assert PRESETS[preset].text == STATIC_TEXT


def test_static_encoder_agrees_with_minilm_on_captions_and_paraphrases(static):
    """Pearson of pairwise cosine similarities against full MiniLM (its vectors of the measured sentences ship
    beside the table, so this needs no MiniLM)."""
    from model_runtime.text_build import MIN_PEARSON, agreement
    scores = agreement(static)
    assert set(scores) == {"captions", "paraphrases"}
    assert min(scores.values()) >= MIN_PEARSON, scores


def test_static_encoder_knows_meaning(static):
    assert cos(static, "a person sprints", "a person runs") > cos(static, "a person sprints", "a person sits") + 0.1
    assert cos(static, "a person leaps", "a person jumps") > 0.6
    assert cos(static, "a person leaps", "a person jumps") > cos(static, "a person leaps", "a person waves") + 0.1
    assert cos(static, "leap", "jump") > 0.6
    assert cos(static, "a person strolls leisurely", "a person walks slowly") > \
        cos(static, "a person strolls leisurely", "a person runs") + 0.1


def test_static_encoder_vectors(static):
    dim = STATIC_TEXT["dim"]
    v = static.encode(["a person walks", "A  Person WALKS", "跳舞 🙂", ""])
    assert v.shape == (4, dim) and v.dtype == torch.float32
    assert torch.allclose(v[0].norm(), torch.tensor(1.0)) and torch.equal(v[0], v[1])
    assert torch.equal(v[2], torch.zeros(dim)) and torch.equal(v[3], torch.zeros(dim))   # nothing readable
    assert static.encode_one("a person walks") is static.encode_one("a person walks")   # encoded once


def test_both_encoders_share_one_prompt_cache(static):
    assert isinstance(static, CachedEncoder) and isinstance(HashedNgramEncoder(dim=8, buckets=64), CachedEncoder)
    assert static.table is build_text_encoder(STATIC_TEXT).table     # the table is read once per process


# ------------------------------------------------------------------------------ checkpoints

# the text config stored in the default-preset files trained before the static encoder (the weights shipped
# until 2026-11-24 among them)
OLD_DEFAULT_TEXT = {"name": "hashed_ngram", "dim": 128, "buckets": 8192, "seed": 1234}


@pytest.mark.filterwarnings("ignore:.*untrained")   # random weights, saved and loaded again on purpose
def test_older_hashed_default_checkpoints_still_load(tmp_path):
    from dataclasses import replace

    from model_runtime.model import ReMoGenModel
    old = ReMoGenModel(replace(PRESETS["default"], text=dict(OLD_DEFAULT_TEXT)))
    model = load_model(save_model(old, tmp_path / "old.pt"))
    assert model.cfg.text == OLD_DEFAULT_TEXT and isinstance(model.text_encoder, HashedNgramEncoder)
    assert torch.equal(model.encode_text("a person walks"), old.encode_text("a person walks"))
    assert model.encode_text("a person walks").shape == (1, model.cfg.text_dim)


def test_shipped_checkpoint_reads_prompts_with_the_static_encoder():
    model = load_model()
    assert model.cfg.text == STATIC_TEXT and isinstance(model.text_encoder, StaticSubwordEncoder)


@pytest.mark.filterwarnings("ignore:.*untrained")   # random weights, saved and loaded again on purpose
def test_tiny_hashed_and_default_static_checkpoints_round_trip(tmp_path, tiny_model):
    assert isinstance(tiny_model.text_encoder, HashedNgramEncoder)
    again = load_model(save_model(tiny_model, tmp_path / "tiny.pt"))
    assert again.cfg.text == tiny_model.cfg.text
    assert torch.equal(again.encode_text("a person jumps"), tiny_model.encode_text("a person jumps"))
    model = load_model(config="default")
    assert isinstance(model.text_encoder, StaticSubwordEncoder) and model.cfg.text_dim == STATIC_TEXT["dim"]
    again = load_model(save_model(model, tmp_path / "default.pt"))
    assert again.cfg.text == STATIC_TEXT and isinstance(again.text_encoder, StaticSubwordEncoder)


def test_checkpoint_of_another_text_table_is_refused_in_one_line(tmp_path):
    model = load_model(config="default")
    path = save_model(model, tmp_path / "m.pt")
    payload = torch.load(path, weights_only=True)
    payload["config"]["text"]["table"] = "0123456789abcdef"
    torch.save(payload, path)
    with pytest.raises(ModelFileError) as err:
        load_model(path)
    msg = str(err.value)
    assert "\n" not in msg and "text table 0123456789abcdef" in msg and TEXT_TABLE_ID in msg


@pytest.mark.parametrize("text, words", [
    ({"name": "bert", "dim": 32}, "text['name'] = 'bert' must be one of hashed_ngram, minilm_static"),
    ({"name": "minilm_static", "dim": 128}, "must have exactly the fields dim, name, table"),
    ({"name": "minilm_static", "dim": 128, "table": "x y"}, "must be a text table id"),
    ({"name": "minilm_static", "dim": 0, "table": "abc"}, "text['dim'] = 0"),
    ({"name": "hashed_ngram", "dim": 32, "buckets": 64, "seed": 1, "table": "abc"}, "exactly the fields"),
])
def test_text_config_is_checked_per_encoder(text, words):
    with pytest.raises(InputError) as err:
        ModelConfig(text=text)
    assert words in str(err.value)
