"""The headless command: cli_main() in process (what `blender -c remogen` calls) and the bpy-module batch entry."""
from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path

import pytest
from blender_env import subprocess_env

bpy = pytest.importorskip("bpy")
ROOT = Path(__file__).resolve().parents[2]


def _saved_scene(ctx, path: Path, with_settings: bool = False) -> None:
    import scenes
    d = scenes.demo_scene(ctx, frames=(1, 24))
    if not with_settings:          # the command line names everything itself
        st = ctx.scene.remogen
        st.partner = st.scene_collection = st.goal = None
        bpy.data.objects.remove(st.ego.children[0])
        bpy.data.objects.remove(st.ego)
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    return d


def _keys(path: Path) -> tuple[str, int]:
    bpy.ops.wm.open_mainfile(filepath=str(path))
    ego = bpy.context.scene.remogen.ego
    act = ego.animation_data.action
    import scenes
    n = sum(len(fc.keyframe_points) for fc in scenes.action_fcurves(act))
    return act.name, n


def test_cli_bakes_saved_blend(fresh, tmp_path, tiny_model_file):
    from remogen_blender.cli import cli_main
    src, out = tmp_path / "scene.blend", tmp_path / "out.blend"
    _saved_scene(fresh, src)
    before = src.read_bytes()
    rc = cli_main(["bake", "--blend", str(src), "--partner", "Partner", "--scene-collection", "Props",
                   "--goal", "Goal", "--text", "walk to the person and wave", "--alpha-hhi", "1",
                   "--alpha-hsi", "0.5", "--frames", "1", "12", "--seed", "0", "--model", str(tiny_model_file),
                   "--output", str(out)])
    assert rc == 0
    assert out.is_file() and src.read_bytes() == before            # the input file is never written
    name, n = _keys(out)
    assert name.startswith("ReMoGen_") and n == 12 * (22 * 4 + 3)
    st = bpy.context.scene.remogen
    assert st.alpha_hsi == pytest.approx(0.5) and st.partner.name == "Partner"


@pytest.mark.parametrize("argv,match", [
    (["bake", "--partner", "Nobody", "--output", "x.blend"], "no object 'Nobody'"),
    (["bake", "--partner", "Goal", "--output", "x.blend"], "not an armature"),
    (["bake", "--alpha-hhi", "3", "--output", "x.blend"], "between 0 and 1"),
    (["bake", "--blend", "/nonexistent.blend", "--output", "x.blend"], "no .blend file"),
    (["bake", "--model", "/nonexistent.pt", "--output", "x.blend"], "not found"),
])
def test_cli_errors_are_one_line(fresh, tmp_path, capsys, argv, match):
    from remogen_blender.cli import cli_main
    src = tmp_path / "scene.blend"
    _saved_scene(fresh, src, with_settings=True)
    argv = [a if a != "x.blend" else str(tmp_path / "x.blend") for a in argv]
    assert cli_main(argv) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("remogen: error:") and match in err[0]
    assert not (tmp_path / "x.blend").exists()


def test_cli_usage(capsys):
    from remogen_blender.cli import cli_main
    assert cli_main(["--help"]) == 0
    assert "bake" in capsys.readouterr().out
    assert cli_main(["bake"]) == 2                       # --output is required


def test_batch_module_in_subprocess(fresh, tmp_path, tiny_model_file):
    src, out = tmp_path / "scene.blend", tmp_path / "out.blend"
    _saved_scene(fresh, src, with_settings=True)
    env = subprocess_env(ROOT)
    r = subprocess.run([sys.executable, "-m", "remogen_blender.batch", "bake", "--blend", str(src),
                        "--frames", "1", "10", "--model", str(tiny_model_file), "--threads", "1",
                        "--output", str(out)], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "remogen: baked frames 1-10" in r.stdout
    name, n = _keys(out)
    assert n == 10 * (22 * 4 + 3)


@pytest.mark.parametrize("sig,code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_batch_stops_on_signal_without_output(fresh, tmp_path, tiny_model_file, sig, code):
    """Ctrl-C / SIGTERM mid-bake: the process stops between model frames, exits 130 / 143, writes nothing."""
    src, out = tmp_path / "scene.blend", tmp_path / "out.blend"
    _saved_scene(fresh, src, with_settings=True)
    env = subprocess_env(ROOT)
    p = subprocess.Popen([sys.executable, "-m", "remogen_blender.batch", "bake", "--blend", str(src),
                          "--frames", "1", "9600", "--model", str(tiny_model_file), "--output", str(out)],
                         cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        for line in p.stdout:                 # wait until the bake is under way
            if line.startswith("remogen: baking"):
                break
        p.send_signal(sig)
        _, err = p.communicate(timeout=120)
    finally:
        p.kill()
    assert p.returncode == code, err[-2000:]
    assert "no output file was written" in err.strip().splitlines()[-1]
    assert sorted(x.name for x in tmp_path.iterdir()) == ["scene.blend"]     # no output, no partial file


@pytest.mark.parametrize("argv,match", [
    (["--seed", "99999999999"], "--seed must be between 0 and 2147483647"),
    (["--seed", "-1"], "--seed must be between 0 and 2147483647"),
    (["--seed", "abc"], "argument --seed: invalid int value: 'abc'"),
    (["--alpha-hhi", "abc"], "argument --alpha-hhi: invalid float value: 'abc'"),
    (["--alpha-hsi", "nan"], "between 0 and 1"),
    (["--guidance", "1e30"], "--guidance must be between 0 and 20"),
    (["--guidance", "inf"], "--guidance must be between 0 and 20"),
    (["--frames", "1"], "argument --frames: expected 2 arguments"),
])
def test_cli_bad_values_are_one_line(fresh, tmp_path, capsys, argv, match):
    from remogen_blender.cli import cli_main
    src = tmp_path / "scene.blend"
    _saved_scene(fresh, src, with_settings=True)
    out = tmp_path / "x.blend"
    rc = cli_main(["bake", "--blend", str(src), *argv, "--output", str(out)])
    assert rc in (1, 2)
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "error:" in err[0] and match in err[0], err
    assert not out.exists()


@pytest.mark.parametrize("flag, control", [("--no-control", False), ("--control", True)])
def test_control_flag_sets_the_steer_setting(fresh, flag, control):
    from remogen_blender.cli import _apply, _parser
    import scenes
    scenes.demo_scene(fresh)
    st = fresh.scene.remogen
    st.use_control = not control
    args = _parser().parse_args(["bake", "--out", "x.blend", flag])
    _apply(args, fresh.scene, st)
    assert st.use_control is control
