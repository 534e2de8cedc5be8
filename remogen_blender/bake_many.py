"""`python -m remogen_blender.batch bake-many SHOTS.csv --jobs N`: the bakes of a shot list as local
processes, N at a time, for studios without a render farm.

Each shot is one process running `remogen bake` (the bpy module's `python -m remogen_blender.batch bake`,
or `BLENDER -b FILE -c remogen bake` with --blender). A failed shot is reported in one line and the others
go on; the exit status is 0 when every shot was baked, 1 when any failed, 2 for a bad shot list (then
nothing runs), 130 / 143 after Ctrl-C / SIGTERM: the running bakes are stopped between two model frames
and leave no output, partial or not.
"""
from __future__ import annotations

import argparse
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Callable, Sequence

from ._runtime import UserError
from .cli import _Parser, _Signals, _stop_on_signals, remove_partial_files
from .shot_list import COLUMNS_HELP, Shot, read_shots

STOP_GRACE_S = 60.0   # after a stop request, running bakes get this long to stop cleanly before a kill
POLL_S = 0.05

EPILOG = f"""\
The shot list is a CSV file with a header row naming its columns, in any order, then one row per bake.
An empty cell keeps the value saved in the .blend file. Paths are relative to the CSV file's folder.
Columns:
{COLUMNS_HELP}

Example:
  file,output,text,alpha_hhi,seed,frame_start,frame_end
  shots/sh010.blend,bakes/sh010.blend,walk to the person and wave,1,0,1,240
  shots/sh020.blend,bakes/sh020.blend,,0.5,7,,

Exit status: 0 all baked, 1 a shot failed, 2 a bad shot list or option (nothing ran),
130 / 143 stopped by Ctrl-C / SIGTERM (no partial output files are left)."""


def _parser() -> argparse.ArgumentParser:
    p = _Parser(prog="python -m remogen_blender.batch bake-many",
                formatter_class=argparse.RawDescriptionHelpFormatter, epilog=EPILOG,
                description="Bake every shot of a CSV shot list, each in its own process, N at a time.")
    p.add_argument("shots", metavar="SHOTS.csv", help="the shot list")
    p.add_argument("--jobs", "-j", type=_positive, default=1, metavar="N", help="bakes at a time (default 1)")
    p.add_argument("--blender", metavar="PATH",
                   help="run each bake as 'PATH -b FILE -c remogen bake ...' with that Blender (the extension "
                        "installed in it); default: this Python's bpy module")
    p.add_argument("--model", help="model file for every bake (default: the extension's)")
    p.add_argument("--threads", type=int, default=1, help="CPU threads for PyTorch in each bake (default 1)")
    p.add_argument("--verbose", "-v", action="store_true", help="also print every line each bake prints")
    return p


def _positive(s: str) -> int:
    try:
        v = int(s)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a whole number, got '{s}'") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"must be 1 or more, got {v}")
    return v


def bake_command(shot: Shot, args: argparse.Namespace) -> list[str]:
    """The process that bakes one shot."""
    tail = shot.bake_args() + [f"--threads={args.threads}"] + ([f"--model={args.model}"] if args.model else [])
    if args.blender:
        return [args.blender, "-b", shot.file, "-c", "remogen", *tail]
    return [sys.executable, "-m", f"{__package__}.batch", *tail]


def _child_env() -> dict[str, str]:
    """This package first on PYTHONPATH, so the bakes run the same code as this process."""
    env = dict(os.environ)
    here = str(Path(__file__).resolve().parents[1])
    env["PYTHONPATH"] = os.pathsep.join([here, *filter(None, [env.get("PYTHONPATH")])])
    return env


class _Bake:
    """One running shot: its process, and the last line that says what went wrong."""

    def __init__(self, number: int, shot: Shot, cmd: list[str], env: dict[str, str],
                 echo: Callable[[str], None] | None) -> None:
        self.number, self.shot, self.echo = number, shot, echo
        self.error: str | None = None
        self.last_line = ""
        self.t0 = time.perf_counter()
        self.proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                     stderr=subprocess.STDOUT, text=True, errors="replace", env=env)
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()

    def _read(self) -> None:
        for line in self.proc.stdout:
            line = line.strip()
            if not line:
                continue
            self.last_line = line
            if line.startswith(("remogen: error:", "remogen: SIG")):
                self.error = line
            if self.echo is not None:
                self.echo(line)

    def finished(self) -> int | None:
        rc = self.proc.poll()
        if rc is not None:
            self.reader.join(timeout=5)
        return rc

    def problem(self) -> str:
        """What went wrong, in one line."""
        rc = self.proc.returncode
        if self.error:
            return self.error.removeprefix("remogen: error: ").removeprefix("remogen: ")
        last = self.last_line[:300]
        return f"exit status {rc}" + (f": {last}" if last else "")

    def stop(self, signum: int) -> None:
        if self.proc.poll() is None:
            if os.name == "posix":
                self.proc.send_signal(signum)
            else:
                self.proc.terminate()

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait()
        self.reader.join(timeout=5)
        remove_partial_files(self.shot.output, self.proc.pid)   # a killed bake cannot clean up itself


class _Report:
    """Progress lines, one per event, safe from the reader threads."""

    def __init__(self, total: int) -> None:
        self.total = total
        self.lock = threading.Lock()

    def line(self, text: str) -> None:
        with self.lock:
            print(f"remogen: {text}", flush=True)

    def shot(self, bake: _Bake, what: str) -> None:
        self.line(f"shot {bake.number}/{self.total} (row {bake.shot.row}) {what}")

    def echo_for(self, number: int) -> Callable[[str], None]:
        def echo(line: str) -> None:
            with self.lock:
                print(f"  shot {number}/{self.total} | {line}", flush=True)
        return echo


def run(shots: list[Shot], args: argparse.Namespace, sig: _Signals) -> int:
    """Bake every shot, `args.jobs` at a time; per-shot failures never stop the others."""
    report = _Report(len(shots))
    env = _child_env()
    todo = list(enumerate(shots, start=1))
    running: list[_Bake] = []
    done: list[_Bake] = []
    failed: list[_Bake] = []
    t0 = time.perf_counter()
    while (todo or running) and not sig.requested():
        while todo and len(running) < args.jobs:
            number, shot = todo.pop(0)
            echo = report.echo_for(number) if args.verbose else None
            bake = _Bake(number, shot, bake_command(shot, args), env, echo)
            running.append(bake)
            report.shot(bake, f"started: {shot.file} -> {shot.output}")
        for bake in list(running):
            rc = bake.finished()
            if rc is None:
                continue
            running.remove(bake)
            if rc == 0 and os.path.isfile(bake.shot.output):
                done.append(bake)
                report.shot(bake, f"done in {time.perf_counter() - bake.t0:.1f} s: {bake.shot.output}")
            else:
                failed.append(bake)
                report.shot(bake, f"failed: {bake.problem()}")
        time.sleep(POLL_S)
    if sig.requested():
        return _stop(running, done, failed, report, sig)
    rows = ", ".join(str(b.shot.row) for b in sorted(failed, key=lambda b: b.number))
    failures = f", {len(failed)} failed (row{'s' if len(failed) > 1 else ''} {rows})" if failed else ""
    report.line(f"{len(done)} of {len(shots)} shots baked{failures} in {time.perf_counter() - t0:.1f} s")
    return 1 if failed else 0


def _stop(running: list[_Bake], done: list[_Bake], failed: list[_Bake], report: _Report, sig: _Signals) -> int:
    """Pass the signal on, give the bakes STOP_GRACE_S to stop between model frames, then kill the rest."""
    name = signal.Signals(sig.received).name
    if running:
        report.line(f"{name}: stopping {len(running)} running bake(s); press Ctrl-C again to kill them at once")
    for bake in running:
        bake.stop(sig.received)
    deadline, count = time.monotonic() + STOP_GRACE_S, sig.count
    while any(b.finished() is None for b in running):
        if time.monotonic() > deadline or sig.count > count:
            break
        time.sleep(POLL_S)
    for bake in running:
        bake.kill()
        if bake.proc.returncode == 0 and os.path.isfile(bake.shot.output):
            done.append(bake)   # it had saved before the signal reached it
    report.line(f"{name}: stopped; {len(done)} of {report.total} shots baked, {len(failed)} failed, "
                f"{report.total - len(done) - len(failed)} not baked; no partial output files are left")
    return sig.exit_code()


def main(argv: Sequence[str]) -> int:
    try:
        args = _parser().parse_args(list(argv))
    except SystemExit as exc:   # argparse already printed the error or the help
        return int(exc.code or 0)
    try:
        if args.blender and shutil.which(args.blender) is None:
            raise UserError(f"--blender: no Blender program at '{args.blender}'")
        if args.model and not os.path.isfile(args.model):
            raise UserError(f"--model: no model file at '{args.model}'")
        shots = read_shots(args.shots)
        for folder in sorted({os.path.dirname(s.output) for s in shots}):
            try:
                os.makedirs(folder, exist_ok=True)
            except OSError as exc:
                raise UserError(f"cannot create the output folder '{folder}': {exc.strerror or exc}") from None
    except UserError as exc:
        print(f"remogen: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    with _stop_on_signals() as sig:
        return run(shots, args, sig)
