"""Preparing and training on a user's own folder of motion files: captions from captions.csv or the file names,
a held-out clip always, one-line errors at once, and a training run that says what it did and how to go on."""
import math
import re
import shutil

import numpy as np
import pytest

from model_runtime.data import prepare
from model_runtime.data.clip_files import caption_from_name, data_files
from model_runtime.data.library import ClipLibrary, held_out
from model_runtime.errors import InputError
from paths import DATA
from synthetic import humanoid_bvh, synthetic_library


def _folder(root, captions: str | None = None):
    """Four short humanoid BVH files (one in a sub-folder), a broken one, a text file, and captions.csv."""
    root.mkdir(parents=True, exist_ok=True)
    (root / "dance").mkdir(exist_ok=True)
    for k, name in enumerate(("walk_fast_01.bvh", "SlowWalk-2.bvh", "dance/salsa_02.bvh", "jog.bvh")):
        humanoid_bvh(root / name, fps=30.0, seconds=1.5, seed=k)
    (root / "broken.bvh").write_text("not a BVH file")
    (root / "notes.txt").write_text("not motion")
    if captions is not None:
        (root / "captions.csv").write_text(captions)
    return root


def test_captions_from_file_names():
    assert caption_from_name("walk_fast_01.bvh") == "walk fast"
    assert caption_from_name("moves/SlowWalk-2.bvh") == "slow walk"
    assert caption_from_name("walking/007.bvh") == "walking"       # only numbers: the folder's words
    assert caption_from_name("07/07_01.bvh") == ""


def test_prepare_reads_any_folder_with_a_captions_csv(tmp_path, capsys):
    data = _folder(tmp_path / "mine", "file,caption,fps\ndance/salsa_02.bvh,a person dances salsa,\n"
                                      "jog.bvh,a person jogs in place,30\n")
    out = tmp_path / "clips.npz"
    assert prepare.main(["--data", str(data), "--out", str(out)]) == 0
    err = capsys.readouterr().err
    lib = ClipLibrary.load(out)
    captions = dict(zip(lib.names, lib.captions))
    assert captions == {"user/SlowWalk-2": "slow walk", "user/dance/salsa_02": "a person dances salsa",
                        "user/jog": "a person jogs in place", "user/walk_fast_01": "walk fast"}
    assert set(lib.sources) == {"user"}
    assert lib.split("val") and lib.split("train")
    assert "skipped broken.bvh: " in err and "held out for validation" in err
    assert f"python -m model_runtime.train all --library {out}" in err


def test_prepare_still_reads_the_indexed_layout(tmp_path):
    """cmu/index.csv: clip names, captions and true frame rates from the index, as the shipped model was trained."""
    index = DATA / "cmu" / "index.csv"
    if not index.exists():
        pytest.skip("CMU test data not present beside the repository")
    rows = index.read_text().splitlines()
    head, body = rows[0], [r for r in rows[1:] if r.startswith("daz_friendly_120fps/02/02_0")][:2]
    assert body
    (tmp_path / "cmu").mkdir()
    (tmp_path / "cmu" / "index.csv").write_text("\n".join([head] + body) + "\n")
    for r in body:
        rel = r.split(",")[0]
        (tmp_path / "cmu" / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(DATA / "cmu" / rel, tmp_path / "cmu" / rel)
    files, layout = data_files(tmp_path)
    assert layout.startswith("cmu/") and [f.name for f in files] == ["cmu/02_01", "cmu/02_02"]
    lib = prepare.build_library(tmp_path, progress=False)
    assert lib.names == ["cmu/02_01", "cmu/02_02"] and lib.captions == ["a person walks"] * 2
    assert lib.sources == ["cmu", "cmu"]


def test_too_few_files_fail_at_once_before_reading_any(tmp_path, capsys, monkeypatch):
    import model_runtime.data.motion as motion

    def never(*a, **k):
        raise AssertionError("a file was read before the count was checked")
    monkeypatch.setattr(motion, "load_motion", never)
    one = tmp_path / "one"
    one.mkdir()
    humanoid_bvh(one / "walk.bvh", fps=30.0, seconds=1.5)
    out = tmp_path / "clips.npz"
    assert prepare.main(["--data", str(one), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("error:") and "at least 2" in err
    assert prepare.main(["--data", str(tmp_path / "nowhere"), "--out", str(out)]) == 2
    assert "not found" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize("csv_text, match", [
    ("name,caption\nwalk_fast_01.bvh,x\n", "needs a 'file' column"),
    ("file,caption,fps\njog.bvh,a person jogs,fast\n", "not a frame rate"),
])
def test_bad_captions_csv_is_a_one_line_error(tmp_path, csv_text, match):
    data = tmp_path / "mine"
    data.mkdir()
    (data / "walk_fast_01.bvh").write_text("")
    (data / "jog.bvh").write_text("")
    (data / "captions.csv").write_text(csv_text)
    with pytest.raises(InputError, match=match) as exc:
        data_files(data)
    assert "\n" not in str(exc.value)


def test_an_ambiguous_file_name_in_captions_csv_asks_for_the_path(tmp_path):
    data = tmp_path / "mine"
    for sub in ("a", "b"):
        (data / sub).mkdir(parents=True)
        (data / sub / "walk.bvh").write_text("")
    (data / "captions.csv").write_text("file,caption\nwalk.bvh,a person walks\n")
    with pytest.raises(InputError, match="matches 2 files"):
        data_files(data)
    (data / "captions.csv").write_text("file,caption\nb/walk.bvh,a person walks\n")
    files, _ = data_files(data)
    assert [(f.name, f.caption) for f in files] == [("user/a/walk", "walk"), ("user/b/walk", "a person walks")]


def _library_named(names: list[str]) -> ClipLibrary:
    lib = synthetic_library(len(names), 20)
    return ClipLibrary(names, lib.captions, lib.sources, lib.rotations, lib.pelvis, lib.offsets)


def _names(n: int, held: int) -> list[str]:
    """n clip names of which the hash split holds out exactly `held`."""
    cands = [f"user/clip_{k:04d}" for k in range(2000)]
    return sorted([c for c in cands if held_out(c)][:held] + [c for c in cands if not held_out(c)][:n - held])


@pytest.mark.parametrize("n, held", [(5, 0), (2, 2)])
def test_the_split_always_has_a_held_out_and_a_training_clip(n, held):
    """Five clips can all fall on the training side of the 10 % hash split (and two on the held-out side)."""
    names = _names(n, held)
    assert sum(held_out(x) for x in names) == held
    lib = _library_named(names)
    val, train = lib.split("val"), lib.split("train")
    assert len(val) == 1 and len(train) == n - 1
    assert lib.split("val") == val      # deterministic


def test_the_large_split_is_unchanged():
    """Where the hash split already holds out some clips (any real library), the guarantee changes nothing."""
    names = [f"cmu/{k:02d}_{t:02d}" for k in range(1, 40) for t in range(1, 6)]
    lib = _library_named(names)
    assert lib.split("val") == [i for i, n in enumerate(names) if held_out(n)]


def test_training_on_one_clip_fails_at_once(tmp_path, capsys, monkeypatch):
    from model_runtime import train
    from model_runtime.training import setup

    def never(*a, **k):
        raise AssertionError("set-up started before the library was checked")
    monkeypatch.setattr(setup, "fit_stats", never)
    synthetic_library(1, 30).save(tmp_path / "one.npz")
    rc = train.main(["vae", "--library", str(tmp_path / "one.npz"), "--out", str(tmp_path / "run"),
                     "--config", "tiny", "--no-progress"])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and "at least 2" in err


def test_a_time_limited_run_ends_with_a_summary_and_the_command_to_continue(tmp_path, capsys):
    from model_runtime import train
    lib_path = tmp_path / "clips.npz"
    synthetic_library(6, 30).save(lib_path)
    args = ["vae", "--library", str(lib_path), "--out", str(tmp_path / "run"), "--config", "tiny", "--batch", "4",
            "--steps", "1000000", "--minutes", "0.0001"]
    assert train.main(args) == 0
    err = capsys.readouterr().err
    # what it does is said before the progress bar, the summary after it
    assert err.index("loading clip library") < err.index("fitting feature statistics") < err.index("train vae")
    done = re.search(r"vae: (\d+) of 1,000,000 steps \(stopped early", err)
    assert done, err
    summary = err[done.start():]
    assert "best held-out loss" in summary
    assert f"saved: {tmp_path / 'run' / 'model.pt'}" in summary
    assert "to continue: python -m model_runtime.train " + " ".join(args) in summary
    assert train.main(args) == 0           # the same command resumes
    again = re.search(r"vae: (\d+) of 1,000,000 steps", capsys.readouterr().err)
    assert int(again.group(1)) > int(done.group(1))


def test_a_finished_stage_names_the_next_and_is_not_trained_again(tmp_path, capsys):
    from model_runtime import train
    lib_path = tmp_path / "clips.npz"
    synthetic_library(6, 30).save(lib_path)
    args = ["--library", str(lib_path), "--out", str(tmp_path / "run"), "--config", "tiny", "--batch", "4",
            "--steps", "2", "--no-progress"]
    assert train.main(["vae", *args]) == 0
    err = capsys.readouterr().err
    assert "vae: 2 of 2 steps (done" in err
    assert "next stage: python -m model_runtime.train prior " + " ".join(args) in err
    before = (tmp_path / "run" / "model.pt").read_bytes()
    assert train.main(["vae", *args]) == 0
    assert "already done" in capsys.readouterr().err
    assert (tmp_path / "run" / "model.pt").read_bytes() == before


@pytest.mark.parametrize("module, default", [("model_runtime.bench", "(default: 300)"),
                                             ("model_runtime.evaluate", "(default: runs/clips.npz)"),
                                             ("model_runtime.data.prepare", "(default: runs/clips.npz)"),
                                             ("model_runtime.train", "(default: runs/train)")])
def test_help_shows_the_defaults(module, default, capsys):
    import importlib
    with pytest.raises(SystemExit) as exc:
        importlib.import_module(module).main(["--help"])
    assert exc.value.code == 0
    assert default in " ".join(capsys.readouterr().out.split())


def test_the_name_hash_split_is_unchanged():
    """The shipped split: names hash to the same side as before (sha1 of the source name, 10 %)."""
    assert [held_out(f"cmu/{i:02d}_01") for i in range(1, 13)] == [
        _old_held_out(f"cmu/{i:02d}_01") for i in range(1, 13)]
    assert math.isclose(np.mean([held_out(f"x{i}") for i in range(5000)]), 0.1, abs_tol=0.02)


def _old_held_out(name: str) -> bool:
    import hashlib
    return (int(hashlib.sha1(name.split("#", 1)[0].encode()).hexdigest()[:8], 16) % 1000) < 100
