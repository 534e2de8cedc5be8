"""Behaviour plots: top-view paths per family (alpha 0 beside alpha 1) and stick-figure strips."""
from __future__ import annotations

from pathlib import Path

from ..evaluation.plots import _pyplot, save_figure



def plot_family_paths(family: str, runs: dict, out_png: str | Path) -> Path:
    """runs: {alpha: [(episode, ego joints)]}. Ego pelvis paths (start dot), partner paths, goals, obstacles."""
    plt = _pyplot()
    alphas = sorted(runs)
    fig, axes = plt.subplots(1, len(alphas), figsize=(5.0 * len(alphas), 5.0), squeeze=False)
    colours = plt.get_cmap("tab20")
    for ax, alpha in zip(axes[0], alphas):
        for k, (ep, ego) in enumerate(runs[alpha]):
            c = colours(k % 20)
            for b in ep.boxes:
                ax.add_patch(plt.Rectangle(b.lo[:2], b.hi[0] - b.lo[0], b.hi[1] - b.lo[1], color="0.6", alpha=0.5))
            if ep.partner is not None:
                ax.plot(ep.partner[:, 0, 0], ep.partner[:, 0, 1], color=c, lw=0.8, ls="--", alpha=0.6)
            if ep.goal is not None:
                ax.plot(ep.goal[0], ep.goal[1], marker="*", color=c, ms=9)
            ax.plot(ego[:, 0, 0], ego[:, 0, 1], color=c, lw=1.4)
            ax.plot(ego[-1, 0, 0], ego[-1, 0, 1], marker="o", color=c, ms=3)
        ax.plot(0, 0, marker="^", color="k", ms=8)
        ax.set_aspect("equal")
        ax.set_title(f"{family}, alpha {alpha:g}: ego (solid), partner (dashed), goal (star)", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3)
    return save_figure(plt, fig, out_png, dpi=100)


def plot_report(report: dict, out_dir: str | Path, strips: int = 2) -> list[Path]:
    """All path plots, and stick-figure strips of the first episodes of the partner families at alpha 1."""
    from ..evaluate import plot_reaction_strip
    out_dir = Path(out_dir)
    written = [plot_family_paths(f, runs, out_dir / f"paths_{f}.png") for f, runs in report["tracks"].items()]
    for family in ("crossing", "approach", "obstacles"):
        runs = report["tracks"].get(family, {}).get(1.0, [])
        for ep, ego in runs[:strips]:
            written.append(plot_reaction_strip(ego, ep.partner, out_dir / f"strip_{family}_{ep.index}.png",
                                               title=f"{family} {ep.index}: {ep.text}, alpha 1"))
    return written
