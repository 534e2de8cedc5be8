"""A command the Flamenco job type produces, run as a worker's Blender runs it: the file loaded first, then
the arguments after `-c remogen` handed to the extension's registered `remogen` command."""
from __future__ import annotations

import math

import pytest
from flamenco_job import compile_job

bpy = pytest.importorskip("bpy")


def test_flamenco_command_bakes_the_shot(fresh, tmp_path, tiny_model_file):
    import scenes
    import remogen_blender
    ego = scenes.demo_scene(fresh, frames=(1, 24))["ego"].name
    shot = tmp_path / "sh010.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(shot))
    before = shot.read_bytes()
    job = compile_job({"blendfile": str(shot), "egos": ego, "frames": "1-12", "text": "wave",
                       "alpha_hhi": 1, "alpha_hsi": 0.5, "seed": 3, "output_dir": str(tmp_path / "out")})
    (tmp_path / "out").mkdir()
    [task] = job["tasks"]
    [cmd] = task["commands"]
    params = cmd["parameters"]
    assert cmd["name"] == "blender-render" and params["blendfile"] == str(shot)
    args = params["args"]
    assert args[:2] == ["-c", "remogen"]

    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.open_mainfile(filepath=params["blendfile"])     # `blender -b FILE` ...
    assert remogen_blender._cli(args[2:]) == 0                  # ... `-c remogen bake ...`

    out = tmp_path / "out" / f"sh010_{ego}_1-12.blend"
    assert out.is_file() and shot.read_bytes() == before
    assert sorted(p.name for p in out.parent.iterdir()) == [out.name]      # no partial file left
    bpy.ops.wm.open_mainfile(filepath=str(out))
    st = bpy.context.scene.remogen
    assert (st.text, st.seed, st.alpha_hhi, st.alpha_hsi) == ("wave", 3, 1.0, 0.5)
    act = bpy.data.objects[ego].animation_data.action
    assert act.name == f"ReMoGen_{ego}_seed3"
    fcurves = scenes.action_fcurves(act)
    values = [v for fc in fcurves for kp in fc.keyframe_points for v in kp.co]
    assert len(fcurves) == 22 * 4 + 3
    assert {int(kp.co[0]) for fc in fcurves for kp in fc.keyframe_points} == set(range(1, 13))
    assert all(math.isfinite(v) for v in values)
