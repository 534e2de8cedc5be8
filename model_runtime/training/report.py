"""What a training run tells its user: what it is doing while it sets up, and at the end what was saved where,
how far each stage got, its best held-out loss, and the command that continues it."""
from __future__ import annotations

import json
import shlex
import sys
from dataclasses import dataclass
from pathlib import Path


@dataclass
class StageRun:
    """The outcome of one call of train_stage."""
    stage: str
    model_path: Path            # EMA weights, loadable with load_model
    state_path: Path            # the resumable state
    log_path: Path              # one JSON line per step
    steps: int                  # steps done in total, earlier runs included
    total: int                  # steps the stage is set to train
    wall_s: float               # wall time of this run

    @property
    def finished(self) -> bool:
        return self.steps >= self.total


def say(msg: str) -> None:
    """One status line on stderr, at once (training sets up for a while before its progress bar)."""
    print(msg, file=sys.stderr, flush=True)


def validation_history(log_path: Path) -> list[tuple[int, float]]:
    """(step, held-out loss) of every validation in a stage's log (unreadable lines skipped)."""
    out = []
    if not log_path.is_file():
        return out
    with log_path.open() as fh:
        for line in fh:
            try:
                row = json.loads(line)
                if row.get("val_loss") is not None:
                    out.append((int(row["step"]), float(row["val_loss"])))
            except (ValueError, KeyError, TypeError, AttributeError):
                continue
    return out


def summary(runs: list[StageRun], stages: tuple[str, ...], argv: list[str], world: int) -> str:
    """The end-of-run report: per stage steps and best held-out loss, the files written, what to run next."""
    if not runs:
        return "nothing to train: every stage asked for is already done (delete its .state.pt to train it again)"
    lines = []
    for r in runs:
        history = validation_history(r.log_path)
        best = min(history, key=lambda sv: sv[1]) if history else None
        val = f"best held-out loss {best[1]:.4f} at step {best[0]:,}" if best else "no held-out loss yet"
        done = "done" if r.finished else "stopped early"
        lines.append(f"{r.stage}: {r.steps:,} of {r.total:,} steps ({done}, this run {r.wall_s / 60:.1f} min); {val}")
    last = runs[-1]
    lines.append(f"saved: {last.model_path} (the model, EMA weights); per stage STAGE.state.pt (resumable state) "
                 f"and STAGE.log.jsonl (losses) in {last.model_path.parent}")
    command = "python -m model_runtime.train " + " ".join(shlex.quote(a) for a in argv)
    if world > 1:
        command = "the same torchrun command"
    if not last.finished:
        bound = "" if "--minutes" in argv else "; add --minutes N to bound the run"
        lines.append(f"to continue: {command}   (resumes {last.stage} at step {last.steps:,}{bound})")
    elif last.stage in stages and last.stage != stages[-1]:
        nxt = stages[stages.index(last.stage) + 1]
        # the STAGE argument: the stage's name where no option precedes it as its value
        at = next((i for i, a in enumerate(argv) if a == last.stage and (i == 0 or not argv[i - 1].startswith("-"))),
                  None)
        if at is None:
            lines.append(f"to continue with {nxt}: {command}")
        else:
            lines.append("next stage: python -m model_runtime.train "
                         + " ".join(shlex.quote(a) for a in [*argv[:at], nxt, *argv[at + 1:]]))
    return "\n".join(lines)
