"""HumanML3D: captioned clips cut from AMASS SMPL+H G parameters (see LAYOUT)."""
from __future__ import annotations

import csv
import warnings
import zipfile
from dataclasses import replace
from pathlib import Path

import numpy as np

from ...errors import InputError
from ..motion import Motion
from .common import grounded, mirror_left_right, need_dir, need_file, npz_arrays, params_to_motion, read_lines

LAYOUT = """HumanML3D (texts + cut list) over AMASS SMPL+H G parameters.
    HumanML3D/                     root: the released dataset folder
        train.txt val.txt test.txt (also train_val.txt, all.txt): one clip id per line; ids 'M<id>' are
                                   the left/right mirror of '<id>' (loaded by mirroring, mirrored=True)
        texts/<id>.txt             (or texts.zip, read in place) one caption per line:
                                   'caption#word/POS word/POS ...#from#to'; from/to in seconds, 0#0 (or nan)
                                   = the whole clip, otherwise a sub-span cut at 20 fps (int(s * 20))
    index.csv                      in root or its parent (the HumanML3D repository root; or index_csv=):
                                   source_path,start_frame,end_frame,new_name, e.g.
                                   ./pose_data/CMU/80/80_63_poses.npy,516,716,000004.npy
    amass_root/<Dataset>/.../<name>_poses.npz   AMASS SMPL+H G: poses (T,156), trans, mocap_framerate
    Frames in index.csv count the 20 fps stream poses[::int(fps / 20)] after HumanML3D's per-dataset trims
    (Eyes_Japan_Dataset and MPI_HDM05 drop 3 s, TotalCapture and MPI_Limits 1 s, Transitions_mocap 0.5 s);
    the cut is mapped back to source frames and resampled from the true frame rate. humanact12 rows are not
    AMASS parameters and are skipped. Each clip is grounded (lowest joint of frame 0 on z = 0, sole offset
    included), as the paper does for HumanML3D.
    Confirmed: index.csv columns and rows, the trims, the stride, the text line format and the 20 fps span
    cut, M-prefixed ids in the split files (EricGuo5513/HumanML3D: index.csv, raw_pose_processing.py,
    legacy/HumanML3D/train.txt; t2m dataset loaders); AMASS folder renames (HDM05 -> MPI_HDM05, BMLrub ->
    BioMotionLab_NTroje, ...) from the same repository's README, used as fallbacks here.
    Assumed: SMPL-X N '_stageii.npz' files as a last fallback (HumanML3D was built from SMPL+H G)."""

HUMANML3D_FPS = 20.0
_HUMANML3D_TRIM_S = (("Eyes_Japan_Dataset", 3.0), ("MPI_HDM05", 3.0), ("TotalCapture", 1.0),
                     ("MPI_Limits", 1.0), ("Transitions_mocap", 0.5))
# HumanML3D's folder names (index.csv) -> names AMASS downloads unzip to today (HumanML3D README).
_AMASS_ALIASES = {"MPI_HDM05": "HDM05", "TCD_handMocap": "TCDHands", "MPI_mosh": "MoSh",
                  "Transitions_mocap": "Transitions", "MPI_Limits": "PosePrior", "SSM_synced": "SSM",
                  "DFaust_67": "DFaust", "BioMotionLab_NTroje": "BMLrub", "ACCAD": "ACCD"}


def _humanml3d_texts(root: Path):
    """id -> list of text lines, from texts/ or texts.zip."""
    folder = root / "texts"
    if folder.is_dir():
        def get(cid: str) -> list[str] | None:
            p = folder / f"{cid}.txt"
            return read_lines(p) if p.is_file() else None
        return get
    zpath = root / "texts.zip"
    if zpath.is_file():
        try:
            with zipfile.ZipFile(zpath) as zf:
                table = {Path(n).stem: [s.strip() for s in zf.read(n).decode("utf-8", "replace").splitlines()
                                        if s.strip()] for n in zf.namelist() if n.endswith(".txt")}
        except (OSError, zipfile.BadZipFile) as exc:
            raise InputError(f"{zpath} is not a readable zip ({exc}); expected HumanML3D's texts") from None
        return table.get
    raise InputError(f"{folder} not found; expected HumanML3D's texts/ folder (or texts.zip) with <id>.txt captions")


def _parse_humanml3d_line(line: str) -> tuple[str, float, float] | None:
    parts = line.split("#")
    caption = parts[0].strip()
    if not caption:
        return None
    try:
        f = float(parts[2]) if len(parts) > 2 else 0.0
        t = float(parts[3]) if len(parts) > 3 else 0.0
    except ValueError:
        f = t = 0.0
    return caption, (0.0 if np.isnan(f) else f), (0.0 if np.isnan(t) else t)


def _amass_candidates(amass_root: Path, source_path: str) -> list[Path]:
    rel = Path(source_path.replace("\\", "/"))
    parts = [p for p in rel.parts if p not in (".", "")]
    if parts and parts[0] == "pose_data":
        parts = parts[1:]
    if not parts:
        return []
    stem = Path(parts[-1]).stem
    base = [amass_root.joinpath(*parts[:-1], stem + ".npz")]
    if parts[0] in _AMASS_ALIASES:
        base.append(amass_root.joinpath(_AMASS_ALIASES[parts[0]], *parts[1:-1], stem + ".npz"))
    if stem.endswith("_poses"):
        base += [p.with_name(stem[:-len("_poses")] + "_stageii.npz") for p in list(base)]
    return base


def _amass_arrays(path: Path) -> tuple[np.ndarray, np.ndarray, float]:
    """poses, trans and frame rate of an AMASS .npz (other keys, e.g. a pickled gender, are not read)."""
    what = "an AMASS .npz (poses, trans, mocap_framerate)"
    d = npz_arrays(path, ("poses", "trans"), what)
    with np.load(path, allow_pickle=False) as z:
        rate = next((float(z[k]) for k in ("mocap_framerate", "mocap_frame_rate") if k in z.files), 0.0)
    if rate <= 0:
        raise InputError(f"{path} has no mocap_framerate; expected {what}")
    if d["poses"].ndim != 2 or d["poses"].shape[1] < 66 or d["trans"].shape != (len(d["poses"]), 3):
        raise InputError(f"{path}: poses must be (T, >=66) and trans (T, 3), got {d['poses'].shape} and "
                         f"{d['trans'].shape}")
    return d["poses"], d["trans"], rate


def load_humanml3d(root: str | Path, amass_root: str | Path, split: str = "train", mirrored: bool = True,
                   index_csv: str | Path | None = None, all_captions: bool = False) -> list[Motion]:
    """HumanML3D clips of one official split, cut from AMASS and resampled to 10 fps.

    One Motion per clip and caption span: the whole clip with its first whole-clip caption, plus one per
    sub-span caption. all_captions=True returns one Motion per caption instead (they share arrays).
    Ids 'M<id>' are mirrored copies (skipped with mirrored=False). See LAYOUT.
    """
    root, amass_root = Path(root), Path(amass_root)
    need_dir(root, "the HumanML3D dataset folder (texts/, train.txt, val.txt, test.txt)")
    need_dir(amass_root, "the AMASS folder with <Dataset>/.../<name>_poses.npz (SMPL+H G) files")
    split_file = need_file(root / f"{split}.txt", f"HumanML3D's split file {split}.txt (one clip id a line)")
    if index_csv is None:
        found = [p for p in (root / "index.csv", root.parent / "index.csv") if p.is_file()]
        if not found:
            raise InputError(f"index.csv not found in {root} or {root.parent}; copy it from the HumanML3D "
                             "repository or pass index_csv=")
        index_csv = found[0]
    index_csv = need_file(Path(index_csv), "HumanML3D's index.csv (source_path,start_frame,end_frame,new_name)")
    index: dict[str, tuple[str, int, int]] = {}
    with open(index_csv, newline="", encoding="utf-8") as fh:
        reader = csv.DictReader(fh)
        need = {"source_path", "start_frame", "end_frame", "new_name"}
        if not need <= set(reader.fieldnames or ()):
            raise InputError(f"{index_csv} must have the columns source_path,start_frame,end_frame,new_name")
        for row in reader:
            index[Path(row["new_name"]).stem] = (row["source_path"], int(row["start_frame"]), int(row["end_frame"]))
    texts = _humanml3d_texts(root)

    cache: dict[Path, tuple[np.ndarray, np.ndarray, float]] = {}
    missing_files: list[str] = []
    skipped = {"humanact12": 0, "no text": 0, "not in index.csv": 0}
    out: list[Motion] = []
    for cid in read_lines(split_file):
        is_mirror = cid.startswith("M")
        if is_mirror and not mirrored:
            continue
        base = cid[1:] if is_mirror else cid
        if base not in index:
            skipped["not in index.csv"] += 1
            continue
        source_path, start, end = index[base]
        if "humanact12" in source_path:
            skipped["humanact12"] += 1
            continue
        lines = texts(cid)
        if not lines:
            skipped["no text"] += 1
            continue
        cands = _amass_candidates(amass_root, source_path)
        path = next((p for p in cands if p.is_file()), None)
        if path is None:
            missing_files.append(str(cands[0]) if cands else source_path)
            continue
        if path not in cache:
            if len(cache) > 16:
                cache.clear()
            cache[path] = _amass_arrays(path)
        poses, trans, rate = cache[path]
        stride = max(int(rate / HUMANML3D_FPS), 1)
        n20 = (len(poses) + stride - 1) // stride
        trim = next((int(s * HUMANML3D_FPS) for key, s in _HUMANML3D_TRIM_S if key in source_path), 0)
        a = trim + start
        b = min(n20 + end if end < 0 else trim + end, n20)

        spans: dict[tuple[int, int], list[str]] = {}
        for line in lines:
            parsed = _parse_humanml3d_line(line)
            if parsed is None:
                continue
            caption, f, t = parsed
            key = (a, b) if (f == 0.0 and t == 0.0) else (a + int(f * HUMANML3D_FPS),
                                                           min(a + int(t * HUMANML3D_FPS), b))
            spans.setdefault(key, []).append(caption)
        for (s0, s1), captions in spans.items():
            if s1 - s0 < 2:
                continue
            src = slice(s0 * stride, (s1 - 1) * stride + 1)
            name = f"humanml3d:{cid}" + ("" if (s0, s1) == (a, b) else f"@{s0 - a}-{s1 - a}")
            m = params_to_motion(poses[src, :3], poses[src, 3:66], trans[src], rate, source=name)
            if len(m.joints) < 2:
                continue
            m = grounded(mirror_left_right(m) if is_mirror else m)
            for c in (captions if all_captions else captions[:1]):
                out.append(replace(m, caption=c))
    if missing_files and not out:
        raise InputError(f"none of the {len(missing_files)} AMASS files of split '{split}' were found, e.g. "
                         f"{missing_files[0]}; expected SMPL+H G npz files under {amass_root}")
    notes = [f"{v} {k}" for k, v in skipped.items() if v]
    if missing_files:
        notes.append(f"{len(missing_files)} missing AMASS files (e.g. {missing_files[0]})")
    if notes:
        warnings.warn(f"HumanML3D {split}: skipped " + ", ".join(notes), stacklevel=2)
    return out
