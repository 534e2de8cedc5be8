"""Several phrasings per caption, one drawn per training window, and held-out prompts that no phrasing contains."""
from __future__ import annotations

import pytest
import torch

from model_runtime.data.phrasings import (HELD_OUT_PROMPTS, caption_phrasings, ing_form, normalised_words,
                                          pick_phrasing, third_person)
from paths import DATA


def test_verb_forms():
    assert [third_person(v) for v in ("walk", "dash", "carry", "go", "punch", "play")] == \
        ["walks", "dashes", "carries", "goes", "punches", "plays"]
    assert [ing_form(v) for v in ("walk", "dance", "run", "lie", "tiptoe", "sit")] == \
        ["walking", "dancing", "running", "lying", "tiptoeing", "sitting"]


def test_a_bandai_caption_gets_subjects_tenses_synonyms_and_the_style_as_an_adjective():
    out = caption_phrasings("a person walks to the left, tired")
    assert out[0] == "a person walks to the left, tired" and len(out) == len(set(out))
    for p in ("someone walks to the left, tired", "a man is walking to the left, tired", "walk to the left, tired",
              "a woman walks to the left, wearily", "a tired person walks to the left",
              "a tired man is walking to the left"):
        assert p in out
    raised = caption_phrasings("a person raises the left hand, like an elderly person")
    assert "an elderly woman lifts the left hand" in raised and "lift the left hand, like a senior" in raised


def test_every_clause_verb_changes_form_and_unknown_wording_is_kept():
    out = caption_phrasings("a person walks and turns left")
    assert "a person is walking and turning left" in out and "walk and turn left" in out
    out = caption_phrasings("a person dances: small jetes and pirouette")
    assert "someone is dancing: small jetes and pirouette" in out   # only the part before the colon changes
    assert caption_phrasings("a person: golf swing") == ("a person: golf swing", "someone: golf swing",
                                                         "a man: golf swing", "a woman: golf swing",
                                                         "the person: golf swing")
    assert caption_phrasings("walk fast") == ("walk fast",)           # not a 'a person ...' caption: itself only


def test_pick_phrasing_repeats_with_a_seed_and_varies():
    draw = [pick_phrasing("a person punches", torch.Generator().manual_seed(3)) for _ in range(2)]
    assert draw[0] == draw[1]
    gen = torch.Generator().manual_seed(0)
    seen = {pick_phrasing("a person punches", gen) for _ in range(60)}
    assert len(seen) > 5 and seen <= set(caption_phrasings("a person punches"))


def test_training_windows_carry_phrasings_of_their_clip_caption():
    from model_runtime import load_model
    from model_runtime.training.samples import SegmentSampler
    from synthetic import synthetic_library
    lib = synthetic_library(6, 40)
    model = load_model(config="tiny")
    b = SegmentSampler(lib, list(range(6)), model.cfg, model.stats, seed=0).sample(64)
    allowed = {p for c in lib.captions for p in caption_phrasings(c)}
    assert set(b.text) <= allowed and len(set(b.text)) > len(set(lib.captions))


def test_held_out_prompts_are_in_no_phrasing_of_the_data_folder_captions():
    from model_runtime.data.clip_files import data_files
    if not (DATA / "cmu" / "index.csv").exists():
        pytest.skip("motion data not present beside the repository")
    captions = {f.caption for f in data_files(DATA)[0]}
    assert len(captions) > 50
    phrasings = [normalised_words(p) for c in captions for p in caption_phrasings(c)]
    assert len(HELD_OUT_PROMPTS) >= 8
    for prompt in HELD_OUT_PROMPTS:
        words = normalised_words(prompt)
        assert not any(words in p for p in phrasings), prompt


def test_wider_phrasings_add_synonyms_of_slow_and_backward_walks_only_when_asked():
    plain, wider = caption_phrasings("a person walks backwards, tired"), caption_phrasings(
        "a person walks backwards, tired", True)
    assert set(plain) < set(wider)
    assert "someone steps back, wearily" in wider and "someone steps back, wearily" not in plain
    assert "a person moves slowly" in caption_phrasings("a person walks slowly", True)
    assert caption_phrasings("a person punches", True) == caption_phrasings("a person punches")


def test_wider_phrasings_hold_no_word_of_a_held_out_prompt():
    from model_runtime.data.phrasings import WIDER_VERB_SYNONYMS
    held_words = {w for p in HELD_OUT_PROMPTS for w in normalised_words(p).split()}
    common = {"a", "an", "at", "in", "the", "to", "with"}     # words that carry no motion
    for subs in WIDER_VERB_SYNONYMS.values():
        for sub in subs:
            assert not (set(normalised_words(sub).split()) & held_words) - common, sub


def test_a_recipe_with_wider_phrasings_trains_on_them():
    from model_runtime import load_model
    from model_runtime.training.recipe import WINDOW_RECIPES
    from model_runtime.training.samples import SegmentSampler
    from synthetic import synthetic_library
    assert WINDOW_RECIPES["kicks_reversed"].wider_phrasings and not WINDOW_RECIPES["kicks"].wider_phrasings
    lib = synthetic_library(6, 40)
    lib.captions = ["a person walks backwards"] * len(lib.captions)
    model = load_model(config="tiny")
    texts = set(SegmentSampler(lib, list(range(6)), model.cfg, model.stats, seed=0, still_share=0.0,
                               wider_phrasings=True).sample(256).text)
    assert texts <= set(caption_phrasings("a person walks backwards", True))
    assert texts - set(caption_phrasings("a person walks backwards"))


def test_path_tails_go_onto_plain_locomotion_only_when_asked():
    from model_runtime.data.phrasings import PATH_TAILS, takes_path_tail, with_path_tail
    assert takes_path_tail("a person runs forward, happily") and takes_path_tail("a person walks backwards")
    assert not takes_path_tail("a person walks and turns left") and not takes_path_tail("a person walks to the left")
    assert not takes_path_tail("a person punches")
    assert with_path_tail("someone runs forward, cheerfully", "down the hall") == \
        "someone runs forward down the hall, cheerfully"                     # the style stays last
    assert with_path_tail("a happy man is running forward", "down the hall") == \
        "a happy man is running forward down the hall"
    # without tails the draws are exactly as before: no extra draw from the generator
    gen_a, gen_b = torch.Generator().manual_seed(5), torch.Generator().manual_seed(5)
    assert [pick_phrasing("a person runs forward", gen_a) for _ in range(20)] == \
        [pick_phrasing("a person runs forward", gen_b, path_tail_share=0.0) for _ in range(20)]
    gen = torch.Generator().manual_seed(0)
    drawn = [pick_phrasing("a person runs forward, tired", gen, path_tail_share=0.3) for _ in range(400)]
    tailed = [d for d in drawn if any(t in d for t in PATH_TAILS)]
    assert 0.2 < len(tailed) / len(drawn) < 0.4
    assert all(d.endswith(("tired", "tiredly", "wearily")) for d in tailed if ", " in d)   # the style stays last
    gen = torch.Generator().manual_seed(0)
    assert not any(any(t in pick_phrasing("a person punches", gen, path_tail_share=1.0) for t in PATH_TAILS)
                   for _ in range(50))


def test_no_path_tail_holds_a_held_out_prompt_word():
    from model_runtime.data.phrasings import PATH_TAILS
    held_out_words = {w for p in HELD_OUT_PROMPTS for w in normalised_words(p).split()} - {"the", "to"}
    assert not held_out_words & {w for t in PATH_TAILS for w in normalised_words(t).split()}
