"""The demo command: builds the scene from the shipped CMU clip, bakes, saves demo.blend and a PNG strip."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from blender_env import subprocess_env

bpy = pytest.importorskip("bpy")
ROOT = Path(__file__).resolve().parents[2]


def test_demo_scene_and_strip(tmp_path, tiny_model_file):
    env = subprocess_env(ROOT)
    r = subprocess.run([sys.executable, "-m", "remogen_blender.demo", "--out", str(tmp_path), "--model",
                        str(tiny_model_file), "--shots", "2", "--size", "64"], cwd=tmp_path, env=env,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "remogen demo: baked 214 frames" in r.stdout   # the 5 s walk, then 4 s held
    assert (tmp_path / "demo.blend").is_file()
    png = (tmp_path / "demo_strip.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    width, height = int.from_bytes(png[16:20], "big"), int.from_bytes(png[20:24], "big")
    assert (width, height) == (128, 64)


def test_demo_with_a_mixamo_target(fresh, tmp_path, tiny_model_file):
    """`--target mixamo`: a Mixamo-named character with longer legs and an A-pose rest stands in for the ego;
    the bake keys it (and no ego is made) and the strip shows it."""
    import scenes
    from remogen_blender import demo
    env = subprocess_env(ROOT)
    r = subprocess.run([sys.executable, "-m", "remogen_blender.demo", "--out", str(tmp_path), "--model",
                        str(tiny_model_file), "--shots", "2", "--size", "64", "--target", "mixamo"], cwd=tmp_path,
                       env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "remogen demo: baked 214 frames" in r.stdout   # the 5 s walk, then 4 s held and "onto 'Character'" in r.stdout
    png = (tmp_path / "demo_strip.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and int.from_bytes(png[16:20], "big") == 128
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "demo.blend"))
    st = bpy.context.scene.remogen
    character = bpy.data.objects["Character"]
    assert st.target == character and st.target_mode == 'TARGET' and st.ego is None
    assert st.target_bone_map_family == "mixamo"
    assert not any(ob.type == 'ARMATURE' and ob.name.startswith("Ego") for ob in bpy.data.objects)
    act = character.animation_data.action
    assert act.name.startswith("ReMoGen_Character") and len(scenes.action_fcurves(act)) == 22 * 4 + 3
    bones = character.data.bones
    joints = {n: np.array(bones["mixamorig:" + demo.MIXAMO_NAMES[n]].head_local) for n in ("left_hip", "left_ankle")}
    legs = np.linalg.norm(joints["left_hip"] - joints["left_ankle"])
    ego_legs = np.linalg.norm(np.subtract(*demo.humanoid_heads()[[1, 7]]))
    assert legs / ego_legs == pytest.approx(demo.TARGET_LEG_SCALE, rel=0.02)
    assert bones["mixamorig:LeftForeArm"].head_local.z < bones["mixamorig:LeftArm"].head_local.z - 0.1   # A-pose
    bpy.context.scene.frame_set(1)
    start = np.array(character.pose.bones["mixamorig:Hips"].head)
    bpy.context.scene.frame_set(118)
    assert np.linalg.norm(np.array(character.pose.bones["mixamorig:Hips"].head) - start) > 0.05   # it moved


def test_demo_clip_is_small_cmu_data():
    import numpy as np
    from model_runtime import WALK_CLIP
    clip = np.load(WALK_CLIP)
    assert clip["local_rotations"].shape[1:] == (22, 4) and len(clip["pelvis"]) == len(clip["local_rotations"])
    assert "mocap.cs.cmu.edu" in str(clip["credit"])
    assert WALK_CLIP.stat().st_size < 100_000


def _screen(scene, points):
    """(N, 3) world points -> (N, 3) camera view: x, y in 0..1 inside the picture, z the depth in front."""
    from bpy_extras.object_utils import world_to_camera_view
    from mathutils import Vector
    return np.array([tuple(world_to_camera_view(scene, scene.camera, Vector(tuple(p)))) for p in points])


def test_strip_camera_shows_ego_table_and_goal(fresh, tmp_path):
    """Every strip frame shows the ego's whole body (feet included), the table and the goal marker, and no
    ego joint or the goal lies behind the table where the table covers it on screen: the demo as it runs, with
    the shipped weights (a random model's ego may wander anywhere, behind the table too)."""
    from model_runtime import load_model
    from remogen_blender import demo, rig
    from remogen_blender.bake import bake
    scene, n = demo.build_scene(fresh)
    bake(scene, 1, n, model=load_model())
    shots = [1, 40, 80, n]
    demo.render_strip(scene, shots, tmp_path / "strip.png", size=32)
    st = scene.remogen
    marker = scene.objects["GoalMarker"]
    assert marker.type == 'MESH' and marker.parent == st.goal and not marker.hide_render   # rendered, unlike an empty
    ego_body = next(c for c in st.ego.children if c.type == 'MESH')
    writer = rig.EgoWriter(st.ego)
    for f in shots:
        scene.frame_set(f)
        joints = writer.world_heads(fresh.evaluated_depsgraph_get())    # all 22, the feet and ankles included
        goal = np.array(st.goal.matrix_world.translation)[None]
        table = demo.world_corners([scene.objects["Table"]])
        seen = {"ego joints": joints, "ego body": demo.world_corners([ego_body]), "goal": goal,
                "goal marker": demo.world_corners([marker]), "table": table}
        for what, pts in seen.items():
            s = _screen(scene, pts)
            inside = (s[:, 0] > 0.0) & (s[:, 0] < 1.0) & (s[:, 1] > 0.0) & (s[:, 1] < 1.0) & (s[:, 2] > 0.0)
            assert inside.all(), f"frame {f}: {what} out of the picture at {s[~inside][:3]}"
        t = _screen(scene, table)
        for what, pts in (("ego joints", joints), ("goal", goal)):
            s = _screen(scene, pts)
            covered = ((s[:, 0] >= t[:, 0].min()) & (s[:, 0] <= t[:, 0].max())
                       & (s[:, 1] >= t[:, 1].min()) & (s[:, 1] <= t[:, 1].max()))
            assert (s[covered, 2] < t[:, 2].min()).all(), f"frame {f}: the table hides {what}"


def test_the_demo_ego_walks_to_the_partner_and_waves(fresh):
    """The demo as it runs (shipped weights, seed 0): the ego ends at the goal beside the partner, about a metre
    from it, and waves (a wrist above its shoulder moving side to side by the wave kind's 8 cm)."""
    from model_runtime import load_model
    from model_runtime.behaviour.metrics import wave_measures
    from remogen_blender import demo, rig
    from remogen_blender.bake import bake
    scene, n = demo.build_scene(fresh)
    bake(scene, 1, n, model=load_model())
    st = scene.remogen
    ego, partner = rig.EgoWriter(st.ego), rig.EgoWriter(st.partner)
    joints = []
    for t in np.arange(0.0, (n - 1) / scene.render.fps, 0.1):       # at the model's 10 frames a second
        f = 1.0 + t * scene.render.fps
        scene.frame_set(int(f), subframe=f - int(f))
        joints.append(ego.world_heads(fresh.evaluated_depsgraph_get()))
    joints = np.array(joints)
    last_partner = partner.world_heads(fresh.evaluated_depsgraph_get())
    goal = np.array(st.goal.matrix_world.translation)
    assert np.linalg.norm(joints[-1, 0, :2] - goal[:2]) < 0.5
    assert 0.5 < np.linalg.norm(joints[-1, 0, :2] - last_partner[0, :2]) < 1.5
    sd, raised = wave_measures(joints)
    assert sd >= 0.08, f"wrist side-to-side sd {sd:.3f} m, raised {raised:.0f} % of frames"
