"""Captions from dataset labels, phrased like HumanML3D ("a person ...") so the prior's text encoder
sees one style of sentence whatever the source."""
from __future__ import annotations

BANDAI_CONTENT = {
    "walk": "a person walks forward", "walk-back": "a person walks backwards", "walk-left": "a person walks to the left",
    "walk-right": "a person walks to the right", "walk-turn-left": "a person walks and turns left",
    "walk-turn-right": "a person walks and turns right", "run": "a person runs forward", "dash": "a person dashes forward",
    "bow": "a person bows", "bye": "a person waves goodbye", "byebye": "a person waves goodbye with both hands",
    "guide": "a person guides someone with a gesture", "respond": "a person responds to someone",
    "call": "a person calls out to someone", "punch": "a person punches", "kick": "a person kicks",
    "slash": "a person slashes with a sword", "dance-short": "a person dances", "dance-long": "a person dances",
    "wave-both-hands": "a person waves both hands", "wave-left-hand": "a person waves the left hand",
    "wave-right-hand": "a person waves the right hand", "raise-up-both-hands": "a person raises both hands",
    "raise-up-left-hand": "a person raises the left hand", "raise-up-right-hand": "a person raises the right hand",
}
BANDAI_STYLE = {
    "normal": "", "not-confident": "unconfidently", "chimpira": "like a thug", "musical": "like in a musical",
    "giant": "like a giant", "masculinity": "in a masculine way", "masculine": "in a masculine way",
    "feminine": "in a feminine way", "childish": "childishly", "old": "like an old person",
    "elderly": "like an elderly person", "youthful": "youthfully", "exhausted": "exhausted", "tired": "tired",
    "active": "actively", "happy": "happily", "sad": "sadly", "angry": "angrily", "proud": "proudly",
}
# HDM05 class-name prefixes (camel case) -> phrase; the longest matching prefix wins
HDM05 = {
    "walk": "a person walks", "walkRightCircle": "a person walks in a circle to the right",
    "walkLeftCircle": "a person walks in a circle to the left", "walkBackwards": "a person walks backwards",
    "walkLeft": "a person walks sideways to the left", "walkRight": "a person walks sideways to the right",
    "run": "a person runs", "jog": "a person jogs", "hop": "a person hops", "jump": "a person jumps",
    "sitDown": "a person sits down", "standUp": "a person stands up", "lieDown": "a person lies down",
    "kick": "a person kicks", "punch": "a person punches", "throw": "a person throws", "grab": "a person grabs something",
    "depositFloor": "a person puts something on the floor", "elbowToKnee": "a person touches elbow to knee",
    "clap": "a person claps", "turnLeft": "a person turns left", "turnRight": "a person turns right",
    "rotateArms": "a person rotates the arms", "squat": "a person squats", "skier": "a person does a skiing exercise",
    "cartwheel": "a person does a cartwheel", "shuffle": "a person shuffles", "staircase": "a person climbs stairs",
    "hit": "a person hits", "wave": "a person waves",
}


def bandai_caption(content: str, style: str) -> str:
    base = BANDAI_CONTENT.get(content, f"a person does {content.replace('-', ' ')}")
    how = BANDAI_STYLE.get(style, style.replace("-", " "))
    return f"{base}, {how}" if how else base


def hdm05_caption(class_name: str) -> str:
    best = max((k for k in HDM05 if class_name.startswith(k)), key=len, default=None)
    return HDM05[best] if best else f"a person does {class_name}"


def cmu_caption(description: str) -> str:
    d = description.strip().strip('"').lower()
    if not d:
        return "a person moves"
    return d if d.startswith("a person") else f"a person: {d}"
