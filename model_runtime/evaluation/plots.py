"""PNG plots (matplotlib, Agg): training curves from the stage logs and a stick-figure strip of a reaction."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..skeleton import PARENTS
from .metrics import FPS

def _pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def read_training_logs(log_dir: str | Path) -> dict[str, dict[str, np.ndarray]]:
    """{stage: {"step", "loss", "val_step", "val_loss"}} from every *.log.jsonl in log_dir (bad lines skipped)."""
    out: dict[str, dict[str, list]] = {}
    for path in sorted(Path(log_dir).glob("*.log.jsonl")):
        for line in path.read_text().splitlines():
            try:
                row = json.loads(line)
                stage, step, loss = str(row.get("stage", path.name.split(".")[0])), int(row["step"]), float(row["loss"])
            except (ValueError, KeyError, TypeError):
                continue
            d = out.setdefault(stage, {"step": [], "loss": [], "val_step": [], "val_loss": []})
            d["step"].append(step)
            d["loss"].append(loss)
            if row.get("val_loss") is not None:
                d["val_step"].append(step)
                d["val_loss"].append(float(row["val_loss"]))
    return {k: {kk: np.asarray(vv, np.float64) for kk, vv in v.items()} for k, v in out.items()}


def plot_training_curves(log_dir: str | Path, out_png: str | Path) -> Path | None:
    """One panel per stage: training loss (raw and smoothed) and validation loss. None when no logs."""
    logs = read_training_logs(log_dir)
    if not logs:
        return None
    plt = _pyplot()
    n = len(logs)
    fig, axes = plt.subplots(1, n, figsize=(4.2 * n, 3.4), squeeze=False)
    for ax, (stage, d) in zip(axes[0], logs.items()):
        order = np.argsort(d["step"], kind="stable")
        step, loss = d["step"][order], d["loss"][order]
        ax.plot(step, loss, color="0.75", lw=0.6, label="train")
        k = max(1, len(loss) // 50)
        if k > 1:
            sm = np.convolve(loss, np.ones(k) / k, mode="valid")
            ax.plot(step[k - 1:], sm, color="tab:blue", lw=1.4, label=f"train (mean of {k})")
        if d["val_loss"].size:
            ax.plot(d["val_step"], d["val_loss"], "o-", color="tab:orange", ms=3, label="validation")
        if (loss > 0).all():
            ax.set_yscale("log")
        ax.set_title(stage)
        ax.set_xlabel("step")
        ax.legend(fontsize=7)
    axes[0][0].set_ylabel("loss")
    return save_figure(plt, fig, out_png)


def save_figure(plt, fig, out_png: str | Path, dpi: int = 110) -> Path:
    """Lay out, write (making the folder) and close a figure."""
    fig.tight_layout()
    out_png = Path(out_png)
    out_png.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out_png, dpi=dpi)
    plt.close(fig)
    return out_png


def _bones(ax, joints: np.ndarray, dims: tuple[int, int], color: str, alpha: float = 1.0) -> None:
    for i, p in enumerate(PARENTS):
        if p >= 0:
            ax.plot(joints[[p, i], dims[0]], joints[[p, i], dims[1]], color=color, lw=1.2, alpha=alpha)


def plot_reaction_strip(ego: np.ndarray, partner: np.ndarray | None, out_png: str | Path, n: int = 6,
                        title: str = "") -> Path:
    """Stick figures at n evenly spaced frames: top view (x-y) above, side view (along the longer horizontal
    extent, against z) below; ego blue, partner red. ego, partner (T, 22, 3)."""
    plt = _pyplot()
    t = ego.shape[0]
    idx = np.linspace(0, t - 1, min(n, t)).round().astype(int)
    pts = ego if partner is None else np.concatenate((ego, partner), 1)
    lo, hi = pts.min((0, 1)) - 0.3, pts.max((0, 1)) + 0.3
    side = 1 if hi[1] - lo[1] > hi[0] - lo[0] else 0   # side view across the longer horizontal extent
    fig, axes = plt.subplots(2, len(idx), figsize=(2.4 * len(idx), 5.2), squeeze=False)
    for c, f in enumerate(idx):
        for r, dims in enumerate(((0, 1), (side, 2))):
            ax = axes[r][c]
            if partner is not None:
                _bones(ax, partner[f], dims, "tab:red")
            _bones(ax, ego[f], dims, "tab:blue")
            if r == 0:   # the ego's path so far, for orientation
                ax.plot(ego[:f + 1, 0, 0], ego[:f + 1, 0, 1], color="tab:blue", lw=0.6, alpha=0.4)
            ax.set_xlim(lo[dims[0]], hi[dims[0]])
            ax.set_ylim(min(lo[dims[1]], 0.0) if r else lo[dims[1]], hi[dims[1]])
            ax.set_aspect("equal")
            ax.tick_params(labelsize=6)
            if r == 0:
                ax.set_title(f"t = {f / FPS:.1f} s", fontsize=8)
        axes[0][c].set_xlabel("x (top view)", fontsize=7)
        axes[1][c].set_xlabel(f"{'xy'[side]} (side view)", fontsize=7)
    axes[0][0].set_ylabel("y", fontsize=7)
    axes[1][0].set_ylabel("z", fontsize=7)
    if title:
        fig.suptitle(title, fontsize=9)
    return save_figure(plt, fig, out_png)
