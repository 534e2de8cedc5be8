"""Build the clip cache that training reads, from a folder of motion files:

    python -m model_runtime.data.prepare --data MOTION_FOLDER --out runs/clips.npz

MOTION_FOLDER is searched with its sub-folders for .bvh, .amc (each with its .asf skeleton beside it) and
AMASS-style .npz files. Captions come from an optional captions.csv in that folder, one row per file:

    file,caption,fps
    walk_fast_01.bvh,a person walks fast,
    dance/salsa_02.bvh,a person dances salsa,
    amc/16_01.amc,a person jumps,120

`file` is the path relative to the folder (just the name when it is unique), `caption` is used as written,
`fps` (optional) is the true frame rate when the file's header is wrong or has none (.amc: 120 assumed).
A file without a row is captioned from its name: "walk_fast_01.bvh" -> "walk fast".

A folder with cmu/index.csv and bandai/index.csv (the layout the shipped model is trained on) is read through
those indexes instead; --cmu-only keeps the CMU clips (commercial use allowed) and --bandai-repo DIR adds
every take of a checkout of the Bandai Namco repository (non-commercial).

Every file is retargeted to the SMPL-X skeleton at 10 fps; clips shorter than MIN_FRAMES frames and files
that cannot be read are skipped with the reason. At least two clips are needed: about 10 % of the clips, and
at least one, are held out for validation, chosen by name (the same clips on every machine).
"""
from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Iterable

from ..cli_help import HelpFormatter
from ..errors import InputError, RemogenError
from .clip_files import ClipFile, bandai_repository_files, data_files, unmatched_sidecar_rows

if TYPE_CHECKING:
    from .library import ClipLibrary

MIN_FRAMES = 12     # 1.2 s at 10 fps: shorter clips hold no training segment
MIN_CLIPS = 2       # one to train on, one held out


def _say(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def collect_files(data_dir: str | Path, cmu_only: bool = False, bandai_repo: str | Path | None = None,
                  skip: tuple[Path, ...] = (), say: Callable[[str], None] = _say) -> list[ClipFile]:
    """The clip files to read, checked and described before anything heavy is loaded."""
    files, layout = data_files(data_dir, cmu_only=cmu_only, skip=skip)
    if bandai_repo is not None and not cmu_only:
        extra = bandai_repository_files(bandai_repo, skip={f.path.stem for f in files})
        if not extra:
            raise InputError(f"no dataset/Bandai-Namco-Research-Motiondataset-*/data/*.bvh under {bandai_repo}; "
                             "pass a checkout of that repository")
        files = files + extra
    if not files:
        raise InputError(f"no .bvh, .amc or .npz motion files in {data_dir} or its sub-folders; pass --data with "
                         "a folder of motion files")
    if len(files) < MIN_CLIPS:
        raise InputError(f"only {len(files)} motion file in {data_dir}; training needs at least {MIN_CLIPS} clips "
                         "(one is held out for validation): add more files")
    origins: dict[str, int] = {}
    for f in files:
        origins[f.caption_from] = origins.get(f.caption_from, 0) + 1
    say(f"{len(files)} motion files in {data_dir} ({layout}); captions: "
        + ", ".join(f"{v} from {k}" for k, v in sorted(origins.items(), key=lambda kv: -kv[1])))
    typos = unmatched_sidecar_rows(Path(data_dir), files) if layout == "plain folder" else []
    if typos:
        say(f"note: captions.csv names {len(typos)} file(s) not in the folder, e.g. {typos[0]}")
    return files


def build_library(data_dir: str | Path, cmu_only: bool = False, progress: bool = True,
                  bandai_repo: str | Path | None = None, skip: tuple[Path, ...] = ()) -> "ClipLibrary":
    """Read every clip file of a data folder (see the module docstring) into a ClipLibrary."""
    say = _say if progress else (lambda msg: None)
    files = collect_files(data_dir, cmu_only, bandai_repo, skip, say)
    from .library import ClipLibrary
    from .motion import load_motion
    motions, names, sources = [], [], []
    notes = not any(f.caption_from == "index" for f in files)   # the indexes already correct what notes say
    for f in _ticking(files, progress):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                m = load_motion(f.path, fps=f.fps, caption=f.caption)
            except (ValueError, OSError) as exc:   # RemogenError is a ValueError; one bad file skips itself
                _write(progress, f"skipped {f.path.name}: {_reason(exc)}")
                continue
        if notes:
            for w in caught:
                _write(progress, f"note: {str(w.message).splitlines()[0]}")
        if m.joints.shape[0] < MIN_FRAMES:
            _write(progress, f"skipped {f.path.name}: {m.joints.shape[0]} frames at 10 fps, shorter than "
                             f"{MIN_FRAMES} ({MIN_FRAMES / 10:g} s)")
            continue
        motions.append(m)
        names.append(f.name)
        sources.append(f.source)
    if len(motions) < MIN_CLIPS:
        raise InputError(f"only {len(motions)} of {len(files)} files gave a clip of at least {MIN_FRAMES / 10:g} s; "
                         f"training needs {MIN_CLIPS}: fix or add files (reasons above)")
    return ClipLibrary.from_motions(motions, names, sources)


def _reason(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def _ticking(files: list[ClipFile], progress: bool) -> Iterable[ClipFile]:
    """The files with a progress bar naming the file being read (tqdm, else one line a file)."""
    if not progress:
        yield from files
        return
    try:
        from tqdm import tqdm
    except ImportError:
        for k, f in enumerate(files, 1):
            _say(f"[{k}/{len(files)}] {f.path.name}")
            yield f
        return
    with tqdm(files, desc="reading clips", unit="file", dynamic_ncols=True) as bar:
        for f in bar:
            bar.set_postfix_str(f.path.name, refresh=False)
            yield f


def _write(progress: bool, msg: str) -> None:
    """One line beside a running progress bar (or plain when tqdm is absent)."""
    if not progress:
        return
    try:
        from tqdm import tqdm
        tqdm.write(msg, file=sys.stderr)
    except ImportError:
        _say(msg)


def summary(lib: "ClipLibrary", out: Path) -> str:
    frames = int(lib.offsets[-1])
    val = [lib.names[i] for i in lib.split("val")]
    which = f": {', '.join(val)}" if len(val) <= 3 else ""
    return (f"{len(lib)} clips, {frames} frames ({frames / 36000:.2f} h at 10 fps), {len(val)} held out for "
            f"validation{which} -> {out}\nnext: python -m model_runtime.train all --library {out} --out runs/train")


def main(argv: list[str] | None = None) -> int:
    parts = __doc__.split("\n\n")
    ap = argparse.ArgumentParser(prog="python -m model_runtime.data.prepare", description=parts[0].rstrip(":") + ".",
                                 epilog="\n\n".join(parts[1:6]), formatter_class=HelpFormatter)
    ap.add_argument("--data", required=True, help="folder of .bvh / .amc (+ .asf) / .npz motion files, searched "
                    "with its sub-folders; an optional captions.csv in it gives captions (see below)")
    ap.add_argument("--out", default="runs/clips.npz", help="the clip cache to write")
    ap.add_argument("--cmu-only", action="store_true",
                    help="read only cmu/index.csv (CMU clips, commercial use allowed)")
    ap.add_argument("--bandai-repo", default=None,
                    help="checkout of the Bandai Namco repository: add all its takes (non-commercial data)")
    ap.add_argument("--quiet", action="store_true", help="no progress output")
    args = ap.parse_args(argv)
    out = Path(args.out)
    try:
        lib = build_library(args.data, cmu_only=args.cmu_only, bandai_repo=args.bandai_repo, skip=(out,),
                            progress=not args.quiet)
        lib.save(out)
    except RemogenError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"interrupted: {out} not written", file=sys.stderr)
        return 130
    print(summary(lib, out), file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
