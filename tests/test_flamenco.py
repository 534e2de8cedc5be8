"""The Flamenco job type "ReMoGen bake" (farm/flamenco/remogen_bake.js), compiled under Node: its settings,
the tasks and the exact `blender -c remogen bake` commands it produces, and its one-line refusals.
Running a produced command is tested with the bpy module in tests/blender/test_flamenco_bake.py."""
from __future__ import annotations

import pytest
from flamenco_job import CompileError, compile_job

SHOTS = {
    "blendfile": "/farm/shots/sh010.flamenco.blend",
    "shot_files": "/farm/shots/sh020.blend;\n /farm/shots/sh030.blend",
    "egos": "Ego, Ego.001",
    "frames": "1-240",
    "text": "walk to the person and wave",
    "alpha_hhi": 1, "alpha_hsi": 0.5, "seed": 7,
    "output_dir": "/farm/out/",
}


def _commands(job: dict) -> list[dict]:
    return [c["parameters"] for t in job["tasks"] for c in t["commands"]]


def test_job_type_settings():
    job = compile_job({"blendfile": "/a.blend", "output_dir": "/out"})
    assert job["label"] == "ReMoGen bake"
    settings = {s["key"]: s for s in job["settings"]}
    assert {"blendfile", "shot_files", "egos", "frames", "text", "alpha_hhi", "alpha_hsi", "seed",
            "frames_per_task", "bakes_per_task", "output_dir", "output_name"} <= set(settings)
    assert all(s["type"] in {"string", "int32", "float", "bool"} for s in settings.values())
    assert all(s.get("description") for s in settings.values())


def test_one_task_per_shot_and_ego_with_the_cli_flags():
    job = compile_job(SHOTS)
    tasks = job["tasks"]
    assert [t["name"] for t in tasks] == [f"bake {f} {e} 1-240" for f in ("sh010", "sh020", "sh030")
                                          for e in ("Ego", "Ego.001")]
    assert all(t["type"] == "blender" and len(t["commands"]) == 1 and not t["dependencies"] for t in tasks)
    assert {c["name"] for t in tasks for c in t["commands"]} == {"blender-render"}
    first = _commands(job)[0]
    assert first == {
        "exe": "{blender}", "exeArgs": "{blenderArgs}", "argsBefore": [],
        "blendfile": "/farm/shots/sh010.flamenco.blend",
        "args": ["-c", "remogen", "bake", "--blend=/farm/shots/sh010.flamenco.blend", "--ego=Ego",
                 "--text=walk to the person and wave", "--alpha-hhi=1", "--alpha-hsi=0.5", "--seed=7",
                 "--frames", "1", "240", "--output=/farm/out/sh010_Ego_1-240.blend"],
    }
    outputs = [c["args"][-1] for c in _commands(job)]
    assert len(set(outputs)) == 6 and "--output=/farm/out/sh030_Ego.001_1-240.blend" in outputs


def test_defaults_keep_each_files_own_settings():
    """Only a file and a folder: no ego, text, alpha, seed or range is forced on the file."""
    job = compile_job({"blendfile": "/farm/sh010.blend", "output_dir": "/farm/out"})
    assert [c["args"] for c in _commands(job)] == [
        ["-c", "remogen", "bake", "--blend=/farm/sh010.blend", "--output=/farm/out/sh010_ego_scene.blend"]]


def test_chunking_frames_and_bakes_per_task():
    job = compile_job({**SHOTS, "shot_files": "", "egos": "Ego", "frames": "1-250", "frames_per_task": 100,
                       "bakes_per_task": 2, "output_name": "{file}.{frames}.blend"})
    assert [t["name"] for t in job["tasks"]] == ["bake sh010 Ego 1-100 +1", "bake sh010 Ego 201-250"]
    frames = [c["args"][c["args"].index("--frames") + 1:][:2] for c in _commands(job)]
    assert frames == [["1", "100"], ["101", "200"], ["201", "250"]]
    assert [c["args"][-1] for c in _commands(job)] == [
        f"--output=/farm/out/sh010.{r}.blend" for r in ("1-100", "101-200", "201-250")]


def test_windows_paths_and_odd_ego_names():
    job = compile_job({"blendfile": "S:\\shots\\sh 010.blend", "egos": "Hero/L, -x", "frames": "-10..10",
                       "output_dir": "S:\\bakes"})
    args = [c["args"] for c in _commands(job)]
    assert args[0][-1] == "--output=S:\\bakes\\sh 010_Hero_L_-10-10.blend"
    assert "--ego=-x" in args[1] and args[1][args[1].index("--frames") + 1:][:2] == ["-10", "10"]


@pytest.mark.parametrize("change,match", [
    ({"alpha_hhi": 3}, "alpha_hhi must be between 0 and 1 (or -1 to keep each file's own), got 3"),
    ({"alpha_hsi": "x"}, "alpha_hsi must be between 0 and 1"),
    ({"seed": -2}, "seed must be a whole number between 0 and 2147483647"),
    ({"seed": 1.5}, "seed must be a whole number"),
    ({"frames": "abc"}, "frames must be a range START-END like '1-240', got 'abc'"),
    ({"frames": "10-1"}, "the end frame must not be before the start"),
    ({"frames": "", "frames_per_task": 50}, "frames_per_task needs a frame range"),
    ({"bakes_per_task": 0}, "bakes_per_task must be a whole number 1 or more, got 0"),
    ({"blendfile": "", "shot_files": ""}, "no .blend file to bake"),
    ({"shot_files": "/farm/shots/sh020.ma"}, "'/farm/shots/sh020.ma' is not a .blend file"),
    ({"egos": "Ego, Ego"}, "ego 'Ego' is listed twice"),
    ({"output_dir": ""}, "output_dir is empty"),
    ({"output_name": "{file}_{take}.blend"}, "unknown field {take}"),
    ({"output_name": "{file}.abc"}, "must end in .blend"),
    ({"output_name": "x/{file}.blend"}, "must be a file name, not a path"),
    ({"output_name": "{file}.blend"}, "would both save '/farm/out/sh010.blend'"),
    ({"output_dir": "/farm/shots", "egos": "", "frames": "", "output_name": "{file}.blend",
      "blendfile": "", "shot_files": "/farm/shots/sh020.blend"}, "would overwrite the shot file"),
])
def test_bad_settings_are_refused_in_one_line(change, match):
    with pytest.raises(CompileError) as exc:
        compile_job({**SHOTS, **change})
    msg = str(exc.value)
    assert msg.startswith("ReMoGen bake: ") and "\n" not in msg and match in msg, msg
