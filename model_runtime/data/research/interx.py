"""Inter-X: two-person SMPL-X interactions, each pair returned with either person as ego (see LAYOUT)."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Mapping

import numpy as np

from ...errors import InputError
from ..motion import Motion
from .common import YUP_TO_ZUP, grounded, need_dir, need_file, npz_arrays, params_to_motion, read_lines

LAYOUT = """Inter-X (two-person SMPL-X at 120 fps, Y-up world).
    Inter-X_Dataset/               root
        splits/train.txt val.txt test.txt all.txt   one id per line, GgggTtttAaaaRrrr
        motions/<id>/P1.npz, P2.npz (motions.zip unzipped) root_orient (T,3), pose_body (T,21,3) or
                                   (T,63), pose_lhand, pose_rhand, trans (T,3), betas (1,10), gender
        texts/<id>.txt             (texts.zip unzipped) several whole-interaction descriptions, one a line
        annots/interaction_order.pkl  actor/reactor order (not needed: both persons are used as ego)
    Each pair is returned twice (P1 as ego with P2 as partner, then the reverse: the paper's augmentation),
    with the first description as text unless role_texts gives role-specific ones (the paper writes those
    with an LLM). Y-up is turned Z-up by (x, y, z) -> (x, -z, y); each person is grounded on its frame 0.
    Confirmed: layout, keys, 120 fps, split files (liangxuy/Inter-X README and preprocess/1_prepare_data.py,
    which grounds on the y axis, i.e. Y-up; visualize/smplx_viewer_tool plays at 120 fps).
    Assumed: texts/<id>.txt is plain text without HumanML3D-style '#' fields (anything after '#' is cut)."""

INTERX_FPS = 120.0


def load_interx_pairs(root: str | Path, split: str = "train", fps: float = INTERX_FPS,
                      role_texts: Mapping[str, tuple[str, str]] | None = None
                      ) -> list[tuple[Motion, np.ndarray, str]]:
    """Inter-X pairs of one official split, each twice: (ego Motion, partner joints (T, 22, 3), text).

    The first tuple of a pair has P1 as ego, the second P2 (the paper's both-ego augmentation).
    role_texts maps an id to (text with P1 as ego, text with P2 as ego). See LAYOUT.
    """
    root = Path(root)
    need_dir(root, "the Inter-X dataset folder (motions/, texts/, splits/)")
    split_file = need_file(root / "splits" / f"{split}.txt", f"Inter-X's split file splits/{split}.txt")
    motions = root / "motions"
    if not motions.is_dir():
        hint = " (unzip motions.zip there)" if (root / "motions.zip").is_file() else ""
        raise InputError(f"{motions} is not a folder; expected motions/<id>/P1.npz and P2.npz{hint}")
    texts = root / "texts"
    if not texts.is_dir() and role_texts is None:
        hint = " (unzip texts.zip there)" if (root / "texts.zip").is_file() else ""
        raise InputError(f"{texts} is not a folder; expected texts/<id>.txt descriptions{hint}")
    keys = ("root_orient", "pose_body", "trans")
    what = "an Inter-X SMPL-X .npz (root_orient, pose_body, trans)"
    out: list[tuple[Motion, np.ndarray, str]] = []
    for cid in read_lines(split_file):
        folder = motions / cid
        people = []
        for p in ("P1", "P2"):
            d = npz_arrays(need_file(folder / f"{p}.npz", f"motions/{cid}/{p}.npz"), keys, what)
            people.append(d)
        n = min(len(people[0]["trans"]), len(people[1]["trans"]))
        if role_texts is not None and cid in role_texts:
            text1, text2 = role_texts[cid]
        else:
            tp = need_file(texts / f"{cid}.txt", f"texts/{cid}.txt with the descriptions of {cid}")
            lines = [s.split("#")[0].strip() for s in read_lines(tp)]
            text1 = text2 = next((s for s in lines if s), "")
        ms = []
        for p, d in zip(("P1", "P2"), people):
            m = params_to_motion(d["root_orient"][:n], np.asarray(d["pose_body"]).reshape(len(d["pose_body"]), -1)[:n],
                                  d["trans"][:n], fps, rotation=YUP_TO_ZUP, source=f"interx:{cid}:{p}")
            ms.append(grounded(m))
        out.append((replace(ms[0], caption=text1), ms[1].joints.copy(), text1))
        out.append((replace(ms[1], caption=text2), ms[0].joints.copy(), text2))
    return out
