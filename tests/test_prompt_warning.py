"""The one-line warning for prompts the text encoders cannot read (another script, only emoji or symbols)."""
from __future__ import annotations

import pytest

from model_runtime import prompt_warning


@pytest.mark.parametrize("text", ["一个人在跳舞", "человек прыгает", "🙂💃🕺", "!!! ???", "跳 jump 舞 踢"])
def test_unreadable_prompts_get_a_one_line_warning(text):
    msg = prompt_warning(text)
    assert msg is not None and "\n" not in msg and "English" in msg


@pytest.mark.parametrize("text", ["", "   ", "a person waves", "wave 👋", "Walk to the café, then wave!",
                                  "a person walks 3 steps"])
def test_readable_or_empty_prompts_get_none(text):
    assert prompt_warning(text) is None


def test_session_and_model_report_the_text_warning(tiny_model):
    from model_runtime import ReactionSession
    s = ReactionSession(tiny_model, text="человек прыгает")
    assert s.text_warning == tiny_model.text_warning("человек прыгает") is not None
    s.text = "a person jumps"
    assert s.text_warning is None
