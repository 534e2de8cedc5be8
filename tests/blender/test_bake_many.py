"""`python -m remogen_blender.batch bake-many SHOTS.csv --jobs N`: a shot list baked as local processes."""
from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path

import pytest
from blender_env import subprocess_env

bpy = pytest.importorskip("bpy")
ROOT = Path(__file__).resolve().parents[2]


def _shot_file(ctx, path: Path) -> str:
    """A saved demo scene; returns its ego's name."""
    import scenes
    ego = scenes.demo_scene(ctx, frames=(1, 24))["ego"].name
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    return ego


def _csv(path: Path, rows: list[str]) -> Path:
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")
    return path


def _bake_many(tmp_path: Path, *args: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "remogen_blender.batch", "bake-many", *args],
                            cwd=tmp_path, env=subprocess_env(ROOT), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def _key_count(path: Path, ego: str) -> int:
    import scenes
    bpy.ops.wm.open_mainfile(filepath=str(path))
    act = bpy.data.objects[ego].animation_data.action
    return sum(len(fc.keyframe_points) for fc in scenes.action_fcurves(act))


def test_bakes_every_shot_and_reports_a_failed_one(fresh, tmp_path, tiny_model_file):
    """Three shots, two at a time: the one naming a missing partner fails in one line, the others bake."""
    ego = _shot_file(fresh, tmp_path / "sh010.blend")
    (tmp_path / "sh020.blend").write_bytes((tmp_path / "sh010.blend").read_bytes())
    shots = _csv(tmp_path / "shots.csv", [
        "file,output,partner,text,alpha_hhi,seed,frame_start,frame_end",
        "sh010.blend,bakes/sh010.blend,Partner,wave,1,0,1,10",
        "sh020.blend,bakes/sh020_bad.blend,Nobody,,,,,",
        "sh020.blend,bakes/sh020.blend,,,0.5,7,3,8",
    ])
    p = _bake_many(tmp_path, str(shots), "--jobs", "2", "--model", str(tiny_model_file))
    out, err = p.communicate(timeout=600)
    assert p.returncode == 1, out + err
    lines = out.strip().splitlines()
    assert "remogen: shot 2/3 (row 3) failed: no object 'Nobody' for --partner in the file" in lines
    assert any(line.startswith("remogen: shot 1/3 (row 2) done in ") for line in lines)
    assert any(line.startswith("remogen: shot 3/3 (row 4) done in ") for line in lines)
    assert lines[-1].startswith("remogen: 2 of 3 shots baked, 1 failed (row 3) in ")
    assert sorted(x.name for x in (tmp_path / "bakes").iterdir()) == ["sh010.blend", "sh020.blend"]
    assert _key_count(tmp_path / "bakes" / "sh010.blend", ego) == 10 * (22 * 4 + 3)
    assert _key_count(tmp_path / "bakes" / "sh020.blend", ego) == 6 * (22 * 4 + 3)
    assert bpy.context.scene.remogen.seed == 7


@pytest.mark.parametrize("rows,match", [
    (["file,text", "a.blend,hi"], "shots.csv: missing column 'output'"),
    (["file,output,alpha", "a.blend,o.blend,1"], "shots.csv: unknown column 'alpha'"),
    (["file,output,alpha_hhi", "a.blend,o1.blend,1", "a.blend,o2.blend,abc"],
     "shots.csv row 3, column 'alpha_hhi': must be a number between 0 and 1, got 'abc'"),
    (["file,output,seed", "a.blend,o.blend,1.5"], "shots.csv row 2, column 'seed': must be a whole number, got '1.5'"),
    (["file,output,seed", "a.blend,o.blend,-1"], "shots.csv row 2, column 'seed': must be between 0 and 2147483647"),
    (["file,output,frame_start,frame_end", "a.blend,o.blend,10,"],
     "shots.csv row 2, column 'frame_end': empty; give both frame_start and frame_end, or neither"),
    (["file,output,frame_start,frame_end", "a.blend,o.blend,10,2"],
     "shots.csv row 2, column 'frame_end': 2 is before frame_start 10"),
    (["file,output", "a.blend,o.blend", "missing.blend,p.blend"], "shots.csv row 3, column 'file': no .blend file at"),
    (["file,output", "a.blend,o.txt"], "shots.csv row 2, column 'output': 'o.txt' is not a .blend file"),
    (["file,output", "a.blend,o.blend", "a.blend,o.blend"],
     "shots.csv row 3, column 'output': '{tmp}/o.blend' is also row 2's output"),
    (["file,output", "a.blend,a.blend"], "shots.csv row 2, column 'output': '{tmp}/a.blend' is the file row 2 bakes"),
    (["file,output"], "shots.csv lists no shots"),
])
def test_bad_shot_list_is_one_line_and_runs_nothing(tmp_path, capsys, monkeypatch, rows, match):
    from remogen_blender import bake_many
    (tmp_path / "a.blend").write_bytes(b"not opened before the list is checked")
    shots = _csv(tmp_path / "shots.csv", rows)
    monkeypatch.setattr(bake_many.subprocess, "Popen", lambda *a, **k: pytest.fail("a bake was started"))
    assert bake_many.main([str(shots), "--jobs", "2"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("remogen: error: ") and match.format(tmp=tmp_path) in err[0], err
    assert sorted(x.name for x in tmp_path.iterdir()) == ["a.blend", "shots.csv"]


def test_bad_options_are_one_line(tmp_path, capsys):
    from remogen_blender import bake_many
    shots = _csv(tmp_path / "shots.csv", ["file,output"])
    assert bake_many.main([str(shots), "--jobs", "0"]) == 2
    assert bake_many.main([str(shots), "--blender", str(tmp_path / "no-blender")]) == 2
    assert bake_many.main([str(tmp_path / "none.csv")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 3
    assert "argument --jobs/-j: must be 1 or more, got 0" in err[0]
    assert "--blender: no Blender program at" in err[1]
    assert "cannot read the shot list" in err[2] and "none.csv" in err[2]


@pytest.mark.parametrize("sig,code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_stop_signal_stops_every_bake_and_leaves_no_output(fresh, tmp_path, tiny_model_file, sig, code):
    """Ctrl-C / SIGTERM to bake-many: the running bakes stop, the rest never start, no file is left."""
    _shot_file(fresh, tmp_path / "sh010.blend")
    shots = _csv(tmp_path / "shots.csv", ["file,output,frame_start,frame_end"] +
                 [f"sh010.blend,bakes/take{i}.blend,1,9600" for i in range(3)])
    p = _bake_many(tmp_path, str(shots), "--jobs", "2", "--verbose", "--model", str(tiny_model_file))
    try:
        for line in p.stdout:                 # wait until a bake is under way
            if "remogen: baking" in line:
                break
        p.send_signal(sig)
        out, err = p.communicate(timeout=120)
    finally:
        p.kill()
    assert p.returncode == code, out[-2000:] + err[-2000:]
    last = out.strip().splitlines()[-1]
    assert last.startswith(f"remogen: {sig.name}: stopped; 0 of 3 shots baked, 0 failed, 3 not baked"), last
    assert "take2" not in out                 # the third shot never started
    assert sorted(x.name for x in (tmp_path / "bakes").iterdir()) == []    # no output, no partial file
