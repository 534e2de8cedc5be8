"""Two-person captures: the two BVH files of one take (two actors in one capture volume) -> both people on
the SMPL-X skeleton at 10 fps, in one shared world frame.

Which files of a folder make a take:
- a `pairs.csv` in the folder, one row per take:

      a,b,caption,text
      020/20_05.bvh,021/21_05.bvh,synchronized walk,a person walks

  `a` and `b` are paths relative to the folder; `caption` describes the take; `text` (optional) is a prompt
  for person B alone (default: the caption);
- otherwise CMU's naming: trial NN of subject 18, 20, 22 or 33 (`SS_NN.bvh` anywhere below the folder) goes
  with trial NN of subject 19, 21, 23 or 34; those takes have no caption.

Both actors are read alike: frames dropped at the start of one are dropped from the other, the up axis and
unit of person A hold for both, and one common scale (the mean of the two actors' leg scales to SMPL-X) is
applied to the whole scene, so the two keep their distances and their shared floor placement.
"""
from __future__ import annotations

import csv
import re
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from .motion import Motion, mapped_source, motion_from_source

PAIRS_CSV = "pairs.csv"
CMU_PARTNER_SUBJECT = {18: 19, 20: 21, 22: 23, 33: 34}    # subject A -> subject B of the same takes
DEFAULT_TEXT = "a person walks"


@dataclass(frozen=True)
class PairFiles:
    name: str                 # "20_21_05" for CMU names, else "<a stem>+<b stem>"
    a: Path
    b: Path
    caption: str = ""
    text: str = ""            # the prompt for person B ("" = the caption, else DEFAULT_TEXT)


@dataclass
class TwoPersonTake:
    name: str
    caption: str
    text: str
    a: Motion                 # person A, 10 fps
    b: Motion                 # person B, same frames, same world frame

    @property
    def frames(self) -> int:
        return self.a.joints.shape[0]


def pair_files(folder: str | Path) -> list[PairFiles]:
    """The takes of a pair folder (module docstring), in file order."""
    root = Path(folder)
    if not root.is_dir():
        raise InputError(f"two-person folder {root} not found; pass a folder holding the two BVH files of each take")
    listed = root / PAIRS_CSV
    takes = _listed_pairs(root, listed) if listed.is_file() else _cmu_pairs(root)
    if not takes:
        raise InputError(f"{root} holds no two-person take: add a {PAIRS_CSV} (columns a, b, caption, text) or "
                         "CMU files named SS_NN.bvh of subjects 18/19, 20/21, 22/23 or 33/34")
    return takes


def _listed_pairs(root: Path, listed: Path) -> list[PairFiles]:
    try:
        with listed.open(newline="", encoding="utf-8-sig") as fh:
            rows = [{(k or "").strip().lower(): (v or "").strip() for k, v in r.items()} for r in csv.DictReader(fh)]
    except (OSError, csv.Error, UnicodeDecodeError) as exc:
        raise InputError(f"{listed} is not a readable CSV file ({exc})") from None
    out = []
    for line, row in enumerate(rows, start=2):
        if not row.get("a") or not row.get("b"):
            raise InputError(f"{listed} line {line}: needs the two files of a take in columns a and b")
        a, b = root / row["a"], root / row["b"]
        for p in (a, b):
            if not p.is_file():
                raise InputError(f"{listed} line {line}: {p} does not exist; fix the path (relative to {root})")
        out.append(PairFiles(f"{a.stem}+{b.stem}", a, b, row.get("caption", ""), row.get("text", "")))
    return out


def _cmu_pairs(root: Path) -> list[PairFiles]:
    files = {}
    for p in sorted(root.rglob("*.bvh")):
        m = re.fullmatch(r"0*(\d+)_(\d+)", p.stem)
        if m:
            files.setdefault((int(m.group(1)), int(m.group(2))), p)
    out = []
    for (subject, trial), a in sorted(files.items()):
        b = files.get((CMU_PARTNER_SUBJECT.get(subject, -1), trial))
        if b is not None:
            out.append(PairFiles(f"{subject}_{subject + 1}_{trial:02d}", a, b))
    return out


def load_pair(a: str | Path, b: str | Path, *, fps: float | None = None, name: str = "", caption: str = "",
              text: str = "") -> TwoPersonTake:
    """Read the two BVH files of one take into one world frame (module docstring).

    fps: the true frame rate of both files when their headers are wrong."""
    from .bvh import read_bvh
    from .retarget import source_frame
    paths = (Path(a), Path(b))
    for p in paths:
        if not p.is_file():
            raise InputError(f"motion file {p} does not exist; check the path")
        if p.suffix.lower() != ".bvh":
            raise InputError(f"{p.name}: two-person takes are read from .bvh files")
    clips = [read_bvh(p) for p in paths]
    rates = [float(fps) if fps else c.fps for c in clips]
    if abs(rates[0] - rates[1]) > 1e-3 * rates[0]:
        raise InputError(f"{paths[0].name} ({rates[0]:g} fps) and {paths[1].name} ({rates[1]:g} fps) differ in frame "
                         "rate; the two files of a take must come from one capture")
    drop = max(c.rest_lead_in() for c in clips)
    if drop:
        warnings.warn(f"{paths[0].name}, {paths[1].name}: frame 0 is an added rest pose; dropped {drop} leading "
                      f"frame{'s' if drop > 1 else ''} from both", stacklevel=2)
    clips = [c.drop_frames(drop) for c in clips]
    n = min(c.data.shape[0] for c in clips)
    if any(c.data.shape[0] != n for c in clips):
        warnings.warn(f"{paths[0].name} and {paths[1].name} differ in length; using their first {n} frames",
                      stacklevel=2)
    sources = []
    for p, c in zip(paths, clips):
        pos, ends = c.world_positions()
        names = [j.name for j in c.joints]
        sources.append(mapped_source(pos[:n], ends[:n], names, [j.name for j in c.joints if j.end_site is not None],
                                     None, p.name))
    first = source_frame(sources[0])
    scale = float(np.mean([source_frame(s, unit=first.unit, up=first.up).scale for s in sources]))
    a_m, b_m = (motion_from_source(s, rates[0], p, caption or None, unit=first.unit, up=first.up, scale=scale)
                for s, p in zip(sources, paths))
    return TwoPersonTake(name or f"{paths[0].stem}+{paths[1].stem}", caption, text or caption or DEFAULT_TEXT,
                         a_m, b_m)


def load_pairs(folder: str | Path) -> list[TwoPersonTake]:
    """Every take of a pair folder."""
    return [load_pair(f.a, f.b, name=f.name, caption=f.caption, text=f.text) for f in pair_files(folder)]
