"""Several egos in one scene: the ego list and its operators, a bake writing one new action per ego
(deterministic per seed, the users' actions kept), and Live posing every ego and putting each back."""
from __future__ import annotations

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")


def _curves(action) -> dict:
    import scenes
    return scenes.action_curves(action)


def _two_egos(frames=(1, 24)) -> dict:
    """The demo scene (first ego at the origin, partner walking in) plus a second ego from the list's + button."""
    import scenes
    bpy.ops.wm.read_factory_settings(use_empty=True)
    d = scenes.demo_scene(bpy.context, frames=frames)
    assert bpy.ops.remogen.ego_add() == {'FINISHED'}
    st = bpy.context.scene.remogen
    d["ego2"] = st.egos[0].ego
    st.egos[0].text = "a person walks forward"
    return d


def test_ego_list_add_and_remove(fresh):
    import scenes
    scenes.demo_scene(bpy.context)
    st = bpy.context.scene.remogen
    first = st.ego
    assert bpy.ops.remogen.ego_add() == {'FINISHED'}
    assert len(st.egos) == 1 and st.egos[0].ego is not None and st.egos[0].ego != first
    assert st.egos[0].ego.type == 'ARMATURE' and st.egos[0].seed != st.seed
    made = st.egos[0].ego.name
    assert bpy.ops.remogen.ego_add(create=False) == {'FINISHED'}
    assert len(st.egos) == 2 and st.egos[1].ego is None and st.ego_index == 1
    # an entry without an armature is refused with one line, and nothing changes
    with pytest.raises(RuntimeError) as err:
        bpy.ops.remogen.bake()
    assert "Ego 3 of the ego list has no armature" in str(err.value) and "\n" not in str(err.value).strip()
    assert not any(a.name.startswith("ReMoGen_") for a in bpy.data.actions)
    assert bpy.ops.remogen.ego_remove() == {'FINISHED'}
    st.ego_index = 0
    assert bpy.ops.remogen.ego_remove() == {'FINISHED'}
    assert len(st.egos) == 0 and made in bpy.data.objects       # removing an entry keeps its armature
    assert not bpy.ops.remogen.ego_remove.poll()
    assert st.ego == first


def test_an_armature_twice_in_the_ego_list_is_refused(fresh):
    _two_egos()
    st = bpy.context.scene.remogen
    st.egos[0].ego = st.ego
    with pytest.raises(RuntimeError) as err:
        bpy.ops.remogen.bake()
    assert "is used twice among the egos" in str(err.value)


def test_two_egos_bake_two_actions_deterministic_per_seed(fresh):
    d = _two_egos()
    user = bpy.data.actions.new("UserAction2")          # the second ego's own action must survive
    d["ego2"].animation_data_create().action = user
    assert bpy.ops.remogen.bake() == {'FINISHED'}
    st = bpy.context.scene.remogen
    first, second = d["ego"].animation_data.action, d["ego2"].animation_data.action
    assert first.name == f"ReMoGen_{d['ego'].name}_seed{st.seed}"
    assert second.name == f"ReMoGen_{d['ego2'].name}_seed{st.egos[0].seed}"
    assert "UserAction2" in bpy.data.actions and bpy.data.actions["UserAction2"].use_fake_user
    a1, a2 = _curves(first), _curves(second)
    assert len(a1) == len(a2) == 22 * 4 + 3
    assert all(np.array_equal(co[:, 0], np.arange(1, 25, dtype=np.float32)) for co in a2.values())
    assert any(not np.array_equal(a1[k][:, 1], a2[k][:, 1]) for k in a1)    # two egos, two motions
    # again: the same keys for both; another seed for the second ego changes its keys
    assert bpy.ops.remogen.bake() == {'FINISHED'}
    b1, b2 = _curves(d["ego"].animation_data.action), _curves(d["ego2"].animation_data.action)
    assert all(np.array_equal(a1[k], b1[k]) for k in a1) and all(np.array_equal(a2[k], b2[k]) for k in a2)
    st.egos[0].seed = 11
    assert bpy.ops.remogen.bake() == {'FINISHED'}
    c2 = _curves(d["ego2"].animation_data.action)
    assert any(not np.array_equal(a2[k], c2[k]) for k in a2)


def test_two_egos_bake_is_one_undo_step(fresh):
    from test_bake import _window_override
    d = _two_egos(frames=(1, 12))
    names = (d["ego"].name, d["ego2"].name)
    with _window_override():
        bpy.ops.ed.undo_push(message="before bake")
        assert bpy.ops.remogen.bake() == {'FINISHED'}
        bpy.ops.ed.undo_push(message="bake")
        assert sum(a.name.startswith("ReMoGen_") for a in bpy.data.actions) == 2
        bpy.ops.ed.undo()
    assert not any(a.name.startswith("ReMoGen_") for a in bpy.data.actions)
    for name in names:
        ob = bpy.data.objects[name]
        assert ob.animation_data is None or ob.animation_data.action is None


def test_live_poses_every_ego_and_puts_each_back(fresh):
    import scenes
    from remogen_blender import live
    d = _two_egos()
    user = bpy.data.actions.new("UserAction2")
    d["ego2"].animation_data_create().action = user
    before = [scenes.ego_pose(d["ego"]), scenes.ego_pose(d["ego2"])]
    assert bpy.ops.remogen.live_start() == {'FINISHED'}
    assert d["ego2"].animation_data.action is None           # held while Live poses it
    for f in range(2, 8):
        bpy.context.scene.frame_set(f)
    assert live.is_running() and len(live.state().driver.group.egos) == 2
    moved = [scenes.ego_pose(d["ego"]), scenes.ego_pose(d["ego2"])]
    assert all(np.abs(m - b).max() > 1e-4 for m, b in zip(moved, before))
    live.stop()
    assert d["ego2"].animation_data.action == user
    assert all(np.array_equal(scenes.ego_pose(ob), b) for ob, b in zip((d["ego"], d["ego2"]), before))


def test_live_stops_when_the_ego_list_changes(fresh):
    from remogen_blender import live
    _two_egos()
    assert bpy.ops.remogen.live_start() == {'FINISHED'}
    bpy.context.scene.frame_set(3)
    bpy.context.scene.remogen.egos.remove(0)
    bpy.context.scene.frame_set(4)
    assert not live.is_running() and "ego list changed" in live.message()


def test_one_ego_settings_and_the_ego_list_survive_save_and_load(fresh, tmp_path):
    """The first ego's settings keep their names on scene.remogen (a file with one ego loads as before, with an
    empty ego list); the list's entries are saved with their own settings."""
    _two_egos()
    st = bpy.context.scene.remogen
    st.text, st.seed, st.alpha_hhi = "wave", 9, 0.25
    st.egos[0].text, st.egos[0].seed, st.egos[0].use_fwsr = "a person runs", 4, False
    ego2 = st.egos[0].ego.name
    path = str(tmp_path / "egos.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.open_mainfile(filepath=path)
    st = bpy.context.scene.remogen
    assert (st.text, st.seed, st.alpha_hhi) == ("wave", 9, 0.25) and st.ego is not None
    item = st.egos[0]
    assert (len(st.egos), item.text, item.seed, item.use_fwsr, item.ego.name) == (1, "a person runs", 4, False, ego2)
