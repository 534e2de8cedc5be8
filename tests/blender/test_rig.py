"""Ego creation and posing, partner reading through bone maps."""
from __future__ import annotations

import sys
import types

import numpy as np
import pytest

bpy = pytest.importorskip("bpy")


def test_create_ego_structure(fresh):
    from model_runtime.skeleton import JOINT_NAMES, SOLE_BELOW_FOOT_JOINT
    assert bpy.ops.remogen.create_ego() == {'FINISHED'}
    st = fresh.scene.remogen
    ob = st.ego
    assert ob is not None and ob.type == 'ARMATURE'
    assert sorted(pb.name for pb in ob.pose.bones) == sorted(JOINT_NAMES)
    assert all(pb.rotation_mode == 'QUATERNION' for pb in ob.pose.bones)
    heads = {b.name: np.array(b.head_local) for b in ob.data.bones}
    lowest = min(heads[n][2] for n in ("left_ankle", "right_ankle", "left_foot", "right_foot"))
    assert lowest == pytest.approx(SOLE_BELOW_FOOT_JOINT, abs=1e-5)       # soles at z = 0
    body = [c for c in ob.children if c.type == 'MESH']
    assert len(body) == 1
    assert {vg.name for vg in body[0].vertex_groups} == set(JOINT_NAMES)
    assert any(m.type == 'ARMATURE' and m.object == ob for m in body[0].modifiers)


def test_written_pose_matches_model_joints(fresh):
    """Evaluated ego bone heads equal EgoFrame.joints (< 1 mm), ego object moved and turned."""
    from model_runtime import ReactionSession, load_model
    from remogen_blender import rig
    ob = rig.create_ego(fresh, location=(1.5, -0.5, 0.2), yaw=0.7)
    w = rig.EgoWriter(ob)
    s = ReactionSession(load_model(config="tiny"), text="walk", seed=3)
    root, yaw = w.start_pose()
    assert root == pytest.approx((1.5, -0.5, 0.2)) and yaw == pytest.approx(0.7)
    s.reset(root_position=root, yaw=yaw)
    for i in range(15):
        f = s.step()
        if i in (0, 7, 14):
            w.write(f.root[:3, 3], f.local_rotations)
            fresh.view_layer.update()
            err = np.abs(w.world_heads(fresh.evaluated_depsgraph_get()) - f.joints).max()
            assert err < 1e-3, f"frame {i}: {err * 1000:.3f} mm"
    w.write_rest()
    fresh.view_layer.update()
    assert all(tuple(pb.rotation_quaternion) == (1, 0, 0, 0) for pb in ob.pose.bones)


@pytest.mark.parametrize("family", ["smplx", "mixamo"])
def test_partner_reader_matches_bone_heads(fresh, family):
    import scenes
    from remogen_blender import rig
    names = None if family == "smplx" else scenes.MIXAMO
    prefix = "" if family == "smplx" else "mixamorig:"
    ob = scenes.make_armature("P", names, prefix=prefix, location=(2.0, 1.0, 0.0), yaw=1.0)
    st = fresh.scene.remogen
    st.partner = ob                        # the update callback guesses the bone map
    assert st.bone_map_family == family and st.bone_map_rig == "P"
    ob.pose.bones[prefix + (names or {}).get("left_elbow", "left_elbow")].rotation_mode = 'XYZ'
    ob.pose.bones[prefix + (names or {}).get("left_shoulder", "left_shoulder")].rotation_euler = (0.3, 0.5, 0.2)
    fresh.view_layer.update()
    reader = rig.PartnerReader(ob, rig.bone_map_dict(st))
    got = reader.read(fresh.evaluated_depsgraph_get())
    mw = ob.matrix_world
    from model_runtime.skeleton import JOINT_NAMES
    for j, name in enumerate(JOINT_NAMES):
        bone = st.bone_map[j].bone
        ref = np.array(mw @ ob.pose.bones[bone].head)
        assert np.abs(got[j] - ref).max() < 1e-5, name


def test_partner_reader_lerp_and_end(fresh):
    import scenes
    from model_runtime import JOINT_NAMES
    from remogen_blender import rig
    ob = scenes.make_armature("P")
    mapping = {j: j for j in JOINT_NAMES}
    mapping["spine2"] = "lerp:spine1:spine3:0.25"
    mapping["head"] = "end:neck"
    got = rig.PartnerReader(ob, mapping).read(fresh.evaluated_depsgraph_get())
    pb = ob.pose.bones
    want_spine2 = 0.75 * np.array(pb["spine1"].head) + 0.25 * np.array(pb["spine3"].head)
    assert np.allclose(got[6], want_spine2, atol=1e-5)
    assert np.allclose(got[15], np.array(pb["neck"].tail), atol=1e-5)


def test_non_humanoid_names_missing_joints(fresh):
    import scenes
    ob = scenes.make_tentacle()
    fresh.scene.remogen.partner = ob
    assert bpy.ops.remogen.guess_bone_map() == {'FINISHED'}   # a warning names the missing joints
    assert all(item.bone == "" for item in fresh.scene.remogen.bone_map)
    from remogen_blender import rig
    with pytest.raises(Exception, match="Partner 'Tentacle' is not humanoid enough"):
        rig.PartnerReader(ob, rig.bone_map_dict(fresh.scene.remogen))


def test_smplx_folder_errors(fresh, tmp_path, monkeypatch):
    from remogen_blender import rig
    from remogen_blender._runtime import UserError
    n = len(bpy.data.objects)
    with pytest.raises(UserError, match="does not exist"):
        rig.create_ego(fresh, smplx_folder=str(tmp_path / "nope"))
    monkeypatch.setitem(sys.modules, "smplx", None)    # not installed
    with pytest.raises(UserError, match="'smplx' package is not installed"):
        rig.create_ego(fresh, smplx_folder=str(tmp_path))
    assert len(bpy.data.objects) == n                  # nothing was created


def test_smplx_mesh_with_fake_package(fresh, tmp_path, monkeypatch):
    """The SMPL-X path: Y-up -> Z-up, pelvis aligned, finger/jaw weights folded into the body joints."""
    import torch
    from model_runtime.skeleton import JOINT_NAMES, REST_JOINTS_ZUP
    from remogen_blender import rig
    zup = np.array(REST_JOINTS_ZUP)
    yup = np.stack((zup[:, 0], zup[:, 2], -zup[:, 1]), 1)          # inverse of (x, -z, y)
    verts = np.concatenate((yup, yup[:3] + 0.01))                  # 25 "vertices"
    parents = list(range(-1, 21)) + [15, 20, 21]                     # 3 extra joints: under head, wrists
    weights = np.zeros((25, 25))
    weights[np.arange(25), np.arange(25)] = 1.0
    weights[22:, :] = 0.0
    weights[22, 22] = weights[23, 23] = weights[24, 24] = 1.0       # extra vertices skinned to extra joints

    class FakeModel:
        faces = np.array([[0, 1, 2], [22, 23, 24]])
        lbs_weights = torch.tensor(weights)
        parents_ = torch.tensor(parents)

        def __call__(self, return_verts=True):
            return types.SimpleNamespace(vertices=torch.tensor(verts)[None],
                                         joints=torch.tensor(np.concatenate((yup, yup[:3])))[None])
    FakeModel.parents = FakeModel.parents_
    fake = types.SimpleNamespace(create=lambda *a, **k: FakeModel())
    monkeypatch.setitem(sys.modules, "smplx", fake)
    ob = rig.create_ego(fresh, smplx_folder=str(tmp_path))
    body = next(c for c in ob.children if c.type == 'MESH')
    co = np.array([v.co for v in body.data.vertices])
    heads = np.array([ob.data.bones[n].head_local for n in JOINT_NAMES])
    assert np.abs(co[:22] - heads).max() < 1e-5
    groups = {vg.index: vg.name for vg in body.vertex_groups}
    v22 = body.data.vertices[22]
    assert [groups[g.group] for g in v22.groups] == ["head"]       # joint 22 -> parent 15 (head)
    assert [groups[g.group] for g in body.data.vertices[24].groups] == ["right_wrist"]


@pytest.mark.parametrize("kind", ["MESH", "EMPTY"])
def test_partner_that_is_no_armature_gives_one_line(fresh, kind, capfd):
    """Python skips the picker's armature filter: every reader of the partner names the mistake in one line."""
    import scenes
    from remogen_blender import live, rig
    from remogen_blender._runtime import UserError
    d = scenes.demo_scene(fresh)
    if kind == "MESH":
        wrong = scenes.make_box("Crate", (0.0, -3.0, 0.0))
        want = "Partner 'Crate' is a MESH, not an armature: pick the partner's armature"
    else:
        wrong = bpy.data.objects.new("Marker", None)
        fresh.scene.collection.objects.link(wrong)
        want = "Partner 'Marker' is an EMPTY, not an armature: pick the partner's armature"
    st = fresh.scene.remogen
    st.partner = wrong                      # the update callback must not raise or print a traceback
    assert "Traceback" not in capfd.readouterr().err
    with pytest.raises(UserError) as err:
        rig.PartnerReader(wrong, rig.bone_map_dict(st))
    assert str(err.value) == want
    with pytest.raises(UserError) as err:
        rig.fill_bone_map(st, wrong)
    assert str(err.value) == want
    n_actions = len(bpy.data.actions)
    for op in (bpy.ops.remogen.guess_bone_map, bpy.ops.remogen.live_start, bpy.ops.remogen.bake):
        with pytest.raises(RuntimeError) as err:
            op()
        assert str(err.value).strip() == f"Error: {want}", op
    assert not live.is_running() and len(bpy.data.actions) == n_actions and d["ego"].animation_data is None
