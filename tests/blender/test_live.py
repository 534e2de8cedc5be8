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
    s = live.state().driver.session
    assert s.alpha["hsi"] == pytest.approx(0.25) and s.text == "sit down"


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
    from remogen_blender.operators import cleanup_modal
    wm = fresh.window_manager
    timer = wm.event_timer_add(0.5, window=fresh.window)
    cleanup_modal(fresh, timer)
    cleanup_modal(fresh, timer)
    cleanup_modal(fresh, None)


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
