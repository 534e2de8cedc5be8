"""Live: frame_set-driven frames move the ego, sliders act, and every way of stopping restores the rest pose."""
from __future__ import annotations

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")


def _pelvis_heads(ctx, ego):
    from remogen_blender import rig
    ctx.view_layer.update()
    return rig.EgoWriter(ego).world_heads(ctx.evaluated_depsgraph_get())


def _run(ctx, frames, alpha_hhi=1.0):
    import scenes
    from remogen_blender import live
    bpy.ops.wm.read_factory_settings(use_empty=True)
    d = scenes.demo_scene(bpy.context)
    scene = bpy.context.scene
    scene.remogen.alpha_hhi = alpha_hhi
    assert bpy.ops.remogen.live_start() == {'FINISHED'}
    assert live.is_running()
    out = []
    for f in frames:
        scene.frame_set(f)
        out.append(_pelvis_heads(bpy.context, d["ego"]))
    return d, np.array(out)


def test_frame_set_moves_ego_and_alpha_changes_pose(fresh):
    from remogen_blender import live
    frames = list(range(1, 30))
    d, a = _run(fresh, frames, alpha_hhi=1.0)
    assert live.is_running(), live.message()
    assert np.abs(a[-1] - a[0]).max() > 1e-3                 # the ego moved
    assert np.isfinite(a).all()
    drv = live.state().driver
    assert drv.latest_index == int(np.ceil((29 - 1) / 24 * 10))   # 10 model frames per second of scene time
    live.stop()
    _, b = _run(fresh, frames, alpha_hhi=0.0)
    assert np.abs(a[-1] - b[-1]).max() > 1e-4               # alpha_HHI changes the pose
    _, c = _run(fresh, frames, alpha_hhi=1.0)
    assert np.allclose(a, c, atol=1e-5)                     # and the same inputs repeat exactly


def test_stop_restores_rest(fresh):
    from remogen_blender import live
    d, _ = _run(fresh, range(1, 10))
    ego = d["ego"]
    assert any(tuple(pb.rotation_quaternion) != (1.0, 0.0, 0.0, 0.0) for pb in ego.pose.bones)
    assert bpy.ops.remogen.live_stop() == {'FINISHED'}
    assert not live.is_running()
    assert all(tuple(pb.rotation_quaternion) == (1.0, 0.0, 0.0, 0.0) for pb in ego.pose.bones)
    assert all(tuple(pb.location) == (0.0, 0.0, 0.0) for pb in ego.pose.bones)
    assert not any(getattr(h, "__module__", "").startswith("remogen_blender")
                   for h in bpy.app.handlers.frame_change_post)


def test_slider_acts_while_running(fresh):
    from remogen_blender import live
    _run(fresh, range(1, 5))
    bpy.context.scene.remogen.alpha_hsi = 0.25
    bpy.context.scene.remogen.text = "sit down"
    bpy.context.scene.frame_set(6)
    s = live.state().driver.group.egos[0]
    assert s.alpha["hsi"] == pytest.approx(0.25) and s.text == "sit down"


@pytest.mark.parametrize("prop, attr", [("use_foot_lock", "cleanup"), ("use_control", "control")])
def test_plant_feet_and_steer_settings_reach_the_session(fresh, prop, attr):
    """The Plant Feet and Steer toggles switch the runtime's foot cleanup and test-time control, at start and
    while running."""
    from remogen_blender import live
    bpy.ops.wm.read_factory_settings(use_empty=True)
    import scenes
    scenes.demo_scene(bpy.context)
    setattr(bpy.context.scene.remogen, prop, False)
    assert bpy.ops.remogen.live_start() == {'FINISHED'}
    bpy.context.scene.frame_set(3)
    group = live.state().driver.group
    s = group if attr == "control" else group.egos[0]      # control is the group's, foot cleanup each ego's
    assert getattr(s, attr) is False
    setattr(bpy.context.scene.remogen, prop, True)
    bpy.context.scene.frame_set(5)
    assert getattr(s, attr) is True
    live.stop()


def test_partner_deleted_mid_run_stops_cleanly(fresh):
    from remogen_blender import live
    d, _ = _run(fresh, range(1, 6))
    bpy.data.objects.remove(d["partner"])
    bpy.context.scene.frame_set(7)
    assert not live.is_running()
    assert "Live stopped:" in live.message() and "Partner" in live.message()
    assert "\n" not in live.message()
    ego = bpy.context.scene.remogen.ego
    assert all(tuple(pb.rotation_quaternion) == (1.0, 0.0, 0.0, 0.0) for pb in ego.pose.bones)


def test_nan_partner_transform_stops(fresh):
    from remogen_blender import live
    d, _ = _run(fresh, range(1, 4))
    d["partner"].animation_data_clear()
    d["partner"].location = (float("nan"), 0.0, 0.0)
    bpy.context.scene.frame_set(5)
    assert not live.is_running()
    assert "NaN" in live.message()


def test_loading_a_file_stops_live(fresh, tmp_path):
    from remogen_blender import live
    path = str(tmp_path / "other.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path, copy=True)
    _run(fresh, range(1, 4))
    bpy.ops.wm.open_mainfile(filepath=path)
    assert not live.is_running()
    assert "another file" in live.message()


def test_errors_at_start_are_one_line(fresh):
    import scenes
    from remogen_blender import live
    with pytest.raises(RuntimeError, match="No ego armature"):
        bpy.ops.remogen.live_start()
    bpy.ops.remogen.create_ego()
    with pytest.raises(RuntimeError, match="Pick a partner armature"):
        bpy.ops.remogen.live_start()
    fresh.scene.remogen.partner = scenes.make_tentacle()
    with pytest.raises(RuntimeError, match=r"not humanoid enough: no bones for pelvis"):
        bpy.ops.remogen.live_start()
    assert not live.is_running()


def test_modal_cleanup_is_idempotent(fresh):
    """The timer is removed and the status text cleared; a second call (or a stale timer) raises nothing."""
    from types import SimpleNamespace
    from remogen_blender.operators import cleanup_modal
    removed, status = [], []

    def remove(timer):
        if timer in removed:
            raise ValueError("timer not found")     # what Blender says for a timer already removed
        removed.append(timer)

    ctx = SimpleNamespace(window_manager=SimpleNamespace(event_timer_remove=remove),
                          workspace=SimpleNamespace(status_text_set=status.append))
    timer = object()
    cleanup_modal(ctx, timer)
    cleanup_modal(ctx, timer)
    cleanup_modal(ctx, None)
    assert removed == [timer] and status == [None, None, None]
    real = fresh.window_manager.event_timer_add(0.5, window=fresh.window)
    cleanup_modal(fresh, real)                      # the real window manager takes it too


def test_timer_tick_keeps_ego_living_while_timeline_stands_still(fresh):
    import time
    from remogen_blender import live
    _run(fresh, [1])
    st = live.state()
    n0 = st.driver.latest_index
    st.last_wall = time.perf_counter() - 0.35          # as if 0.35 s of wall time passed since the last tick
    live.tick(bpy.context)
    assert live.is_running(), live.message()
    assert st.driver.latest_index - n0 in (3, 4)        # one model frame per 0.1 s
    assert live.status_line().startswith("ReMoGen live:") and "ms/frame" in live.status_line()


def test_ego_deleted_mid_run_stops_cleanly(fresh):
    from remogen_blender import live
    d, _ = _run(fresh, range(1, 5))
    body = d["ego"].children[0]
    bpy.data.objects.remove(d["ego"])
    bpy.data.objects.remove(body)
    bpy.context.scene.frame_set(7)
    assert not live.is_running()
    assert live.message().startswith("Live stopped:") and "\n" not in live.message()


def test_imported_cmu_bvh_partner(fresh):
    """A real rig: Blender's BVH importer on a CMU clip of the test data (DAZ names) is mapped and drives live."""
    import addon_utils
    from remogen_blender import live, rig
    from paths import shared_file
    bvh = shared_file("data/cmu/daz_friendly_120fps/05/05_01.bvh")
    addon_utils.enable("io_anim_bvh")
    try:
        bpy.ops.import_anim.bvh(filepath=str(bvh), global_scale=0.01, axis_forward='-Z', axis_up='Y',
                                update_scene_fps=False, update_scene_duration=True)
        partner = fresh.active_object
        bpy.ops.remogen.create_ego()
        st = fresh.scene.remogen
        st.partner = partner
        assert st.bone_map_family == "daz" and all(item.bone for item in st.bone_map)
        fresh.scene.frame_set(10)
        j = rig.PartnerReader(partner, rig.bone_map_dict(st)).read(fresh.evaluated_depsgraph_get())
        assert 1.3 < j[15, 2] - min(j[7, 2], j[8, 2]) < 1.8        # ankle to head: a person in metres
        assert bpy.ops.remogen.live_start() == {'FINISHED'}
        for f in range(11, 30):
            fresh.scene.frame_set(f)
        assert live.is_running(), live.message()
        live.stop()
        # the same clip imported at scale 1 is in centimetres: refused with a hint, nothing changes
        bpy.ops.import_anim.bvh(filepath=str(bvh), global_scale=1.0, axis_forward='-Z', axis_up='Y',
                                update_scene_fps=False, update_scene_duration=False)
        st.partner = fresh.active_object
        n_actions = len(bpy.data.actions)
        with pytest.raises(RuntimeError, match="centimetres"):
            bpy.ops.remogen.bake(frame_start=1, frame_end=10)
        assert len(bpy.data.actions) == n_actions
    finally:
        addon_utils.disable("io_anim_bvh")


def _give_action(ego, name="UserWalk"):
    """A user action on the ego: a pelvis key at frames 1 and 20."""
    act = bpy.data.actions.new(name)
    ego.animation_data_create().action = act
    pb = ego.pose.bones["pelvis"]
    for f, z in ((1, 0.0), (20, 0.3)):
        pb.location = (0.0, 0.0, z)
        pb.keyframe_insert("location", frame=f)
    pb.location = (0.0, 0.0, 0.0)
    return act


def _key_count(act) -> int:
    import scenes
    return sum(len(fc.keyframe_points) for fc in scenes.action_fcurves(act))


def test_save_during_live_keeps_the_ego_action(fresh, tmp_path):
    import scenes
    from remogen_blender import live
    bpy.ops.wm.read_factory_settings(use_empty=True)
    d = scenes.demo_scene(bpy.context)
    ego, scene = d["ego"], bpy.context.scene
    ego_name = ego.name
    act = _give_action(ego)
    n_keys = _key_count(act)
    scene.frame_set(1)
    before = scenes.ego_pose(ego)
    assert bpy.ops.remogen.live_start() == {'FINISHED'}
    for f in range(2, 12):
        scene.frame_set(f)
    assert ego.animation_data.action is None and act.use_fake_user      # off the ego, kept safe
    path = str(tmp_path / "during_live.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    # Live goes on after the save: the action is off the ego again and the live pose is shown
    assert live.is_running(), live.message()
    assert ego.animation_data.action is None
    assert not np.allclose(scenes.ego_pose(ego), before, atol=1e-4)
    scene.frame_set(12)
    assert live.is_running(), live.message()
    bpy.ops.wm.open_mainfile(filepath=path)
    ego = bpy.data.objects[ego_name]
    act = bpy.data.actions.get("UserWalk")
    assert act is not None and _key_count(act) == n_keys
    assert ego.animation_data.action == act and not act.use_fake_user   # as before Live
    bpy.context.scene.frame_set(1)
    assert np.allclose(scenes.ego_pose(ego), before, atol=1e-6)          # the action drives it again


def test_stop_gives_back_action_and_pose(fresh):
    import scenes
    from remogen_blender import live
    d, _ = _run(fresh, [1])
    live.stop()
    ego = d["ego"]
    act = _give_action(ego)
    ego.pose.bones["left_knee"].rotation_quaternion = (0.9, 0.3, 0.0, 0.0)   # a pose by hand, no key
    before = scenes.ego_pose(ego)
    bpy.ops.remogen.live_start()
    for f in range(2, 10):
        bpy.context.scene.frame_set(f)
    assert live.is_running()
    bpy.ops.remogen.live_stop()
    assert ego.animation_data.action == act and not act.use_fake_user
    bpy.context.scene.frame_set(1)            # the action drives the pelvis; the knee is as posed by hand
    assert np.allclose(scenes.ego_pose(ego), before, atol=1e-6)


@pytest.mark.parametrize("with_scene", [True, False])
def test_nan_weights_stop_live_at_the_first_bad_frame(fresh, with_scene):
    """A model turning out NaN mid-run: Live stops naming the cause (not the scene sample's transform)."""
    import scenes
    from remogen_blender import live
    d, _ = _run(fresh, range(1, 4))
    scene = bpy.context.scene
    if not with_scene:
        scene.remogen.scene_collection = None
    ego = d["ego"]
    scenes.poison_weights(live.state().driver.model)
    for f in range(4, 48):
        scene.frame_set(f)
        assert np.isfinite(scenes.ego_pose(ego)).all()          # never a NaN on the rig
        if not live.is_running():
            break
    msg = live.message()
    assert not live.is_running()
    assert "non-finite joints at model frame" in msg and "NaN or infinite weights" in msg, msg
    assert "ego-to-world" not in msg and "\n" not in msg
    assert np.allclose(scenes.ego_pose(ego)[:, :4], (1.0, 0.0, 0.0, 0.0))   # back as before Live


def test_nan_weights_refused_at_live_start(fresh):
    import scenes
    from remogen_blender import _runtime, live
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scenes.demo_scene(bpy.context)
    scenes.poison_weights(_runtime.get_model())
    with pytest.raises(RuntimeError, match="non-finite joints at model frame 0 .*NaN or infinite weights"):
        bpy.ops.remogen.live_start()
    assert not live.is_running()


def test_guidance_is_bounded(fresh):
    from remogen_blender.properties import GUIDANCE_MAX
    st = fresh.scene.remogen
    st.guidance = 1e30
    assert st.guidance == pytest.approx(GUIDANCE_MAX)


def test_partner_deleted_with_the_operator_stops_live(fresh):
    from remogen_blender import live
    d, _ = _run(fresh, range(1, 5))
    partner = d["partner"]
    for ob in bpy.context.view_layer.objects:
        ob.select_set(ob == partner)
    with bpy.context.temp_override(selected_objects=[partner], active_object=partner):
        assert bpy.ops.object.delete() == {'FINISHED'}
    bpy.context.scene.frame_set(6)
    assert not live.is_running()
    msg = live.message()
    assert msg.startswith("Live stopped:") and "Partner 'Partner' was deleted" in msg and "\n" not in msg
    with pytest.raises(RuntimeError, match="Partner was deleted or is not in scene"):
        bpy.ops.remogen.live_start()


def test_an_action_assigned_during_live_is_kept_and_so_is_the_old_one(fresh):
    from remogen_blender import live
    d, _ = _run(fresh, [1])
    live.stop()
    ego = d["ego"]
    old = _give_action(ego, "Old")
    bpy.ops.remogen.live_start()
    new = bpy.data.actions.new("New")
    ego.animation_data.action = new
    live.stop()
    assert ego.animation_data.action == new and old.use_fake_user     # neither is lost on the next save
