"""What the text family's prompts are judged on: each prompt's kind, the kind's statistic and its target.

A kind names one thing a prompt asks for ("run", "wave", ...). Its statistic is a key of
metrics.text_measures, computed on every episode; a prompt passes when the mean over its episodes meets the
target, and a kind passes when the mean over all its prompts' episodes does. A kind without a target
(dance) is reported, not judged. `caption` picks the real clips whose statistic is the kind's reference
(real_clips.py).

The family's prompts are, for each kind, one literal prompt of the kind the data's captions use and the
held-out paraphrases of data/phrasings.py (wording that appears in no caption).
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass

from ..data.phrasings import HELD_OUT_PROMPTS
from .metrics import finite_mean as _mean

HELD_OUT_PER_KIND = 2      # 8 kinds x (1 literal + 2 held out) = 24 prompts: 2 episodes each of the 48


@dataclass(frozen=True)
class TextTarget:
    statistic: str                 # a key of metrics.text_measures
    low: float | None = None       # the mean must be at least this
    high: float | None = None      # and at most this
    caption: str = ""              # regex on a real clip's caption: the clips this kind is compared with

    @property
    def target(self) -> str:
        """'>= 2 m/s', '0.4-0.9 m/s', '<= 0.1 m/s' or '' (reported only)."""
        unit = UNITS[self.statistic]
        if self.low is not None and self.high is not None:
            return f"{self.low:g}-{self.high:g} {unit}"
        if self.low is not None:
            return f">= {self.low:g} {unit}"
        return f"<= {self.high:g} {unit}" if self.high is not None else ""

    def judge(self, value: float) -> bool | None:
        """Whether `value` meets the target; None when the kind has none. A missing value fails."""
        if self.low is None and self.high is None:
            return None
        if value is None or not math.isfinite(value):
            return False
        return (self.low is None or value >= self.low) and (self.high is None or value <= self.high)

    def matches(self, caption: str) -> bool:
        return bool(self.caption) and re.search(self.caption, caption) is not None


UNITS = {"speed_mps": "m/s", "airborne_percent": "% of frames airborne", "max_ankle_height_m": "m ankle height",
         "wave_sd_m": "m side-to-side wrist sd", "travel_vs_facing_deg": "deg travel vs facing",
         "wrist_speed_mps": "m/s wrist speed"}

KINDS: dict[str, TextTarget] = {
    "run": TextTarget("speed_mps", low=2.0, caption=r"^a person (runs|dashes|sprints)\b"),
    "walk slowly": TextTarget("speed_mps", low=0.4, high=0.9, caption=r"^a person walks slowly\b"),
    "stand": TextTarget("speed_mps", high=0.1, caption=r"^a person (stands|stays|remains)\b"),
    "jump": TextTarget("airborne_percent", low=10.0, caption=r"^a person jumps\b"),
    "kick": TextTarget("max_ankle_height_m", low=0.4, caption=r"^a person kicks\b"),
    "wave": TextTarget("wave_sd_m", low=0.08, caption=r"^a person waves\b"),
    "backwards": TextTarget("travel_vs_facing_deg", low=150.0, caption=r"^a person walks backwards\b"),
    "dance": TextTarget("wrist_speed_mps", caption=r"^a person dances\b"),
}

LITERAL_PROMPTS = {
    "a person runs": "run", "a person walks slowly": "walk slowly", "a person stands": "stand",
    "a person jumps": "jump", "a person kicks": "kick", "a person waves": "wave",
    "a person walks backwards": "backwards", "a person dances": "dance",
}


def _family_prompts() -> dict[str, str]:
    """prompt -> kind: every kind's literal prompt first, then its held-out paraphrases, round by round, so
    the first episodes of the family already cover every kind."""
    held = {k: [p for p, kind in HELD_OUT_PROMPTS.items() if kind == k][:HELD_OUT_PER_KIND] for k in KINDS}
    out = dict(LITERAL_PROMPTS)
    for r in range(HELD_OUT_PER_KIND):
        out.update({held[k][r]: k for k in KINDS if r < len(held[k])})
    return out


PROMPT_KINDS: dict[str, str] = _family_prompts()
TEXT_PROMPTS: tuple[str, ...] = tuple(PROMPT_KINDS)


def is_held_out(prompt: str) -> bool:
    """Whether the prompt is a paraphrase that appears in no caption."""
    return prompt in HELD_OUT_PROMPTS


def _row(kind: str, episodes: list[dict]) -> dict:
    t = KINDS[kind]
    measured = _mean(r[t.statistic] for r in episodes)
    return {"kind": kind, "statistic": t.statistic, "measured": measured, "target": t.target,
            "pass": t.judge(measured), "episodes": len(episodes)}


def judge_text(results: list[dict]) -> dict:
    """Per-episode text measures (each with its "prompt") -> {"prompts": {prompt: row}, "kinds": {kind: row},
    "passed": counts}. A row: kind, statistic, measured (mean over its episodes), target, pass (None: no
    target), episodes; prompt rows add held_out and the mean of every other measure. Prompts of no kind
    (not in PROMPT_KINDS) get their measures only."""
    by_prompt: dict[str, list[dict]] = {}
    for r in results:
        by_prompt.setdefault(r["prompt"], []).append(r)
    keys = [k for k in results[0] if k in UNITS or k.endswith(("_m", "_percent", "_mps", "_deg"))] if results else []
    prompts, by_kind = {}, {}
    for p, rs in by_prompt.items():
        kind = PROMPT_KINDS.get(p)
        row = _row(kind, rs) if kind else {"kind": None, "episodes": len(rs)}
        row["held_out"] = is_held_out(p)
        row["measures"] = {k: _mean(r[k] for r in rs) for k in keys}
        prompts[p] = row
        if kind:
            by_kind.setdefault(kind, []).extend(rs)
    kinds = {k: {**_row(k, rs), "prompts": sum(1 for p in by_prompt if PROMPT_KINDS.get(p) == k)}
             for k, rs in by_kind.items()}
    judged_p = [r["pass"] for r in prompts.values() if r.get("pass") is not None]
    judged_k = [r["pass"] for r in kinds.values() if r["pass"] is not None]
    held = [r["pass"] for r in prompts.values() if r["held_out"] and r.get("pass") is not None]
    return {"prompts": prompts, "kinds": kinds,
            "passed": {"prompts": sum(judged_p), "prompts_judged": len(judged_p),
                       "held_out_prompts": sum(held), "held_out_prompts_judged": len(held),
                       "kinds": sum(judged_k), "kinds_judged": len(judged_k)}}
