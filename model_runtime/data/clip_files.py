"""Which motion files a data folder holds, each with its clip name, licence tag, caption and frame rate.

Two layouts (`data_files` tells them apart):

- any folder: every .bvh, .amc (with its .asf) and AMASS-style .npz below it, sub-folders included (names
  starting with '.' are skipped). Captions come from an optional `captions.csv` in the folder:

      file,caption,fps
      walk_fast_01.bvh,a person walks fast,
      dance/salsa_02.bvh,a person dances salsa,
      amc/16_01.amc,a person jumps,120

  `file` is the path relative to the folder (or just the file name when that is unique); `caption` is
  used as written; `fps` (optional) is the true frame rate when the file's header is wrong or has none
  (.amc files carry none: 120 is assumed). A file without a row gets the caption its dataset labels
  give (Bandai Namco and HDM05 file names), else the words of its file name: "walk_fast_01.bvh" ->
  "walk fast" (numbers dropped; the folder's name when the file name is only numbers).
- the layout the shipped model is trained on: `cmu/index.csv` and/or `bandai/index.csv`, one row per BVH
  (`file` relative to that sub-folder; CMU rows add `fps_true` and a `caption` description, Bandai rows
  `content` and `style`), turned into HumanML3D-style sentences (data/captions.py).

Clip names ("<source>/<path without suffix>") decide the held-out split (library.held_out), so they are
kept stable: the same file always gets the same name. Sources are licence tags: "cmu" (commercial use
allowed), "bandai" (non-commercial), "user" (the user's own files, licence theirs to know).

This module reads only names and CSV files (no PyTorch), so a folder is checked in a fraction of a second.
"""
from __future__ import annotations

import csv
import os
import re
from dataclasses import dataclass
from pathlib import Path

from ..errors import InputError
from .captions import bandai_caption, caption_for, cmu_caption

SIDECAR = "captions.csv"
MOTION_SUFFIXES = (".bvh", ".amc", ".npz")
USER_SOURCE = "user"


@dataclass(frozen=True)
class ClipFile:
    path: Path
    name: str                 # the clip's name in the library: "<source>/<path without suffix>"
    source: str               # "cmu" | "bandai" | "user": the licence tag
    caption: str
    fps: float | None = None  # the true frame rate, when the file's own is wrong or missing
    caption_from: str = ""    # where the caption came from: "captions.csv", "labels", "file name", "index"


def data_files(folder: str | os.PathLike, *, cmu_only: bool = False, skip: tuple[Path, ...] = ()
               ) -> tuple[list[ClipFile], str]:
    """The clip files of a data folder and a few words on its layout ("index.csv files" or "plain folder").

    skip: files to leave out (e.g. the clip cache being written into the folder)."""
    root = Path(folder)
    if not root.is_dir():
        raise InputError(f"data folder {root} not found; pass --data with a folder of .bvh, .amc (+ .asf) or "
                         ".npz motion files")
    if is_indexed_layout(root):
        return indexed_files(root, cmu_only=cmu_only), "cmu/ and bandai/ index.csv files"
    if cmu_only:
        raise InputError(f"--cmu-only needs the cmu/index.csv layout, which {root} does not have; leave it out")
    return folder_files(root, skip=skip), "plain folder"


def is_indexed_layout(root: Path) -> bool:
    return (root / "cmu" / "index.csv").is_file() or (root / "bandai" / "index.csv").is_file()


# ------------------------------------------------------------------------------ the indexed layout
def indexed_files(root: Path, cmu_only: bool = False) -> list[ClipFile]:
    """Every BVH listed by cmu/index.csv and bandai/index.csv that exists."""
    out = []
    for source in ("cmu",) if cmu_only else ("cmu", "bandai"):
        index = root / source / "index.csv"
        if not index.is_file():
            continue
        for row in _csv_rows(index):
            rel = row.get("file") or row.get("path") or ""
            path = root / source / rel
            if path.suffix.lower() != ".bvh" or not path.is_file():
                continue
            if source == "cmu":
                fps = _positive(row.get("fps_true"))   # amc2bvh headers say 30, the capture is 120
                caption = cmu_caption(row.get("caption", ""))
            else:
                fps, caption = None, bandai_caption(row.get("content", ""), row.get("style", ""))
            out.append(ClipFile(path, f"{source}/{Path(rel).stem}", source, caption, fps, "index"))
    return out


def bandai_repository_files(repo_dir: str | os.PathLike, skip: set[str] = frozenset()) -> list[ClipFile]:
    """Every take of a checkout of the Bandai Namco repository
    (`dataset/Bandai-Namco-Research-Motiondataset-{1,2}/data/*.bvh`), for a larger run than the indexed
    layout's 3 takes per content and style. Content and style come from the file name
    `dataset-N_<content>_<style>_<take>.bvh`; stems in `skip` (clips already read) are left out so no clip
    is counted twice."""
    out = []
    for p in sorted(Path(repo_dir).glob("dataset/Bandai-Namco-Research-Motiondataset-*/data/*.bvh")):
        parts = p.stem.split("_")
        if len(parts) != 4 or p.stem in skip:
            continue
        out.append(ClipFile(p, f"bandai/{p.stem}", "bandai", bandai_caption(parts[1], parts[2]), None, "labels"))
    return out


# ------------------------------------------------------------------------------ any folder
def folder_files(root: Path, skip: tuple[Path, ...] = ()) -> list[ClipFile]:
    """Every motion file below root, with captions and frame rates from its captions.csv (module docstring)."""
    skipped = {Path(p).resolve() for p in skip}
    paths = sorted(p for p in root.rglob("*") if p.suffix.lower() in MOTION_SUFFIXES and p.is_file()
                   and not any(part.startswith(".") for part in p.relative_to(root).parts)
                   and p.resolve() not in skipped)
    rels = [p.relative_to(root).as_posix() for p in paths]
    rows = _sidecar_rows(root, rels)
    stems = [rel.rsplit(".", 1)[0] for rel in rels]
    out = []
    for path, rel, stem in zip(paths, rels, stems):
        row = rows.get(rel, {})
        caption, caption_from = (row.get("caption") or "").strip(), "captions.csv"
        if not caption:
            caption, caption_from = caption_for(path) or "", "labels"
        if not caption:
            caption, caption_from = caption_from_name(path), "file name"
        source = "bandai" if re.match(r"dataset-\d+_", path.name) else USER_SOURCE
        name = f"{source}/{rel if stems.count(stem) > 1 else stem}"   # two files differing only in suffix
        out.append(ClipFile(path, name, source, caption, _positive(row.get("fps"), f"{SIDECAR}, {rel}"),
                            caption_from))
    return out


def caption_from_name(path: str | os.PathLike) -> str:
    """The words of a file name without numbers: "walk_fast_01.bvh" -> "walk fast", "SlowWalk-2" -> "slow walk";
    the parent folder's words when the name is only numbers ("walking/007.bvh" -> "walking"), else ""."""
    path = Path(path)
    for stem in (path.stem, path.parent.name):
        spaced = re.sub(r"([a-z])([A-Z])", r"\1 \2", stem)
        words = [w for w in re.split(r"[\s_\-.,+]+", spaced.lower()) if w and not w.isdigit()]
        if words:
            return " ".join(words)
    return ""


def _sidecar_rows(root: Path, rels: list[str]) -> dict[str, dict]:
    """captions.csv rows by the relative path of the file each names (empty without a captions.csv)."""
    sidecar = root / SIDECAR
    if not sidecar.is_file():
        return {}
    rows = _csv_rows(sidecar)
    if rows and "file" not in rows[0]:
        raise InputError(f"{sidecar} needs a 'file' column (then 'caption' and optionally 'fps'); its header is "
                         f"{','.join(k for k in rows[0] if k)}")
    by_name: dict[str, list[str]] = {}
    for rel in rels:
        by_name.setdefault(rel.rsplit("/", 1)[-1], []).append(rel)
    out: dict[str, dict] = {}
    for line, row in enumerate(rows, start=2):
        key = (row.get("file") or "").strip().replace("\\", "/").removeprefix("./")
        if not key:
            continue
        if key in by_name.get(key.rsplit("/", 1)[-1], []):
            out[key] = row
        elif "/" not in key and len(by_name.get(key, [])) == 1:
            out[by_name[key][0]] = row
        elif "/" not in key and by_name.get(key):
            raise InputError(f"{sidecar} line {line}: {key} matches {len(by_name[key])} files "
                             f"({', '.join(by_name[key][:2])}, ...); write its path relative to {root}")
    return out


def unmatched_sidecar_rows(root: Path, files: list[ClipFile]) -> list[str]:
    """The `file` entries of captions.csv that name no motion file of the folder (likely typos)."""
    sidecar = root / SIDECAR
    if not sidecar.is_file():
        return []
    rels = {f.path.relative_to(root).as_posix() for f in files}
    names = {r.rsplit("/", 1)[-1] for r in rels}
    keys = [(row.get("file") or "").strip().replace("\\", "/").removeprefix("./") for row in _csv_rows(sidecar)]
    return [k for k in keys if k and k not in rels and k not in names]


def _csv_rows(path: Path) -> list[dict]:
    try:
        with path.open(newline="", encoding="utf-8-sig", errors="replace") as fh:   # -sig: a spreadsheet's BOM
            return [{(k or "").strip().lower(): (v or "") for k, v in row.items()} for row in csv.DictReader(fh)]
    except (OSError, csv.Error) as exc:
        raise InputError(f"{path} is not a readable CSV file ({exc})") from None


def _positive(value: str | None, where: str = "") -> float | None:
    """A frame rate from a CSV cell: None when empty; a bad one is an error naming `where` (or ignored)."""
    if value is None or not str(value).strip():
        return None
    try:
        fps = float(value)
    except ValueError:
        fps = float("nan")
    if fps > 0 and fps < 1e4:
        return fps
    if where:
        raise InputError(f"{where}: fps {value!r} is not a frame rate; write a positive number or leave it empty")
    return None
