"""Markdown tables of a behaviour report's text family and diversity, as README and the model card show them.

    python -m model_runtime.behaviour --table REPORT.json [MORE.json ...]   # saved --json reports, joined
"""
from __future__ import annotations

import math

from .text_targets import UNITS


def _num(x) -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    return f"{x:.2f}" if abs(x) < 10 else f"{x:.0f}"


def _pass(p) -> str:
    return "-" if p is None else ("yes" if p else "no")


def _reference(refs: dict, kind: str | None) -> str:
    if "absent" in refs:
        return "-"
    r = refs.get(kind) if kind else None
    if not r or not r["clips"]:
        return "no clip"
    n = r["clips"]
    return f"{_num(r['mean'])} ({n} {'held-out ' if r['split'] == 'val' else ''}clip{'' if n == 1 else 's'})"


def text_table(report: dict, alpha: str = "alpha=1") -> str:
    """One row per prompt, then one per kind (the mean over all of its prompts' episodes)."""
    s = report["families"]["text"][alpha]
    refs = report.get("reference", {}).get("text", {"absent": ""})
    head = ["| prompt | kind | held out | statistic | measured | target | pass | real clips |",
            "|---|---|---|---|---|---|---|---|"]
    rows = [f"| {p} | {r['kind'] or '-'} | {'yes' if r['held_out'] else 'no'} | {r.get('statistic', '-')} | "
            f"{_num(r.get('measured'))} | {r.get('target') or '-'} | {_pass(r.get('pass'))} | "
            f"{_reference(refs, r['kind'])} |" for p, r in s["prompts"].items()]
    rows += [f"| **{k}: all {r['prompts']} prompts** | {k} | | {r['statistic']} | {_num(r['measured'])} | "
             f"{r['target'] or '-'} | {_pass(r['pass'])} | {_reference(refs, k)} |" for k, r in s["kinds"].items()]
    n = s["passed"]
    foot = (f"\n{alpha}: {n['prompts']}/{n['prompts_judged']} prompts pass ({n['held_out_prompts']}/"
            f"{n['held_out_prompts_judged']} held out), {n['kinds']}/{n['kinds_judged']} kinds. Statistics: "
            + "; ".join(f"{k} in {u}" for k, u in UNITS.items()) + ".")
    if "absent" in refs:
        foot += " Real clips: " + refs["absent"] + "."
    return "\n".join(head + rows) + "\n" + foot


def diversity_table(report: dict) -> str:
    """One row per diversity prompt: between-seed distance, real between-take distance, ratio, pass."""
    d = report["diversity"]
    head = ["| prompt | between seeds (m) | real between takes (m) | real pairs (match) | ratio | pass |",
            "|---|---|---|---|---|---|"]
    rows = [f"| {p} | {_num(r['between_seeds_m'])} | {_num(r['real_between_takes_m'])} | {r['real_pairs']}"
            f"{' (' + r['real_match'] + ')' if r['real_match'] else ''} | {_num(r['ratio'])} | {_pass(r['pass'])} |"
            for p, r in d["prompts"].items()]
    foot = (f"\n{d['seeds']} seeds x {d['frames']} frames; mean ratio {_num(d['ratio_mean'])} "
            f"(target >= {d['target_ratio']:g}): {_pass(d['pass'])}.")
    if "reference" in d:
        foot += " Real takes: " + d["reference"] + "."
    return "\n".join(head + rows) + "\n" + foot


_SEAM_ROW = None   # where the worst family's seam ratio goes
# (row name, target, family, summary key, unit, decimals)
_TARGET_ROWS = (
    ("partner crossing: episodes with min joint clearance >= 0.10 m", ">= 90 % at alpha 1", "crossing",
     "percent_clear_10cm", " %", 1),
    ("approach: mean final facing error", "<= 30 deg", "approach", "facing_error_mean_deg", " deg", 1),
    ("approach: episodes within 45 deg", ">= 85 %", "approach", "percent_within_45deg", " %", 1),
    ("approach: smallest clearance over episodes", ">= 0.2 m", "approach", "min_clearance_min_m", " m", 2),
    ("goal in any direction: reached within 0.5 m in 12 s", ">= 90 %", "goal", "reach_percent", " %", 1),
    ("goal in any direction: distance 2 s after arrival", "<= 0.3 m", "goal", "settle_mean_m", " m", 2),
    ("goal past obstacles: reached within 0.5 m in 12 s", ">= 90 %", "obstacles", "reach_percent", " %", 1),
    ("goal past obstacles: distance 2 s after arrival", "<= 0.3 m", "obstacles", "settle_mean_m", " m", 2),
    ("goal past obstacles: frames with a joint inside", "<= 1 %", "obstacles", "inside_obstacle_percent", " %", 2),
    _SEAM_ROW,
    ("planted-toe speed, walk forward", "<= 5 cm/s", "walk_forward", "planted_toe_cm_s", " cm/s", 2),
    ("planted-toe speed, stand", "<= 1 cm/s", "stand", "planted_toe_cm_s", " cm/s", 2),
    ("mean abs net yaw per 20 s, walk forward", "<= 20 deg", "walk_forward", "abs_net_yaw_mean_deg", " deg", 1),
    ("standing drift per minute", "<= 0.3 m", "stand", "drift_mean_m_per_min", " m", 2),
)


def _value(families: dict, family: str, alpha: int, key: str) -> float | None:
    s = families.get(family, {}).get(f"alpha={alpha}")
    if s is None:
        return None
    if key == "percent_clear_10cm":
        under = s.get("percent_under_10cm")
        return None if under is None else 100.0 - under
    return s.get(key)


def _fmt(v, unit: str, decimals: int) -> str:
    return "n/a" if v is None or (isinstance(v, float) and not math.isfinite(v)) else f"{v:.{decimals}f}{unit}"


def targets_table(report: dict) -> str:
    """The behaviour targets at alpha 1 and 0, with the worst seam ratio over the families run, and every
    family's seam ratio below it."""
    fam = report.get("families", {})
    seams = {(f, a): _value(fam, f, a, "seam_ratio") for f in fam for a in (1, 0)}
    seams = {k: v for k, v in seams.items() if v is not None}
    n = max((s.get("episodes", 0) for by in fam.values() for s in by.values()), default=0)
    control = {True: "control on", False: "control off"}.get(report.get("control"), "")
    head = [f"| metric ({n} episodes a family, {report.get('split', '?')} split{', ' + control if control else ''}) "
            "| target | alpha 1 | alpha 0 |", "|---|---|---|---|"]
    worst = {a: max(((v, f) for (f, b), v in seams.items() if b == a), default=(None, "-")) for a in (1, 0)}
    rows = []
    for row in _TARGET_ROWS:
        if row is _SEAM_ROW:
            if seams:
                rows.append(f"| seam ratio, worst family ({worst[1][1]} at alpha 1; {worst[0][1]} at alpha 0) | "
                            f"<= 1.3 | {_fmt(worst[1][0], '', 2)} | {_fmt(worst[0][0], '', 2)} |")
            continue
        name, target, family, key, unit, nd = row
        if family in fam:
            rows.append(f"| {name} | {target} | {_fmt(_value(fam, family, 1, key), unit, nd)} | "
                        f"{_fmt(_value(fam, family, 0, key), unit, nd)} |")
    per_family = ", ".join(f"{f} {_fmt(seams.get((f, 1)), '', 2)} / {_fmt(seams.get((f, 0)), '', 2)}"
                           for f in dict.fromkeys(f for f, _ in seams))
    foot = f"\nSeam ratio per family (alpha 1 / 0): {per_family}." if seams else ""
    return "\n".join(head + rows) + "\n" + foot


def merge_reports(reports: list[dict]) -> dict:
    """One report from several runs of the suite (e.g. the partner families in one, the text family with a
    library in another): families, references and diversity joined. Runs must share split and control
    setting, and no family may appear twice."""
    if not reports:
        raise ValueError("no report to merge")
    out = {k: v for k, v in reports[0].items() if k not in ("families", "reference")}
    out["families"], out["reference"] = {}, {}
    for r in reports:
        for key in ("split", "control"):
            if r.get(key) != reports[0].get(key):
                raise ValueError(f"the reports differ in {key} ({reports[0].get(key)!r} and {r.get(key)!r}); "
                                 "merge runs of one split and one control setting")
        for name, fam in r.get("families", {}).items():
            if name in out["families"]:
                raise ValueError(f"family {name!r} is in more than one report; give each family once")
            out["families"][name] = fam
        for name, ref in r.get("reference", {}).items():
            # a real reference wins over an "absent" placeholder from a run without a library
            if name not in out["reference"] or "absent" in out["reference"][name]:
                out["reference"][name] = ref
        if "diversity" in r:
            out["diversity"] = r["diversity"]
    return out


def report_tables(report: dict) -> str:
    """Every table the report has data for ('' when it has no family at all)."""
    parts = []
    if any(f != "text" for f in report.get("families", {})):
        parts.append("Behaviour targets\n\n" + targets_table(report))
    text = report.get("families", {}).get("text", {})
    for alpha in ["alpha=1"] if "alpha=1" in text else text:      # the model as shipped; else what was run
        parts.append(f"Text family, {alpha}\n\n" + text_table(report, alpha))
    if "diversity" in report:
        parts.append("Diversity\n\n" + diversity_table(report))
    return "\n\n".join(parts)
