"""Build the clip cache from the project's data folder:

    python -m model_runtime.data.prepare --data ../shared/data --out runs/clips.npz [--cmu-only]
        [--bandai-repo DIR]   # a checkout of BandaiNamcoResearchInc/Bandai-Namco-Research-Motiondataset:
                              # all 2,902 dataset-2 takes instead of the data folder's 210 (non-commercial)
"""
from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

from .captions import bandai_caption, cmu_caption
from .library import ClipLibrary, bandai_repository_files, shared_data_files
from .motion import load_motion


def build_library(data_dir: str | Path, cmu_only: bool = False, progress: bool = True,
                  bandai_repo: str | Path | None = None) -> ClipLibrary:
    files = shared_data_files(data_dir, cmu_only=cmu_only)
    if not files:
        raise FileNotFoundError(f"no clips listed in {data_dir}/cmu/index.csv or {data_dir}/bandai/index.csv")
    if bandai_repo is not None and not cmu_only:
        extra = bandai_repository_files(bandai_repo, skip={p.stem for p, _, _ in files})
        if not extra:
            raise FileNotFoundError(f"no dataset/Bandai-Namco-Research-Motiondataset-*/data/*.bvh under {bandai_repo}")
        files = files + extra
    motions, names, sources = [], [], []
    it = files
    if progress:
        from tqdm import tqdm
        it = tqdm(files, desc="reading clips", unit="clip")
    for path, source, row in it:
        if source == "cmu":
            fps = float(row.get("fps_true") or 0) or None   # amc2bvh headers say 30, the capture is 120
            caption = cmu_caption(row.get("caption", ""))
        else:
            fps = None
            caption = bandai_caption(row.get("content", ""), row.get("style", ""))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            m = load_motion(path, fps=fps, caption=caption)
        if m.joints.shape[0] < 12:
            continue
        motions.append(m)
        names.append(f"{source}/{Path(row.get('file', path.name)).stem}")
        sources.append(source)
    return ClipLibrary.from_motions(motions, names, sources)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m model_runtime.data.prepare", description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", default="../shared/data")
    ap.add_argument("--out", default="runs/clips.npz")
    ap.add_argument("--cmu-only", action="store_true")
    ap.add_argument("--bandai-repo", default=None,
                    help="checkout of the Bandai Namco repository: read all its takes (non-commercial data)")
    args = ap.parse_args(argv)
    lib = build_library(args.data, cmu_only=args.cmu_only, bandai_repo=args.bandai_repo)
    lib.save(args.out)
    frames = int(lib.offsets[-1])
    print(f"{len(lib)} clips, {frames} frames ({frames / 36000:.2f} h at 10 fps), "
          f"{len(lib.split('val'))} held out -> {args.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
