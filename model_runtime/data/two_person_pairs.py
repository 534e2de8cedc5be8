"""Real two-person captures as HHI training pairs: each take of a two-person folder (data/two_person.py) appended
to a clip library twice, once with person B as the ego and person A as its partner, and once the other way round.

    python -m model_runtime.data.two_person_pairs --library CLIPS.npz --pairs FOLDER --out CLIPS_PAIRS.npz

The ego of a take is stored as `<source>/<file stem>#twoperson<k>` and its partner beside it as
`<source>/<file stem>#twopersonpartner<k>` (data/new_clips.py), both in the take's one shared world frame, so
`train hhi --library CLIPS_PAIRS.npz` reads them as pairs of kind two_person (data/pairs/hhi.py) beside the
derived ones, drawn recipe.TWO_PERSON_WEIGHT times as often as their frame count says. Unlike the derived
kinds, nothing about them is invented: no clearance is asked of them, since real people touch when they shake
hands or clap a high five. Each ego is captioned with its take's `text` (pairs.csv), the prompt that person's
part answers to.

Each ego keeps the held-out split of its own file's name (library.held_out), so a take may fall on the held-out
side. Takes meant to judge the model (`python -m model_runtime.evaluate --two-person FOLDER`) belong in another
folder than the ones appended here: a take trained on is no test of what was learned.
"""
from __future__ import annotations

import argparse
import sys
from collections import Counter
from pathlib import Path

import numpy as np

from ..errors import RemogenError
from .library import DERIVED, ClipLibrary
from .new_clips import NewClip, extend_library, partner_clip_name
from .two_person import TwoPersonTake, load_pairs

KIND = "twoperson"
MIN_FRAMES = 10       # a take shorter than one window (history + future at 10 fps) cannot be trained on


def two_person_clips(takes: list[TwoPersonTake], source: str = "cmu") -> list[NewClip]:
    """Both egos of every take, each followed by its partner clip. `source` is the data's dataset tag (its
    licence)."""
    out: list[NewClip] = []
    for take in takes:
        if take.frames < MIN_FRAMES:
            raise RemogenError(f"take {take.name} has {take.frames} frames at 10 fps; a training pair needs at least "
                               f"{MIN_FRAMES} (1 s): leave it out of the folder")
        for ego, partner in ((take.b, take.a), (take.a, take.b)):
            stem = Path(ego.source).stem if ego.source else take.name
            name = f"{source}/{stem}{DERIVED}{KIND}0"
            out.append(_clip(name, take.text, source, ego))
            out.append(_clip(partner_clip_name(name), take.text, source, partner, ego=False))
    return out


def _clip(name: str, caption: str, source: str, motion, ego: bool = True) -> NewClip:
    err = float((motion.fit_error_mm or {}).get("mean", 0.0))
    return NewClip(name, caption, source, np.asarray(motion.local_rotations, np.float32),
                   np.asarray(motion.root, np.float32)[:, :3, 3].copy(), err, ego)


def add_two_person_pairs(lib: ClipLibrary, takes: list[TwoPersonTake],
                         source: str = "cmu") -> tuple[ClipLibrary, list[int]]:
    """`lib` with both egos of every take and their partners appended; (library, indices of the egos). Refuses a
    take whose clips the library already holds."""
    clips = two_person_clips(takes, source)
    names = [c.name for c in clips]
    shared = sorted(n for n, k in Counter(names).items() if k > 1)
    if shared:     # a clip is named after its file, and its partner is found by that name
        raise RemogenError(f"two takes name their clips alike ({shared[0]}): give every person's file its own name")
    held = set(lib.names)
    twice = sorted({n for n in names if n in held})
    if twice:
        raise RemogenError(f"the library already holds {', '.join(twice[:3])}; append each take once "
                           "(start again from the library without them)")
    return extend_library(lib, clips)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m model_runtime.data.two_person_pairs", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--library", required=True, help="clip library .npz to append to")
    ap.add_argument("--pairs", required=True, help="two-person folder (pairs.csv, or CMU SS_NN.bvh names)")
    ap.add_argument("--out", required=True, help="library .npz to write")
    ap.add_argument("--source", default="cmu", help="dataset tag of the takes, for their licence (default: cmu)")
    args = ap.parse_args(argv)
    try:
        lib = ClipLibrary.load(args.library)
        takes = load_pairs(args.pairs)
        out, egos = add_two_person_pairs(lib, takes, args.source)
        out.save(args.out)
    except RemogenError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    frames = sum(out.frames(i) for i in egos)
    print(f"wrote {args.out}: {len(takes)} take(s) as {len(egos)} HHI egos with their partners "
          f"({frames} frames at 10 fps)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
