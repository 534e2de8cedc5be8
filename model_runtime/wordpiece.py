"""BERT's uncased tokenisation (the basic split and greedy longest-match WordPiece), for the static text table.

Written out here (about 40 lines) rather than taken from the `tokenizers` package so that the runtime needs
nothing beyond PyTorch and NumPy: Blender's bundled Python gets no compiled tokenizer wheel, and the table
only needs the uncased BERT rules below. The table build checks that this gives the same tokens as the
package on every sentence it measures. Torch-free.
"""
from __future__ import annotations

import unicodedata

MAX_WORD_CHARS = 100   # BERT's limit: a longer word is one unknown token


def is_punctuation(ch: str) -> bool:
    cp = ord(ch)
    # BERT counts every non-alphanumeric ASCII character as punctuation ("$", "^", "`" included)
    if 33 <= cp <= 47 or 58 <= cp <= 64 or 91 <= cp <= 96 or 123 <= cp <= 126:
        return True
    return unicodedata.category(ch).startswith("P")


def _is_cjk(cp: int) -> bool:
    return (0x4E00 <= cp <= 0x9FFF or 0x3400 <= cp <= 0x4DBF or 0x20000 <= cp <= 0x2A6DF or 0x2A700 <= cp <= 0x2B73F
            or 0x2B740 <= cp <= 0x2B81F or 0x2B820 <= cp <= 0x2CEAF or 0xF900 <= cp <= 0xFAFF
            or 0x2F800 <= cp <= 0x2FA1F)


def basic_tokens(text: str) -> list[str]:
    """Lower-cased, accent-stripped words and punctuation marks; CJK characters are words of their own;
    control characters are dropped."""
    chars = []
    for ch in text:
        cp = ord(ch)
        if ch.isspace():
            chars.append(" ")
        elif cp == 0 or cp == 0xFFFD or unicodedata.category(ch) in ("Cc", "Cf", "Cn", "Co"):
            continue
        elif _is_cjk(cp):
            chars.append(f" {ch} ")
        else:
            chars.append(ch)
    text = unicodedata.normalize("NFD", "".join(chars).lower())
    text = "".join(ch for ch in text if unicodedata.category(ch) != "Mn")
    out: list[str] = []
    for word in text.split():
        piece = ""
        for ch in word:
            if is_punctuation(ch):
                out += [piece, ch] if piece else [ch]
                piece = ""
            else:
                piece += ch
        if piece:
            out.append(piece)
    return out


def wordpiece(word: str, vocab: dict[str, int]) -> list[int] | None:
    """Greedy longest-match-first sub-word ids ('##' marks a continuation); None when the word cannot be
    pieced from the vocabulary (BERT's unknown token)."""
    if len(word) > MAX_WORD_CHARS:
        return None
    ids, start = [], 0
    while start < len(word):
        end = len(word)
        while end > start:
            piece = word[start:end] if start == 0 else "##" + word[start:end]
            if piece in vocab:
                ids.append(vocab[piece])
                break
            end -= 1
        if end == start:
            return None
        start = end
    return ids


def token_ids(text: str, vocab: dict[str, int]) -> list[int]:
    """The vocabulary ids of a text; unknown words are left out (as model2vec does)."""
    out: list[int] = []
    for word in basic_tokens(text):
        ids = wordpiece(word, vocab)
        if ids:
            out += ids
    return out
