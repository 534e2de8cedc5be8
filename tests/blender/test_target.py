"""The user's own rig as the target: retargeted bakes (directions, pelvis path, planted feet), its action kept,
one undo step, the same keys per seed, Live giving it back, missing bones named, its bone map in the panel."""
from __future__ import annotations

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

# (family, proportions, rest pose, object scale): the rigs a retarget must handle
CASES = {
    "mixamo_a_pose": dict(family="mixamo", a_pose_deg=45.0),
    "rigify_0.8x": dict(family="rigify", scale=0.8),
    "mixamo_1.25x_fbx_cm": dict(family="mixamo", scale=1.25, a_pose_deg=30.0, centimetres=True),
    "rigify_legs_1.15x_a_pose": dict(family="rigify", leg_scale=1.15, a_pose_deg=45.0),
}
MAX_DIRECTION_DEG = 10.0
MAX_PELVIS_CM = 5.0
MAX_PLANTED_CM = 1.0


@pytest.fixture(scope="module")
def shipped_model():
    from model_runtime import load_model
    return load_model()


def _curves(action) -> dict:
    import scenes
    return scenes.action_curves(action)


def _give_action(ob, bone: str, name: str = "UserAction"):
    """The user's own action on `ob`: two keys on one bone."""
    act = bpy.data.actions.new(name)
    ob.animation_data_create().action = act
    pb = ob.pose.bones[bone]
    pb.rotation_mode = 'QUATERNION'
    for f, w in ((1, 1.0), (20, 0.9)):
        pb.rotation_quaternion = (w, (1.0 - w * w) ** 0.5, 0.0, 0.0)
        pb.keyframe_insert("rotation_quaternion", frame=f)
    pb.rotation_quaternion = (1.0, 0.0, 0.0, 0.0)
    return act


def _bake_and_measure(model, target, mode: str, text: str = "walk forward"):
    import retarget_checks
    import scenes
    from model_runtime.skeleton import standing_pelvis_height
    from remogen_blender import rig
    from remogen_blender.bake import BakeJob
    d = scenes.target_scene(bpy.context, target, mode=mode)
    st = bpy.context.scene.remogen
    st.text = text
    mapping = rig.bone_map_dict(st, rig.TARGET)
    user = _give_action(target, mapping["left_elbow"])
    job = BakeJob(bpy.context.scene, model=model)
    while not job.step(max_frames=8):
        pass
    res = job.finish()
    if mode == 'BOTH':
        start = np.array(d["ego"].location)
    else:
        rest = retarget_checks.rest_points(target, mapping)["pelvis"]
        start = np.array((rest[0], rest[1], target.location.z))
    start = start + (0.0, 0.0, standing_pelvis_height())
    worst = retarget_checks.measure(bpy.context.scene, job, target, mapping, start,
                                    {0: mapping["left_foot"], 1: mapping["right_foot"]})
    return d, res, user, worst


@pytest.mark.parametrize("case", list(CASES))
def test_retargeted_bake_follows_the_ego(fresh, shipped_model, case):
    """Three seconds of a walk baked onto the target beside the ego: every mapped bone points where the ego's
    does, the pelvis follows the ego's path scaled by leg length, planted toes stay put; the user's action
    on the target is kept and both armatures get new actions."""
    import scenes
    target = scenes.make_target("Character", location=(-1.5, 0.0, 0.0), **CASES[case])
    d, res, user, worst = _bake_and_measure(shipped_model, target, 'BOTH')
    print(f"{case}: {worst}")
    assert worst.direction_deg <= MAX_DIRECTION_DEG, worst
    assert worst.pelvis_cm <= MAX_PELVIS_CM, worst
    assert worst.planted_frames >= 30, worst           # the walk has planted feet to check
    assert worst.planted_cm <= MAX_PLANTED_CM, worst
    assert [ob for ob, _a, _o in res.keyed] == [d["ego"].name, "Character"]
    assert target.animation_data.action == res.keyed[1][1] and res.keyed[1][2] == "UserAction"
    assert user.name in bpy.data.actions and user.use_fake_user and len(scenes.action_fcurves(user)) == 4


def test_target_only_starts_where_the_target_stands(fresh, shipped_model):
    """No ego in the file: the motion starts at the target's place and facing, and the same checks hold."""
    import math
    import scenes
    target = scenes.make_target("Character", family="mixamo", scale=1.1, a_pose_deg=40.0,
                                location=(0.6, 0.4, 0.0), yaw=math.radians(25.0))
    d, res, _user, worst = _bake_and_measure(shipped_model, target, 'TARGET')
    print(f"target only: {worst}")
    assert "ego" not in d and not any(ob.type == 'ARMATURE' and ob.name.startswith("SMPLX") for ob in bpy.data.objects)
    assert [ob for ob, _a, _o in res.keyed] == ["Character"]
    assert worst.direction_deg <= MAX_DIRECTION_DEG and worst.pelvis_cm <= MAX_PELVIS_CM, worst
    assert worst.planted_frames >= 30 and worst.planted_cm <= MAX_PLANTED_CM, worst


def _target_scene(frames=(1, 24), **kw):
    import scenes
    bpy.ops.wm.read_factory_settings(use_empty=True)
    target = scenes.make_target("Character", location=(-1.5, 0.0, 0.0), **kw)
    return scenes.target_scene(bpy.context, target, mode='BOTH', frames=frames)


def test_same_seed_same_target_keys(fresh):
    d = _target_scene(a_pose_deg=45.0)
    assert bpy.ops.remogen.bake() == {'FINISHED'}
    a = _curves(d["target"].animation_data.action)
    assert bpy.ops.remogen.bake() == {'FINISHED'}
    b = _curves(d["target"].animation_data.action)
    assert a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)
    bpy.context.scene.remogen.seed = 5
    assert bpy.ops.remogen.bake() == {'FINISHED'}
    c = _curves(d["target"].animation_data.action)
    assert any(not np.array_equal(a[k], c[k]) for k in a)


def test_undo_removes_the_bake_of_ego_and_target_in_one_step(fresh):
    d = _target_scene(frames=(1, 12))
    _give_action(d["target"], "mixamorig:LeftForeArm")
    win = bpy.context.window_manager.windows[0]
    area = next(a for a in win.screen.areas if a.type == 'VIEW_3D')
    with bpy.context.temp_override(window=win, area=area):
        bpy.ops.ed.undo_push(message="before bake")
        assert bpy.ops.remogen.bake() == {'FINISHED'}
        bpy.ops.ed.undo_push(message="bake")
        assert sum(a.name.startswith("ReMoGen_") for a in bpy.data.actions) == 2
        bpy.ops.ed.undo()
    assert not any(a.name.startswith("ReMoGen_") for a in bpy.data.actions)
    target = bpy.data.objects["Character"]
    assert target.animation_data.action.name == "UserAction"


def _snapshot():
    import scenes
    st = bpy.context.scene.remogen
    obs = [ob for ob in (st.ego, st.target) if ob is not None]
    return (sorted(a.name for a in bpy.data.actions), bpy.context.scene.frame_current,
            [scenes.ego_pose(ob).tolist() for ob in obs],
            [ob.animation_data.action.name if ob.animation_data and ob.animation_data.action else None for ob in obs])


def test_missing_bones_are_named_in_one_line_and_nothing_changes(fresh):
    from remogen_blender import live
    d = _target_scene(frames=(1, 12), unmapped=("left_knee", "right_wrist"))
    _give_action(d["target"], "mixamorig:LeftForeArm")
    before = _snapshot()
    for op in (bpy.ops.remogen.bake, bpy.ops.remogen.live_start):
        with pytest.raises(RuntimeError) as exc:
            op()
        msg = str(exc.value).strip()
        assert msg == ("Error: Target 'Character' has no bones for left_knee, right_wrist: map them in the Target "
                       "Bone Map panel (or pick a humanoid armature)"), msg
        assert _snapshot() == before and not live.is_running()


def test_target_bone_map_is_detected_and_editable(fresh):
    import scenes
    from remogen_blender import rig
    d = _target_scene(family="rigify")
    st = fresh.scene.remogen
    assert st.target_bone_map_family == "rigify" and st.target_bone_map_rig == "Character"
    assert rig.bone_map_dict(st, rig.TARGET)["neck"] == "DEF-spine.004"
    assert st.bone_map_family == "mixamo"                       # the partner's map is its own
    # an edit in the panel is what Live and Bake use: a wrong name is named
    st.target_bone_map[[it.joint for it in st.target_bone_map].index("left_elbow")].bone = "DEF-nope"
    with pytest.raises(RuntimeError, match="Target 'Character' has no bones for left_elbow"):
        bpy.ops.remogen.bake()
    st.target_bone_map_index = [it.joint for it in st.target_bone_map].index("left_elbow")
    d["target"].data.bones.active = d["target"].data.bones["DEF-forearm.L"]
    assert bpy.ops.remogen.bone_from_active(target=True) == {'FINISHED'}
    assert bpy.ops.remogen.bake() == {'FINISHED'}
    assert bpy.ops.remogen.guess_bone_map(target=True) == {'FINISHED'}
    assert rig.bone_map_dict(st, rig.TARGET)["left_elbow"] == "DEF-forearm.L"
    # the picker offers armatures other than the partner and the ego
    from remogen_blender.properties import _is_target_candidate
    assert _is_target_candidate(st, d["target"]) and not _is_target_candidate(st, d["partner"])
    assert not _is_target_candidate(st, d["ego"]) and not _is_target_candidate(st, scenes.make_box("B", (0, 0, 0)))


def test_target_that_is_the_partner_is_refused(fresh):
    d = _target_scene()
    st = fresh.scene.remogen
    st.partner = d["target"]                  # a script can set what the picker would not offer
    with pytest.raises(RuntimeError, match="The target and the partner are the same armature"):
        bpy.ops.remogen.bake()


def test_euler_bones_are_keyed_in_their_own_mode(fresh):
    """A rig whose bones rotate in Euler XYZ gets Euler keys that give the same pose as quaternion keys."""
    from remogen_blender import rig
    d = _target_scene(frames=(1, 12))
    target, scene = d["target"], fresh.scene

    def heads():
        dg = fresh.evaluated_depsgraph_get()
        ev = target.evaluated_get(dg)
        return np.array([tuple(pb.tail) for pb in ev.pose.bones])

    assert bpy.ops.remogen.bake() == {'FINISHED'}
    scene.frame_set(9)
    want = heads()
    mapped = set(rig.bone_map_dict(fresh.scene.remogen, rig.TARGET).values())
    for pb in target.pose.bones:
        pb.rotation_mode = 'XYZ'
    assert bpy.ops.remogen.bake() == {'FINISHED'}
    paths = {k[0] for k in _curves(target.animation_data.action)}
    assert all(f'pose.bones["{b}"].rotation_euler' in paths for b in mapped)
    scene.frame_set(9)
    assert np.abs(heads() - want).max() < 1e-4


def test_live_poses_the_target_and_gives_it_back(fresh, tmp_path):
    """Live moves the target as the bake does (< 1 mm), keeps its action safe through a save, and puts its
    action and pose back on stop."""
    import scenes
    from remogen_blender import live
    d = _target_scene(frames=(1, 24))
    target, scene = d["target"], fresh.scene
    assert bpy.ops.remogen.bake() == {'FINISHED'}
    baked_action = target.animation_data.action

    def tails():
        dg = fresh.evaluated_depsgraph_get()
        ev = target.evaluated_get(dg)
        mw = np.array(ev.matrix_world)
        return np.array([mw[:3, :3] @ np.array(pb.tail) + mw[:3, 3] for pb in ev.pose.bones])

    baked = []
    for f in range(1, 25):
        scene.frame_set(f)
        baked.append(tails())
    scene.frame_set(1)
    target.pose.bones["mixamorig:Head"].rotation_quaternion = (0.9, 0.0, 0.3, 0.0)   # posed by hand too
    before = scenes.ego_pose(target)
    assert bpy.ops.remogen.live_start() == {'FINISHED'}
    lived = []
    for f in range(1, 25):
        scene.frame_set(f)
        lived.append(tails())
    assert live.is_running(), live.message()
    assert target.animation_data.action is None and baked_action.use_fake_user
    assert np.abs(np.array(baked) - np.array(lived)).max() < 1e-3
    path = str(tmp_path / "live.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    assert live.is_running() and target.animation_data.action is None
    live.stop()
    assert target.animation_data.action == baked_action
    assert np.allclose(scenes.ego_pose(target), before, atol=1e-6)
    name = baked_action.name
    bpy.ops.wm.open_mainfile(filepath=path)
    assert bpy.data.objects["Character"].animation_data.action.name == name      # the file has it assigned


def test_panel_shows_the_target_and_its_bone_map(fresh):
    from test_ui_and_deps import FakeLayout, _draw
    from remogen_blender.panels import REMOGEN_PT_main, REMOGEN_PT_target_bone_map, REMOGEN_UL_bone_map
    _target_scene()
    st = fresh.scene.remogen
    log = _draw(REMOGEN_PT_main, fresh)
    props = [a[1] for name, a, kw in log if name == "prop"]
    assert "target" in props and "target_mode" in props
    labels = [kw.get("text", "") for name, a, kw in log if name == "label"]
    assert labels.count("Bone map: mixamo (22/22)") == 2            # the partner's and the target's
    assert REMOGEN_PT_target_bone_map.poll(fresh)
    _draw(REMOGEN_PT_target_bone_map, fresh)
    REMOGEN_UL_bone_map.draw_item(None, fresh, FakeLayout([]), st, st.target_bone_map[0], 0, st,
                                  "target_bone_map_index")


def test_command_line_bake_of_a_target_only_file_makes_no_ego(fresh, tmp_path, tiny_model_file):
    """A file whose target is posed alone bakes from the command line without an ego being added to it."""
    import scenes
    from remogen_blender.cli import cli_main
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scenes.target_scene(fresh, scenes.make_target("Character"), mode='TARGET', frames=(1, 12))
    src, out = tmp_path / "scene.blend", tmp_path / "out.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(src))
    assert cli_main(["bake", "--blend", str(src), "--model", str(tiny_model_file), "--output", str(out)]) == 0
    bpy.ops.wm.open_mainfile(filepath=str(out))
    assert [ob.name for ob in bpy.data.objects if ob.type == 'ARMATURE'] == ["Character", "Partner"]
    assert bpy.data.objects["Character"].animation_data.action.name.startswith("ReMoGen_Character")


def test_target_deleted_during_live_stops_it_in_one_line(fresh):
    from remogen_blender import live
    d = _target_scene(frames=(1, 24))
    assert bpy.ops.remogen.live_start() == {'FINISHED'}
    fresh.scene.frame_set(3)
    bpy.data.objects.remove(d["target"])
    fresh.scene.frame_set(5)
    assert not live.is_running()
    msg = live.message()
    assert msg.startswith("Live stopped:") and "Target" in msg and "\n" not in msg, msg


def test_leg_ik_maths():
    """The analytic solve puts a reachable ankle exactly on its goal; the foot roll turns about the toe; the
    pelvis move lets a stretched leg reach while a straight other leg keeps its length."""
    from remogen_blender.rig import leg_ik
    rng = np.random.default_rng(0)
    n = 200
    hip = rng.normal(size=(n, 3))
    knee = hip + 0.4 * leg_ik.unit(rng.normal(size=(n, 3)) + (0.0, 0.0, -2.0))
    ankle = knee + 0.42 * leg_ik.unit(rng.normal(size=(n, 3)) + (0.0, 0.0, -2.0))
    goal = hip + leg_ik.unit(rng.normal(size=(n, 3))) * rng.uniform(0.1, 0.8, size=(n, 1))
    turn_hip, turn_knee = leg_ik.solve_leg(hip, knee, ankle, goal, np.tile((1.0, 0.0, 0.0), (n, 1)))
    new_knee = hip + (turn_hip @ (knee - hip)[..., None])[..., 0]
    new_ankle = new_knee + (turn_knee @ (ankle - knee)[..., None])[..., 0]
    assert np.abs(new_ankle - goal).max() < 1e-9
    assert np.allclose(np.linalg.norm(new_knee - hip, axis=-1), 0.4)             # bones keep their lengths
    # a toe 2 mm out of reach: the foot rolls about the toe until the ankle is in reach
    toe = np.array([[0.0, -0.15, 0.0]])
    ank = np.array([[0.0, 0.0, 0.05]])
    hips = np.array([[0.0, 0.3, 0.05 + 0.80]])
    reach = np.linalg.norm(hips - ank) - 0.002
    roll = leg_ik.roll_about_toe(ank, toe, hips, reach)
    rolled = toe + (roll[0] @ (ank - toe)[0])
    assert np.linalg.norm(hips[0] - rolled) == pytest.approx(reach, abs=1e-9)
    assert np.linalg.norm(rolled - toe[0]) == pytest.approx(np.linalg.norm(ank - toe), abs=1e-12)
    # two planted legs: A 2 cm beyond reach, B straight (at its reach): the pelvis moves, B keeps its length
    hips2 = np.array([[[0.1, 0.0, 0.9], [-0.1, 0.0, 0.9]]])
    goals = np.array([[[0.1, 0.35, 0.9 - 0.80], [-0.1, -0.2, 0.1]]])
    reach2 = np.array([np.linalg.norm(goals[0, 0] - hips2[0, 0]) - 0.02, np.linalg.norm(goals[0, 1] - hips2[0, 1])])
    shift = leg_ik._pelvis_shift(hips2, goals, reach2)
    after = np.linalg.norm(goals - (hips2 + shift[:, None]), axis=-1)[0]
    assert after[0] == pytest.approx(reach2[0], abs=1e-3) and after[1] == pytest.approx(reach2[1], abs=1e-3)
