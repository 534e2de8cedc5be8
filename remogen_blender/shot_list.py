"""The shot list of `bake-many`: a CSV file read and checked whole before anything runs.

One row per bake. `file` and `output` are required; every other column is optional, and an empty cell
keeps the value saved in the file. Paths are relative to the CSV file's folder.
"""
from __future__ import annotations

import csv
import math
import os
from dataclasses import dataclass, field
from typing import Callable

from ._runtime import UserError
from .properties import GUIDANCE_MAX, SEED_MAX

REQUIRED = ("file", "output")


def _float_between(lo: float, hi: float) -> Callable[[str], str]:
    def parse(cell: str) -> str:
        try:
            v = float(cell)
        except ValueError:
            v = math.nan
        if not (math.isfinite(v) and lo <= v <= hi):
            raise ValueError(f"must be a number between {lo:g} and {hi:g}, got '{cell}'")
        return repr(v)
    return parse


def _int_between(lo: int, hi: int) -> Callable[[str], str]:
    def parse(cell: str) -> str:
        try:
            v = int(cell)
        except ValueError:
            raise ValueError(f"must be a whole number, got '{cell}'") from None
        if not lo <= v <= hi:
            raise ValueError(f"must be between {lo} and {hi}, got {v}")
        return str(v)
    return parse


def _text(cell: str) -> str:
    return cell


# column -> (the bake's command-line option, cell check returning the option's value, help)
OPTIONS: dict[str, tuple[str, Callable[[str], str], str]] = {
    "scene": ("--scene", _text, "scene name"),
    "ego": ("--ego", _text, "ego armature"),
    "partner": ("--partner", _text, "partner armature"),
    "scene_collection": ("--scene-collection", _text, "collection of scene meshes"),
    "goal": ("--goal", _text, "goal object"),
    "text": ("--text", _text, "intent text"),
    "alpha_hhi": ("--alpha-hhi", _float_between(0.0, 1.0), "partner influence 0-1"),
    "alpha_hsi": ("--alpha-hsi", _float_between(0.0, 1.0), "scene influence 0-1"),
    "guidance": ("--guidance", _float_between(0.0, GUIDANCE_MAX), f"guidance 0-{GUIDANCE_MAX:g}"),
    "seed": ("--seed", _int_between(0, SEED_MAX), f"random seed 0-{SEED_MAX}"),
}
FRAMES = ("frame_start", "frame_end")
COLUMNS = (*REQUIRED, *OPTIONS, *FRAMES)

COLUMNS_HELP = "\n".join([
    "  file              .blend file to bake (required)",
    "  output            .blend file to save the bake to (required; overwritten if it exists)",
    *(f"  {name:<17} {help_}" for name, (_, _, help_) in OPTIONS.items()),
    "  frame_start       first frame, with frame_end (both empty: the file's scene range)",
    "  frame_end         last frame",
])


@dataclass
class Shot:
    """One bake: `row` is the CSV line (the header is row 1, as in a spreadsheet)."""
    row: int
    file: str
    output: str
    options: list[str] = field(default_factory=list)

    def bake_args(self) -> list[str]:
        """The `remogen bake` arguments; `--opt=value` keeps a value starting with '-' a value."""
        return ["bake", f"--blend={self.file}", *self.options, f"--output={self.output}"]


def read_shots(path: str) -> list[Shot]:
    """Every row checked (columns, numbers, files, outputs); any problem raises UserError in one line."""
    name = os.path.basename(path)
    try:
        with open(path, newline="", encoding="utf-8-sig") as f:
            reader = csv.DictReader(f, skipinitialspace=True)
            header = [h.strip() for h in (reader.fieldnames or [])]
            _check_header(name, header)
            reader.fieldnames = header
            base = os.path.dirname(os.path.abspath(path))
            shots = [_shot(name, reader.line_num, row, base) for row in reader
                     if any((v or "").strip() for v in row.values())]
    except OSError as exc:
        raise UserError(f"cannot read the shot list '{path}': {exc.strerror or exc}") from None
    except csv.Error as exc:
        raise UserError(f"{name}: not a readable CSV file: {exc}") from None
    if not shots:
        raise UserError(f"{name} lists no shots: one row per bake below the header row")
    _check_outputs(name, shots)
    return shots


def _check_header(name: str, header: list[str]) -> None:
    for col in REQUIRED:
        if col not in header:
            raise UserError(f"{name}: missing column '{col}' (the first row names the columns; "
                            f"'file' and 'output' are required)")
    for col in header:
        if col not in COLUMNS:
            raise UserError(f"{name}: unknown column '{col}' (known: {', '.join(COLUMNS)})")
        if header.count(col) > 1:
            raise UserError(f"{name}: column '{col}' appears twice")


def _shot(name: str, row: int, cells: dict, base: str) -> Shot:
    def where(col: str) -> str:
        return f"{name} row {row}, column '{col}'"

    if None in cells:
        raise UserError(f"{name} row {row}: more cells than columns")
    cell = {k: (v or "").strip() for k, v in cells.items()}
    paths = {}
    for col in REQUIRED:
        if not cell[col]:
            raise UserError(f"{where(col)}: empty; name a .blend file")
        p = os.path.abspath(os.path.join(base, os.path.expanduser(cell[col])))
        if not p.lower().endswith(".blend"):
            raise UserError(f"{where(col)}: '{cell[col]}' is not a .blend file")
        paths[col] = p
    if not os.path.isfile(paths["file"]):
        raise UserError(f"{where('file')}: no .blend file at '{paths['file']}'")

    options = []
    for col, (flag, parse, _) in OPTIONS.items():
        if cell.get(col, ""):
            try:
                options.append(f"{flag}={parse(cell[col])}")
            except ValueError as exc:
                raise UserError(f"{where(col)}: {exc}") from None
    frames = {col: cell.get(col, "") for col in FRAMES}
    if any(frames.values()):
        bounds = []
        for col, v in frames.items():
            if not v:
                raise UserError(f"{where(col)}: empty; give both frame_start and frame_end, or neither")
            try:
                bounds.append(int(v))
            except ValueError:
                raise UserError(f"{where(col)}: must be a whole number, got '{v}'") from None
        if bounds[1] < bounds[0]:
            raise UserError(f"{where('frame_end')}: {bounds[1]} is before frame_start {bounds[0]}")
        options += ["--frames", str(bounds[0]), str(bounds[1])]
    return Shot(row, paths["file"], paths["output"], options)


def _check_outputs(name: str, shots: list[Shot]) -> None:
    """No two bakes save the same file, and no bake saves over a file another row bakes."""
    inputs = {os.path.normcase(s.file): s for s in shots}
    outputs: dict[str, Shot] = {}
    for s in shots:
        key = os.path.normcase(s.output)
        if key in inputs:
            raise UserError(f"{name} row {s.row}, column 'output': '{s.output}' is the file row "
                            f"{inputs[key].row} bakes; save the bake under another name")
        if key in outputs:
            raise UserError(f"{name} row {s.row}, column 'output': '{s.output}' is also row "
                            f"{outputs[key].row}'s output")
        outputs[key] = s
