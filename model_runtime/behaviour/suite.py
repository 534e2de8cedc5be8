"""Run the behaviour suite: roll out every episode through a ReactionSession and aggregate the metrics."""
from __future__ import annotations

import time
from typing import TYPE_CHECKING, Callable, Iterable

import numpy as np

from ..errors import DEFAULT_GUIDANCE
from . import metrics as M
from .metrics import finite_mean as _mean
from .metrics import text_measures
from .scenarios import FAMILIES, GOAL_LIMIT_FRAMES, Episode, box_triangles, draw_episodes, walk_clip
from .text_targets import judge_text

if TYPE_CHECKING:
    from ..data.library import ClipLibrary

ALPHAS = (0.0, 1.0)


def scene_grid(ep: Episode):
    """The episode's obstacles as an OccupancyGrid (None without obstacles)."""
    if not ep.boxes:
        return None
    from ..voxel import OccupancyGrid
    v, f = box_triangles(ep.boxes)
    return OccupancyGrid.from_triangles(v, f, voxel_size=0.05)


def has_cue(ep: Episode) -> bool:
    """Whether the episode gives the interaction modules anything to react to: a partner, a goal or obstacles."""
    return ep.partner is not None or ep.goal is not None or bool(ep.boxes)


def roll_out_frames(model, ep: Episode, alpha: float, *, guidance: float = DEFAULT_GUIDANCE,
                    **session_options) -> list:
    """The ego's EgoFrames in one episode, both interaction alphas set to `alpha`."""
    from ..session import ReactionSession
    s = ReactionSession(model, text=ep.text, seed=ep.seed, alpha={"hhi": alpha, "hsi": alpha},
                        guidance=guidance, scene=scene_grid(ep), **{"fwsr": True, **session_options})
    s.reset(root_position=(0.0, 0.0, 0.0), yaw=0.0)
    return [s.step(partner=None if ep.partner is None else ep.partner[i], goal=ep.goal) for i in range(ep.frames)]


def roll_out(model, ep: Episode, alpha: float, *, guidance: float = DEFAULT_GUIDANCE, **session_options) -> np.ndarray:
    """(frames, 22, 3) world joints of the ego in one episode, both interaction alphas set to `alpha`."""
    frames = roll_out_frames(model, ep, alpha, guidance=guidance, **session_options)
    return np.stack([f.joints for f in frames]).astype(np.float32, copy=False)


def episode_metrics(ep: Episode, ego: np.ndarray) -> dict:
    """Every metric that applies to this episode's family."""
    out = {"toe_speeds": M.planted_toe_speed(ego),
           "seam_steps": _seam_split(ego), "peak_pelvis_speed": M.peak_pelvis_speed(ego)}
    if ep.partner is not None:
        out["min_clearance_m"] = M.min_joint_clearance(ego, ep.partner)
    if ep.family == "approach":
        out["facing_error_deg"] = float(M.facing_error_deg(ego[-1], ep.partner[-1, 0]))
    if ep.goal is not None:
        reached, closest, settle = M.goal_arrival(ego, ep.goal, GOAL_LIMIT_FRAMES)
        out.update(reached=reached, closest_m=closest, settle_m=settle)
    if ep.boxes:
        out["inside_frames"] = M.frames_inside_boxes(ego, ep.boxes)
    if ep.family == "walk_forward":
        out["net_yaw_deg_per_20s"] = M.net_yaw_deg(ego, 20.0)
    if ep.family == "stand":
        out["drift_m_per_min"] = M.standing_drift_m(ego, 60.0)
    if ep.family == "text":
        out.update(text_measures(ego))
    return out


def _seam_split(ego: np.ndarray) -> tuple[float, int, float, int]:
    """(sum of seam steps, count, sum of other steps, count): pooled into a family's seam ratio."""
    steps = M.joint_steps(ego)
    t = np.arange(1, len(steps) + 1)
    seam = t % M.SEAM_PERIOD == 0
    return float(steps[seam].sum()), int(seam.sum()), float(steps[~seam].sum()), int((~seam).sum())


def summarise(family: str, results: list[dict]) -> dict:
    """Family-level numbers (the ones README and the model card report) from per-episode metrics."""
    s = {"episodes": len(results)}
    seam, ns, other, no = (sum(r["seam_steps"][k] for r in results) for k in range(4))
    s["seam_ratio"] = float((seam / max(ns, 1)) / max(other / max(no, 1), 1e-9))
    toes = np.concatenate([r["toe_speeds"] for r in results]) if results else np.zeros(0)
    s["planted_toe_cm_s"] = float(toes.mean() * 100.0) if toes.size else float("nan")
    s["percent_dragged_toe_steps"] = M.dragged_toe_percent(toes)
    s["percent_glide"] = float(100.0 * np.mean([r["peak_pelvis_speed"] > M.GLIDE_SPEED for r in results]))
    if "min_clearance_m" in results[0]:
        c = np.array([r["min_clearance_m"] for r in results])
        s.update(min_clearance_mean_m=float(c.mean()), min_clearance_min_m=float(c.min()),
                 percent_under_10cm=float(100.0 * (c < 0.10).mean()),
                 percent_under_20cm=float(100.0 * (c < 0.20).mean()))
    if family == "approach":
        f = np.array([r["facing_error_deg"] for r in results])
        s.update(facing_error_mean_deg=float(f.mean()), percent_within_45deg=float(100.0 * (f <= 45.0).mean()))
    if "reached" in results[0]:
        s.update(reach_percent=float(100.0 * np.mean([r["reached"] for r in results])),
                 closest_mean_m=_mean(r["closest_m"] for r in results),
                 settle_mean_m=_mean(r["settle_m"] for r in results))
    if "inside_frames" in results[0]:
        s["inside_obstacle_percent"] = float(100.0 * np.concatenate([r["inside_frames"] for r in results]).mean())
    if family == "walk_forward":
        y = np.abs([r["net_yaw_deg_per_20s"] for r in results])
        s.update(abs_net_yaw_mean_deg=float(y.mean()), percent_within_20deg=float(100.0 * (y <= 20.0).mean()))
    if family == "stand":
        s["drift_mean_m_per_min"] = _mean(r["drift_m_per_min"] for r in results)
    if family == "text":
        s.update(judge_text(results))      # per prompt and per kind: statistic, mean, target, pass
    return s


def real_reference() -> dict:
    """The metrics that apply to real motion, on the shipped real walk (seams at the same 8-frame period)."""
    joints, _ = walk_clip()
    toes = M.planted_toe_speed(joints)
    return {"walk_clip": {"seam_ratio": M.seam_ratio(joints),
                          "planted_toe_cm_s": float(toes.mean() * 100.0),
                          "percent_dragged_toe_steps": M.dragged_toe_percent(toes),
                          "net_yaw_deg_per_20s": M.net_yaw_deg(joints, 20.0)}}


def run_suite(model, split: str, *, families: Iterable[str] = FAMILIES, episodes: int | None = None,
              alphas: Iterable[float] = ALPHAS, guidance: float = DEFAULT_GUIDANCE,
              progress: Callable[[str], None] | None = None, keep_tracks: int = 12,
              library: ClipLibrary | None = None,
              diversity_seeds: int = 0, **session_options) -> dict:
    """Every family at every alpha: {"families": {family: {"alpha=A": summary}}, "tracks": ..., "reference"}.

    library: a ClipLibrary for the text family's real-clip references (report["reference"]["text"]) and
    the diversity reference. diversity_seeds > 0 adds report["diversity"] (diversity.py): every diversity
    prompt rolled out with that many seeds.
    """
    families = list(families)
    report: dict = {"split": split, "families": {}, "reference": real_reference()}
    if "text" in families:
        from .real_clips import text_reference
        report["reference"]["text"] = text_reference(library) if library is not None else \
            {"absent": "no clip library given (--library PATH)"}
    tracks: dict = {}
    for family in families:
        eps = draw_episodes(family, split) if episodes is None else draw_episodes(family, split, episodes)
        # nothing for the interaction modules or their costs to act on: every alpha rolls out the same frames
        # (tests/test_behaviour_suite.py checks it), so the first alpha's rollouts serve them all
        cue_free = not any(has_cue(ep) for ep in eps)
        first: float | None = None
        for alpha in alphas:
            if cue_free and first is not None:
                done = report["families"][family]
                done[f"alpha={alpha:g}"] = dict(done[f"alpha={first:g}"], seconds=0.0, same_as=f"alpha={first:g}")
                if first in tracks.get(family, {}):   # none kept with keep_tracks=0
                    tracks[family][alpha] = tracks[family][first]
                if progress is not None:
                    progress(f"{family} alpha={alpha:g}: the alpha={first:g} rollouts (no partner, goal or scene)")
                continue
            t0, results = time.perf_counter(), []
            for k, ep in enumerate(eps):
                ego = roll_out(model, ep, alpha, guidance=guidance, **session_options)
                r = episode_metrics(ep, ego)
                r["prompt"] = ep.text
                results.append(r)
                if k < keep_tracks:
                    tracks.setdefault(family, {}).setdefault(alpha, []).append((ep, ego))
            first = alpha if first is None else first
            summary = summarise(family, results)
            summary["seconds"] = round(time.perf_counter() - t0, 1)
            report["families"].setdefault(family, {})[f"alpha={alpha:g}"] = summary
            if progress is not None:
                progress(f"{family} alpha={alpha:g}: {len(eps)} episodes in {summary['seconds']} s")
    if diversity_seeds > 0:
        from .diversity import diversity_report
        report["diversity"] = diversity_report(model, split, seeds=diversity_seeds, library=library,
                                               guidance=guidance, progress=progress, **session_options)
    report["tracks"] = tracks
    return report
