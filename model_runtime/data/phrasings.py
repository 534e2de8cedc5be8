"""Several phrasings of one caption, so the prior learns the motion rather than one sentence.

A clip's caption (data/captions.py: "a person walks to the left, tired") is turned into the sentences a user
might type for the same motion: other subjects ("someone", "a man"), the present progressive ("a person is
walking to the left"), the imperative ("walk to the left"), verb and style synonyms ("lifts" for "raises",
"wearily" for "tired") and the style as an adjective ("a tired person walks to the left"). Training draws
one phrasing per window (training/samples.py); the clip's split and stored caption do not change.

HELD_OUT_PROMPTS are paraphrases that appear in no phrasing of any caption the data folder gives (a test
checks it), for measuring whether the prior follows wording it was never trained on.
"""
from __future__ import annotations

import re
from functools import lru_cache

import torch

SUBJECTS = ("a person", "someone", "a man", "a woman", "the person")
ADJECTIVE_SUBJECTS = ("person", "man", "woman")   # "a tired man ..."

# Base forms of the verbs captions start their clauses with; a clause starting with another word keeps its
# wording (only the subject changes).
VERBS = frozenset("""walk run jog dash bow wave guide respond call punch kick slash dance raise fight jump keep lift
    rise scoop bend play wash turn reach tiptoe grab sit stand hop skip squat clap climb step throw catch push pull
    carry stretch march sneak limp shuffle crawl spin roll fall swing look point touch cross lower rock dangle balance
    do go drink pick shoot dribble kneel lie sweep mop toss circle hold shake nod""".split())
_DOUBLED = frozenset("run jog hop skip step sit spin grab clap nod swim stop trip slip drop squat dig tap".split())

# Swaps of a clause's first words that keep the motion (third person, as captions are written).
VERB_SYNONYMS = {
    "dashes": ("rushes",), "punches": ("throws a punch",), "bows": ("takes a bow",), "raises": ("lifts",),
    "calls out to": ("shouts to",), "responds to": ("answers",), "guides": ("shows",), "slashes with": ("swings",),
    "washes": ("cleans",), "fights with": ("battles with",), "jogs": ("runs at a jog",),
    "walks briskly": ("walks at a brisk pace",), "walks slowly": ("walks at a slow pace",), "walks with long strides": ("walks with big steps",),
}
# More ways of saying the two kinds whose own captions are few (4 slow-walk takes; 15 backward takes beside the
# reversed copies of data/reversals.py), drawn only by a recipe that asks for them (WindowRecipe.wider_phrasings):
# the shipped text table and weights were built from the phrasings above alone. None holds a HELD_OUT_PROMPTS word.
WIDER_VERB_SYNONYMS = {
    "walks slowly": ("moves slowly", "takes slow steps", "walks at an easy pace"),
    "walks backwards": ("walks backward", "moves backwards", "steps backwards", "steps back", "walks in reverse"),
}
# Where a walk or run goes, in words that change nothing of its motion, drawn onto a share of the plain locomotion
# windows by a recipe that asks for them (WindowRecipe.path_tail_share): no caption names a destination, and the idea
# was that a prompt adding one ("... across the room") lands away from every caption of its own motion. Measured and
# not in the shipped weights: the shipped prior already runs when told "runs across the room" (2.1 m/s), and the
# tails did not speed up "sprints across the room" (docs/HISTORY.md, "Path tails"). None holds a HELD_OUT_PROMPTS
# word other than "the" and "to" (a test checks it).
PATH_TAILS = ("to the other side", "down the hall", "toward the door", "over to the wall", "down the street",
              "through the hallway", "from one end to the other", "down the corridor")
# The caption predicates (style removed) of plain locomotion with no direction of its own, which take a path tail.
PATH_PREDICATES = frozenset(("walks", "walks forward", "walks briskly", "walks slowly", "walks backwards", "runs",
                             "runs forward", "jogs", "dashes forward"))
# Bandai styles (the tail after ", ") -> other ways of saying it; and as an adjective of the subject.
STYLE_SYNONYMS = {
    "happily": ("cheerfully", "in a happy mood"), "sadly": ("sorrowfully", "in a sad mood"),
    "angrily": ("in anger", "furiously"), "proudly": ("with pride",), "unconfidently": ("timidly", "without confidence"),
    "in a masculine way": ("in a manly way",), "in a feminine way": ("in a ladylike way",),
    "childishly": ("like a child",), "like an old person": ("like someone old",),
    "like an elderly person": ("like a senior",), "tired": ("tiredly", "wearily"),
    "exhausted": ("worn out", "in an exhausted way"), "actively": ("energetically", "vigorously"),
    "like in a musical": ("theatrically",), "like a giant": ("as a giant would",), "like a thug": ("like a gangster",),
    "youthfully": ("in a youthful way",),
}
STYLE_ADJECTIVES = {
    "happily": "happy", "sadly": "sad", "angrily": "angry", "proudly": "proud", "unconfidently": "timid",
    "childishly": "childish", "tired": "tired", "exhausted": "exhausted", "actively": "energetic",
    "youthfully": "youthful", "like an old person": "old", "like an elderly person": "elderly",
}

# Paraphrases of the evaluation's text families that no caption phrasing contains (prompt -> family).
HELD_OUT_PROMPTS = {
    "someone sprints across the room": "run", "a person races ahead at top speed": "run",
    "a person strolls leisurely": "walk slowly", "someone ambles along unhurriedly": "walk slowly",
    "a person stays perfectly still": "stand", "someone remains motionless": "stand",
    "someone leaps into the air": "jump", "a person springs upward": "jump",
    "someone delivers a high kick": "kick", "a person strikes out with a foot": "kick",
    "someone waves hello": "wave", "a person signals hello with a wave": "wave",
    "a person backs away": "backwards", "someone retreats step by step": "backwards",
    "someone performs a lively dance": "dance", "a person grooves to music": "dance",
}


def third_person(verb: str) -> str:
    """'walk' -> 'walks', 'dash' -> 'dashes', 'carry' -> 'carries', 'go' -> 'goes'."""
    if verb in ("do", "go"):
        return verb + "es"
    if re.search(r"(s|sh|ch|x|z)$", verb):
        return verb + "es"
    if re.search(r"[^aeiou]y$", verb):
        return verb[:-1] + "ies"
    return verb + "s"


def ing_form(verb: str) -> str:
    """'walk' -> 'walking', 'dance' -> 'dancing', 'run' -> 'running', 'lie' -> 'lying'."""
    if verb.endswith("ie"):
        return verb[:-2] + "ying"
    if verb.endswith("e") and not verb.endswith(("ee", "oe", "ye")):
        return verb[:-1] + "ing"
    if verb in _DOUBLED:
        return verb + verb[-1] + "ing"
    return verb + "ing"


_BASE = {third_person(v): v for v in VERBS}


def _clauses(predicate: str) -> list[str]:
    """'walks and turns left' -> ['walks', ' and ', 'turns left']: clauses with their joints kept."""
    return re.split(r"(, | and )", predicate)


def _verb_form(predicate: str, form: str) -> str | None:
    """The predicate with every clause-leading verb in `form` ('third', 'ing' or 'base'); None when its first
    word is not a known verb (the caption then keeps its wording)."""
    head, colon, tail = predicate.partition(":")
    parts = _clauses(head)
    if parts[0].split(" ", 1)[0] not in _BASE:
        return None
    out = []
    for k, part in enumerate(parts):
        word, _, rest = part.partition(" ")
        base = _BASE.get(word) if k % 2 == 0 else None
        if base is None:
            out.append(part)
            continue
        new = {"third": word, "ing": ing_form(base), "base": base}[form]
        out.append(f"{new} {rest}".rstrip())
    return "".join(out) + colon + tail


def _predicate_variants(predicate: str, wider: bool = False) -> list[str]:
    """The predicate and its verb-synonym swaps (with WIDER_VERB_SYNONYMS too when `wider`)."""
    out = [predicate]
    tables = (VERB_SYNONYMS, WIDER_VERB_SYNONYMS) if wider else (VERB_SYNONYMS,)
    for table in tables:
        for key, subs in table.items():
            if predicate == key or predicate.startswith(key + " "):
                out += [sub + predicate[len(key):] for sub in subs]
    return out


def _split_style(caption: str) -> tuple[str, str]:
    """'a person bows, happily' -> ('a person bows', 'happily'); no known style tail -> (caption, '')."""
    head, sep, tail = caption.rpartition(", ")
    return (head, tail) if sep and tail in STYLE_SYNONYMS else (caption, "")


def _article(word: str) -> str:
    return "an" if word[0] in "aeiou" else "a"


@lru_cache(maxsize=4096)
def caption_phrasings(caption: str, wider: bool = False) -> tuple[str, ...]:
    """The caption first, then its other phrasings (no duplicates; `wider`: with WIDER_VERB_SYNONYMS). A caption
    not of the form 'a person ...' has only itself."""
    caption = caption.strip()
    if not caption.startswith("a person"):
        return (caption,)
    base, style = _split_style(caption)
    rest = base[len("a person"):]
    if not rest.startswith(" "):                   # "a person: dance - ..." keeps its wording past the subject
        return tuple(dict.fromkeys([caption] + [s + rest + (f", {style}" if style else "") for s in SUBJECTS]))
    styles = [style, *STYLE_SYNONYMS[style]] if style else [""]
    out = [caption]
    for predicate in _predicate_variants(rest[1:], wider):
        forms = {f: _verb_form(predicate, f) for f in ("third", "ing", "base")}
        if forms["third"] is None:
            forms = {"third": predicate, "ing": None, "base": None}
        for how in styles:
            tail = f", {how}" if how else ""
            for subject in SUBJECTS:
                out.append(f"{subject} {forms['third']}{tail}")
                if forms["ing"]:
                    out.append(f"{subject} is {forms['ing']}{tail}")
            if forms["base"]:
                out.append(f"{forms['base']}{tail}")
        adjective = STYLE_ADJECTIVES.get(style)
        if adjective:
            for noun in ADJECTIVE_SUBJECTS:
                subject = f"{_article(adjective)} {adjective} {noun}"
                out.append(f"{subject} {forms['third']}")
                if forms["ing"]:
                    out.append(f"{subject} is {forms['ing']}")
    return tuple(dict.fromkeys(out))


def takes_path_tail(caption: str) -> bool:
    """Whether a caption is plain locomotion without a direction of its own (PATH_PREDICATES)."""
    base, _ = _split_style(caption.strip())
    return base.startswith("a person ") and base[len("a person "):] in PATH_PREDICATES


_STYLE_WORDS = frozenset(STYLE_SYNONYMS) | {w for subs in STYLE_SYNONYMS.values() for w in subs}


def with_path_tail(phrasing: str, tail: str) -> str:
    """'someone runs forward, happily' + 'down the hall' -> 'someone runs forward down the hall, happily'."""
    head, sep, style = phrasing.rpartition(", ")
    if sep and style in _STYLE_WORDS:
        return f"{head} {tail}, {style}"
    return f"{phrasing} {tail}"


def pick_phrasing(caption: str, gen: torch.Generator, wider: bool = False, path_tail_share: float = 0.0) -> str:
    """One of the caption's phrasings, uniformly (drawn from `gen`, so a seeded sampler repeats); for a plain
    locomotion caption, with one of PATH_TAILS a `path_tail_share` of the time (no extra draw at 0, so recipes
    without tails draw exactly as before)."""
    options = caption_phrasings(caption, wider)
    out = options[int(torch.randint(0, len(options), (1,), generator=gen))] if len(options) > 1 else options[0]
    if path_tail_share > 0.0 and takes_path_tail(caption) and \
            float(torch.rand((), generator=gen)) < path_tail_share:
        out = with_path_tail(out, PATH_TAILS[int(torch.randint(0, len(PATH_TAILS), (1,), generator=gen))])
    return out


def normalised_words(text: str) -> str:
    """Lower-case words joined by single spaces, framed by spaces: for whole-word containment checks."""
    return " " + " ".join(re.findall(r"[a-z0-9]+", text.lower())) + " "
