"""Captions from dataset labels, phrased like HumanML3D ("a person ...") so the prior's text encoder
sees one style of sentence whatever the source.

- Bandai: the JSON beside each BVH holds content and style ids that index (0-based) the lines of the
  dataset's cfg/content_label.txt and cfg/style_label.txt ("dataset-1_walk-left", "dataset-1_tired").
- HDM05: camel-case class names ("walkRightCircle4StepsRstart"), in file names like
  HDM_bd_walkRightCircle4StepsRstart_001_120.amc.
- CMU: the trial description from an index CSV row ("slow walk", "dance - small jetes, pirouette").
"""
from __future__ import annotations

import csv
import json
import re
from functools import lru_cache
from pathlib import Path

BANDAI_CONTENT = {
    "walk": "a person walks forward", "walk-back": "a person walks backwards",
    "walk-left": "a person walks to the left", "walk-right": "a person walks to the right",
    "walk-turn-left": "a person walks and turns left", "walk-turn-right": "a person walks and turns right",
    "run": "a person runs forward", "dash": "a person dashes forward", "bow": "a person bows",
    "bye": "a person waves goodbye", "byebye": "a person waves goodbye with both hands",
    "guide": "a person guides someone the way with a gesture", "respond": "a person responds to someone",
    "call": "a person calls out to someone", "punch": "a person punches", "kick": "a person kicks",
    "slash": "a person slashes with a sword", "dance-short": "a person dances", "dance-long": "a person dances",
    "wave-both-hands": "a person waves both hands", "wave-left-hand": "a person waves the left hand",
    "wave-right-hand": "a person waves the right hand", "raise-up-both-hands": "a person raises both hands",
    "raise-up-left-hand": "a person raises the left hand", "raise-up-right-hand": "a person raises the right hand",
}
BANDAI_STYLE = {
    "normal": "", "happy": "happily", "sad": "sadly", "angry": "angrily", "proud": "proudly",
    "not-confident": "unconfidently", "masculinity": "in a masculine way", "masculine": "in a masculine way",
    "feminine": "in a feminine way", "childish": "childishly", "old": "like an old person",
    "elderly": "like an elderly person", "tired": "tired", "exhausted": "exhausted", "active": "actively",
    "musical": "like in a musical", "giant": "like a giant", "chimpira": "like a thug", "youthful": "youthfully",
}

# HDM05 class-name prefixes (camel case) -> phrase; the longest matching prefix wins
HDM05 = {
    "walk": "a person walks", "walkBackwards": "a person walks backwards",
    "walkLeft": "a person walks sideways to the left", "walkRight": "a person walks sideways to the right",
    "walkLeftCircle": "a person walks in a circle to the left",
    "walkRightCircle": "a person walks in a circle to the right",
    "walkOnPlace": "a person walks on the spot", "walkLeftCrossFront": "a person steps sideways to the left, crossing the legs",
    "walkRightCrossFront": "a person steps sideways to the right, crossing the legs",
    "jog": "a person jogs", "jogLeftCircle": "a person jogs in a circle to the left",
    "jogRightCircle": "a person jogs in a circle to the right", "jogOnPlace": "a person jogs on the spot",
    "run": "a person runs", "runOnPlace": "a person runs on the spot", "sneak": "a person sneaks forward",
    "shuffle": "a person shuffles sideways", "staircaseUp": "a person walks up the stairs",
    "staircaseDown": "a person walks down the stairs", "hopBothLegs": "a person hops on both legs",
    "hopLLeg": "a person hops on the left leg", "hopRLeg": "a person hops on the right leg",
    "jumpDown": "a person jumps down", "jumpingJack": "a person does jumping jacks", "jump": "a person jumps",
    "sitDown": "a person sits down", "sitDownChair": "a person sits down on a chair",
    "sitDownFloor": "a person sits down on the floor", "sitDownTable": "a person sits down on a table",
    "sitDownKneelTieShoes": "a person kneels down to tie the shoes", "standUp": "a person stands up",
    "standUpSitChair": "a person stands up from a chair", "standUpSitFloor": "a person stands up from the floor",
    "standUpLieFloor": "a person gets up from lying on the floor", "standUpKneelToStand": "a person stands up from kneeling",
    "lieDown": "a person lies down", "lieDownFloor": "a person lies down on the floor",
    "kickLFront": "a person kicks forward with the left leg", "kickRFront": "a person kicks forward with the right leg",
    "kickLSide": "a person kicks sideways with the left leg", "kickRSide": "a person kicks sideways with the right leg",
    "kick": "a person kicks", "punchLFront": "a person punches forward with the left hand",
    "punchRFront": "a person punches forward with the right hand",
    "punchLSide": "a person punches sideways with the left hand",
    "punchRSide": "a person punches sideways with the right hand", "punch": "a person punches",
    "throwBasketball": "a person throws a basketball", "throwFar": "a person throws something far",
    "throwSitting": "a person throws something while sitting", "throwStanding": "a person throws something",
    "throw": "a person throws something", "grabFloor": "a person picks something up from the floor",
    "grabHigh": "a person reaches up and grabs something", "grabMiddle": "a person grabs something in front",
    "grab": "a person grabs something", "depositFloor": "a person puts something on the floor",
    "depositHigh": "a person puts something up high", "depositMiddle": "a person puts something down in front",
    "deposit": "a person puts something down", "elbowToKnee": "a person touches the elbow to the opposite knee",
    "clap": "a person claps", "clapAboveHead": "a person claps above the head", "hitRHandHead": "a person taps the head with the right hand",
    "turnLeft": "a person turns left", "turnRight": "a person turns right",
    "rotateArmsBothBackward": "a person circles both arms backwards",
    "rotateArmsBothForward": "a person circles both arms forwards",
    "rotateArmsLBackward": "a person circles the left arm backwards",
    "rotateArmsLForward": "a person circles the left arm forwards",
    "rotateArmsRBackward": "a person circles the right arm backwards",
    "rotateArmsRForward": "a person circles the right arm forwards", "rotateArms": "a person circles the arms",
    "squat": "a person squats", "skier": "a person does a skiing exercise", "cartwheel": "a person does a cartwheel",
    "exercise": "a person exercises", "dance": "a person dances", "wave": "a person waves",
}

# CMU descriptions: whole phrases first, then the first word's verb
CMU_PHRASES = {
    "walk": "a person walks", "slow walk": "a person walks slowly", "brisk walk": "a person walks briskly",
    "walk/stride": "a person walks with long strides", "slow walk/stride": "a person walks slowly with long strides",
    "walk, exaggerated stride": "a person walks with exaggerated strides",
    "walk on uneven terrain": "a person walks on uneven terrain", "run": "a person runs",
    "run/jog": "a person jogs", "jump": "a person jumps", "forward jump": "a person jumps forward",
    "jump, balance": "a person jumps and keeps balance", "punch/strike": "a person punches",
    "swordplay": "a person fights with a sword", "wash self": "a person washes themselves",
}
CMU_TOPICS = {"dance": "a person dances", "basketball": "a person plays basketball",
              "playground": "a person plays on a playground", "boxing": "a person boxes",
              "golf": "a person plays golf", "soccer": "a person plays football"}
_IRREGULAR = {"go": "goes", "do": "does", "wash": "washes", "reach": "reaches", "catch": "catches",
              "punch": "punches", "stretch": "stretches", "march": "marches", "push": "pushes",
              "toss": "tosses", "cross": "crosses", "touch": "touches", "fly": "flies", "carry": "carries"}
_VERBS = {"walk", "run", "jump", "climb", "sit", "stand", "bend", "scoop", "rise", "lift", "turn", "kick",
          "throw", "dribble", "shoot", "hop", "skip", "dance", "step", "lower", "rock", "dangle", "balance",
          "crawl", "fall", "spin", "wave", "bow", "pick", "drink", "swing", "squat", "stretch", "reach",
          "push", "pull", "carry", "catch", "punch", "march", "jog", "look", "point", "clap", "roll",
          "wash", "go", "do", "touch", "toss", "cross", "sweep", "mop", "sneak", "tiptoe", "limp", "shuffle"}


def bandai_caption(content: str, style: str) -> str:
    """'walk-left', 'tired' -> 'a person walks to the left, tired'."""
    base = BANDAI_CONTENT.get(content, f"a person does {content.replace('-', ' ')}")
    how = BANDAI_STYLE.get(style, style.replace("-", " "))
    return f"{base}, {how}" if how else base


def hdm05_caption(class_name: str) -> str:
    """'walkRightCircle4StepsRstart' -> 'a person walks in a circle to the right'."""
    best = max((k for k in HDM05 if class_name.startswith(k)), key=len, default=None)
    if best:
        return HDM05[best]
    words = re.sub(r"([a-z])([A-Z0-9])", r"\1 \2", class_name).lower()
    return f"a person does {re.sub(r'[0-9].*$', '', words).strip() or class_name}"


def _third_person(phrase: str) -> str:
    """'climb' -> 'climbs', 'scoop up' -> 'scoops up'; other phrases stay as they are."""
    words = phrase.split()
    if not words or words[0] not in _VERBS:
        return phrase
    v = words[0]
    words[0] = _IRREGULAR.get(v, v + "s")
    return " ".join(words)


def _join(items: list[str]) -> str:
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " and " + items[-1]


def cmu_caption(description: str) -> str:
    """A CMU trial description -> a sentence ('slow walk' -> 'a person walks slowly',
    'playground - climb, sit' -> 'a person plays on a playground: climbs and sits')."""
    d = re.sub(r"\s+", " ", description.strip().strip('"').lower())
    if not d:
        return "a person moves"
    if d.startswith("a person"):
        return d
    if d in CMU_PHRASES:
        return CMU_PHRASES[d]
    topic, _, rest = d.partition(" - ")
    if rest and topic in CMU_TOPICS:
        return f"{CMU_TOPICS[topic]}: {_join([_third_person(p.strip()) for p in rest.split(',') if p.strip()])}"
    parts = [p.strip() for p in d.replace(" - ", ", ").split(",") if p.strip()]
    first = CMU_PHRASES.get(parts[0])
    if first is None:
        verb = _third_person(parts[0])
        first = f"a person {verb}" if verb != parts[0] else f"a person: {parts[0]}"
    others = [_third_person(p) for p in parts[1:]]
    return f"{first}, {_join(others)}" if others else first


# ------------------------------------------------------------------------------ lookups

def bandai_labels(path: str | Path) -> tuple[str, str] | None:
    """(content, style) of a Bandai BVH: from its JSON ids and the dataset's cfg labels, else its name."""
    path = Path(path)
    meta = path.with_suffix(".json")
    cfg = path.parent.parent / "cfg"
    if meta.exists() and (cfg / "content_label.txt").exists():
        try:
            ids = json.loads(meta.read_text())
            content = _labels(cfg / "content_label.txt")[int(ids["content"])]
            style = _labels(cfg / "style_label.txt")[int(ids["style"])]
            return content, style
        except (ValueError, KeyError, IndexError, TypeError):
            pass              # a malformed JSON falls back on the file name
    m = re.match(r"dataset-\d+_(.+)_([a-z-]+)_\d+$", path.stem)
    return (m.group(1), m.group(2)) if m else None


@lru_cache(maxsize=16)
def _labels(path: Path) -> list[str]:
    """Label lines with the 'dataset-N_' prefix removed."""
    return [re.sub(r"^dataset-\d+_", "", ln.strip()) for ln in path.read_text().splitlines() if ln.strip()]


@lru_cache(maxsize=8)
def _read_index(path: str, mtime: float) -> tuple[dict, ...]:
    with open(path, newline="", encoding="utf-8", errors="replace") as fh:
        return tuple(csv.DictReader(fh))


def _subject_trial(stem: str) -> tuple[int, int] | None:
    m = re.match(r"0*(\d+)_0*(\d+)$", stem)
    return (int(m.group(1)), int(m.group(2))) if m else None


def index_row(path: str | Path, index: str | Path, exact_only: bool = False) -> dict | None:
    """The row of an index CSV describing `path`: by its 'file' column (the path's tail), else
    (unless exact_only) by subject and trial ('07_01' or '007_01'; CMU's own trial list)."""
    index = Path(index)
    if not index.exists():
        return None
    rows = _read_index(str(index), index.stat().st_mtime)
    parts = Path(path).parts
    for r in rows:
        rel = Path((r.get("file") or r.get("path") or "").replace("\\", "/")).parts
        if rel and parts[-len(rel):] == rel:
            return dict(r)
    if exact_only:
        return None
    st = _subject_trial(Path(path).stem)
    if st is None:
        return None
    for r in rows:
        try:
            if (int(r.get("subject") or r.get("Subject")), int(r.get("trial") or r.get("Trial #"))) == st:
                return dict(r)
        except (TypeError, ValueError):
            continue
    return None


def caption_for(path: str | Path, index: str | Path | None = None) -> str | None:
    """A caption for a motion file from whatever labels exist, else None."""
    path = Path(path)
    labels = bandai_labels(path) if path.stem.startswith("dataset-") else None
    if labels:
        return bandai_caption(*labels)
    m = re.match(r"HDM_[a-z]{2}_([A-Za-z][A-Za-z0-9]*?)_\d+", path.stem)
    if m:
        return hdm05_caption(m.group(1))
    row = index_row(path, index) if index is not None else None
    if row:
        if row.get("content") and row.get("style"):
            return bandai_caption(row["content"], row["style"])
        desc = row.get("caption") or row.get("Motion Description") or row.get("description")
        if desc:
            return cmu_caption(desc)
    return None
