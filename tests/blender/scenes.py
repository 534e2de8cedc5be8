"""Scene builders for the extension tests: armatures with chosen bone names, a walking partner, props."""
from __future__ import annotations

import math

import bpy
import numpy as np

from model_runtime.skeleton import JOINT_NAMES, PARENTS, rest_joints, standing_pelvis_height

MIXAMO = {
    "pelvis": "Hips", "spine1": "Spine", "spine2": "Spine1", "spine3": "Spine2", "neck": "Neck", "head": "Head",
    "left_hip": "LeftUpLeg", "left_knee": "LeftLeg", "left_ankle": "LeftFoot", "left_foot": "LeftToeBase",
    "left_collar": "LeftShoulder", "left_shoulder": "LeftArm", "left_elbow": "LeftForeArm", "left_wrist": "LeftHand",
}
MIXAMO.update({"right_" + k[5:]: v.replace("Left", "Right") for k, v in list(MIXAMO.items()) if k.startswith("left_")})


def rest_heads() -> np.ndarray:
    h = rest_joints().numpy().astype(np.float64)
    h[:, 2] += standing_pelvis_height()
    return h


def make_armature(name: str, names: dict[str, str] | None = None, prefix: str = "",
                  location=(0.0, 0.0, 0.0), yaw: float = 0.0) -> bpy.types.Object:
    """A 22-bone humanoid at the SMPL-X rest positions; bone names from `names` (SMPL-X joint -> bone)."""
    names = names or {j: j for j in JOINT_NAMES}
    heads = rest_heads()
    arm = bpy.data.armatures.new(name)
    ob = bpy.data.objects.new(name, arm)
    bpy.context.scene.collection.objects.link(ob)
    ob.location = location
    ob.rotation_euler = (0.0, 0.0, yaw)
    bpy.context.view_layer.objects.active = ob
    bpy.ops.object.mode_set(mode='EDIT')
    ebs = []
    for i, j in enumerate(JOINT_NAMES):
        eb = arm.edit_bones.new(prefix + names[j])
        eb.head = heads[i]
        eb.tail = heads[i] + np.array((0.0, 0.05, 0.0))   # odd bone axes on purpose: only heads are read
        ebs.append(eb)
    for i, p in enumerate(PARENTS):
        if p >= 0:
            ebs[i].parent = ebs[p]
    bpy.ops.object.mode_set(mode='OBJECT')
    return ob


def make_tentacle(name: str = "Tentacle") -> bpy.types.Object:
    arm = bpy.data.armatures.new(name)
    ob = bpy.data.objects.new(name, arm)
    bpy.context.scene.collection.objects.link(ob)
    bpy.context.view_layer.objects.active = ob
    bpy.ops.object.mode_set(mode='EDIT')
    prev = None
    for i in range(5):
        eb = arm.edit_bones.new(f"seg{i}")
        eb.head = (0.0, 0.0, 0.2 * i)
        eb.tail = (0.0, 0.0, 0.2 * (i + 1))
        eb.parent = prev
        prev = eb
    bpy.ops.object.mode_set(mode='OBJECT')
    return ob


def keyframe_walk(ob: bpy.types.Object, start, end, f0: int, f1: int) -> None:
    """Object-level walk from `start` to `end` with a knee bend to make the pose move too."""
    ob.location = start
    ob.keyframe_insert("location", frame=f0)
    ob.location = end
    ob.keyframe_insert("location", frame=f1)
    knee = next((pb for pb in ob.pose.bones if pb.name.lower().endswith(("left_knee", "leftleg"))), None)
    if knee is not None:
        knee.rotation_mode = 'XYZ'
        for k, f in enumerate(range(f0, f1 + 1, 6)):
            knee.rotation_euler = (0.6 * (k % 2), 0.0, 0.0)
            knee.keyframe_insert("rotation_euler", frame=f)


def make_box(name: str, location, size=(0.6, 0.6, 0.8), collection: bpy.types.Collection | None = None):
    me = bpy.data.meshes.new(name)
    sx, sy, sz = (s / 2 for s in size)
    v = [(x, y, z) for x in (-sx, sx) for y in (-sy, sy) for z in (0.0, 2 * sz)]
    f = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    me.from_pydata(v, [], f)
    me.update()
    ob = bpy.data.objects.new(name, me)
    (collection or bpy.context.scene.collection).objects.link(ob)
    ob.location = location
    return ob


def demo_scene(context, fps: int = 24, frames=(1, 48)) -> dict:
    """Ego at the origin facing -Y; a Mixamo-named partner walking toward it from -Y; a table; a goal."""
    scene = context.scene
    scene.render.fps = fps
    scene.frame_start, scene.frame_end = frames
    scene.frame_set(frames[0])
    props = bpy.data.collections.new("Props")
    scene.collection.children.link(props)
    make_box("Table", (1.0, -1.0, 0.0), collection=props)
    goal = bpy.data.objects.new("Goal", None)
    scene.collection.objects.link(goal)
    goal.location = (0.0, -2.0, 0.0)
    partner = make_armature("Partner", MIXAMO, prefix="mixamorig:", location=(0.0, -4.0, 0.0), yaw=math.pi)
    keyframe_walk(partner, (0.0, -4.0, 0.0), (0.0, -1.2, 0.0), frames[0], frames[1])
    bpy.ops.remogen.create_ego()
    st = scene.remogen
    st.partner = partner
    st.scene_collection = props
    st.goal = goal
    st.text = "walk to the person and wave"
    scene.frame_set(frames[0])
    return {"scene": scene, "partner": partner, "ego": st.ego, "props": props, "goal": goal}


def action_fcurves(action) -> list:
    """F-curves of an action on 4.2/4.3 (action.fcurves) and 4.4+ (layers > strips > channel bags)."""
    if hasattr(action, "layers"):
        return [fc for layer in action.layers for strip in layer.strips for bag in strip.channelbags
                for fc in bag.fcurves]
    return list(action.fcurves)


def poison_weights(model) -> None:
    """Fill every weight of a loaded model with NaN in place (a damaged model file, as far as output goes)."""
    import torch
    with torch.no_grad():
        for p in model.parameters():
            p.fill_(float("nan"))


def ego_pose(ego) -> np.ndarray:
    """(bones, 7) pose-bone quaternions and locations, to compare before and after."""
    return np.array([tuple(pb.rotation_quaternion) + tuple(pb.location) for pb in ego.pose.bones])
