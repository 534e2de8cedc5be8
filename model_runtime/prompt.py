"""A one-line warning for a prompt the text encoders cannot read. Torch-free (the Blender panel calls it).

Both text encoders read English words: after lower-casing and accent stripping, the static table keeps
ASCII tokens only and the hashed encoder ASCII letters and digits. A prompt in another script, or made of
emoji and symbols, embeds like an empty prompt (or close to it), so the motion ignores it; that deserves a
warning, while an empty prompt (no text on purpose) does not.
"""
from __future__ import annotations

from .wordpiece import basic_tokens, is_punctuation

_SHOWN = 40   # characters of the prompt quoted in the warning


def _is_english_word(token: str) -> bool:
    return token.isascii() and any(ch.isalpha() for ch in token)


def prompt_warning(text: str) -> str | None:
    """None when the prompt is empty or mostly English words; else one line saying what is wrong and what
    to do."""
    if not isinstance(text, str) or not text.strip():
        return None
    words = [t for t in basic_tokens(text) if not (len(t) == 1 and is_punctuation(t))]
    shown = text.strip() if len(text.strip()) <= _SHOWN else text.strip()[:_SHOWN - 3] + "..."
    known = sum(_is_english_word(w) for w in words)
    if known == 0:
        return (f"the prompt {shown!r} has no English word the text encoder can read, so the motion ignores it "
                "(as with an empty prompt); describe the motion in English")
    if known * 2 < len(words):
        return (f"most of the prompt {shown!r} is outside the text encoder's English vocabulary (another script, "
                "emoji or symbols), so the motion barely follows it; write the prompt in English")
    return None
