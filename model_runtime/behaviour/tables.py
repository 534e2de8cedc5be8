"""Markdown tables of a behaviour report's text family and diversity, as README and the model card show them.

    python -m model_runtime.behaviour --table REPORT.json     # from a saved --json report
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


def report_tables(report: dict) -> str:
    """Every table the report has data for ('' when it has neither the text family nor diversity)."""
    parts = []
    text = report.get("families", {}).get("text", {})
    for alpha in ["alpha=1"] if "alpha=1" in text else text:      # the model as shipped; else what was run
        parts.append(f"Text family, {alpha}\n\n" + text_table(report, alpha))
    if "diversity" in report:
        parts.append("Diversity\n\n" + diversity_table(report))
    return "\n\n".join(parts)
