"""Scene builders for the extension tests: armatures with chosen bone names, a walking partner, props."""
from __future__ import annotations

import math

import bpy
import numpy as np

from model_runtime.skeleton import JOINT_NAMES, PARENTS, rest_joints, standing_pelvis_height

from remogen_blender.demo import MIXAMO_NAMES as MIXAMO


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


def action_curves(action) -> dict:
    """{(data_path, index): (keys, 2) array of (frame, value)} for every F-curve of an action."""
    import numpy as np
    out = {}
    for fc in action_fcurves(action):
        co = np.empty(len(fc.keyframe_points) * 2, dtype=np.float32)
        fc.keyframe_points.foreach_get("co", co)
        out[(fc.data_path, fc.array_index)] = co.reshape(-1, 2)
    return out


def poison_weights(model) -> None:
    """Fill every weight of a loaded model with NaN in place (a damaged model file, as far as output goes)."""
    import torch
    with torch.no_grad():
        for p in model.parameters():
            p.fill_(float("nan"))


def ego_pose(ego) -> np.ndarray:
    """(bones, 7) pose-bone quaternions and locations, to compare before and after."""
    return np.array([tuple(pb.rotation_quaternion) + tuple(pb.location) for pb in ego.pose.bones])


# ---------------------------------------------------------------------------- target rigs (retargeting)

def humanoid_heads(scale: float = 1.0, leg_scale: float = 1.0, a_pose_deg: float = 0.0) -> np.ndarray:
    """(22, 3) SMPL-X-ordered joint positions of a standing humanoid, soles at z = 0: the SMPL-X rest body
    with its legs (hip to toe) `leg_scale` times as long, its arms lowered `a_pose_deg` from the T-pose,
    all scaled by `scale`."""
    from remogen_blender.demo import humanoid_heads as heads
    return heads(scale, leg_scale, a_pose_deg)


def make_target(name: str = "Character", family: str = "mixamo", scale: float = 1.0, leg_scale: float = 1.0,
                a_pose_deg: float = 0.0, centimetres: bool = False, location=(0.0, 0.0, 0.0), yaw: float = 0.0,
                rolls: int | None = 0, unmapped: tuple[str, ...] = ()) -> bpy.types.Object:
    """A user's humanoid rig as an importer leaves it: bones aimed at their child joints, random rolls
    (seed `rolls`; None: roll 0), named the Mixamo way ("mixamorig:Hips") or Rigify's deform bones
    ("DEF-spine", with Rigify's unmapped "root" parent and "DEF-spine.005" between neck and head).

    centimetres: an FBX import without "Apply Transform": bones in Y-up centimetres, the object turned 90
    degrees about X and scaled 0.01. `unmapped` joints get bones no bone map knows (a rig missing them).
    """
    from model_runtime.data.bone_maps import BONE_MAPS
    from remogen_blender.rig.ego import LEAF_TAIL, TAIL_CHILD
    heads = humanoid_heads(scale, leg_scale, a_pose_deg)
    if family == "mixamo":
        names = {j: "mixamorig:" + MIXAMO[j] for j in JOINT_NAMES}
    elif family == "rigify":
        names = dict(BONE_MAPS["rigify"])
    else:
        raise ValueError(family)
    for k, j in enumerate(unmapped):
        names[j] = f"Extra{k}"
    rng = np.random.default_rng(rolls) if rolls is not None else None
    if centimetres:
        def to_data(p):                              # world metres -> Y-up centimetres under the object
            p = np.asarray(p, dtype=np.float64)
            return np.array((p[0], p[2], -p[1])) * 100.0
    else:
        def to_data(p):
            return np.asarray(p, dtype=np.float64)
    arm = bpy.data.armatures.new(name)
    ob = bpy.data.objects.new(name, arm)
    bpy.context.scene.collection.objects.link(ob)
    ob.location = location
    if centimetres:
        ob.rotation_euler = (math.pi / 2, 0.0, yaw)
        ob.scale = (0.01, 0.01, 0.01)
    else:
        ob.rotation_euler = (0.0, 0.0, yaw)
    bpy.context.view_layer.objects.active = ob
    bpy.ops.object.mode_set(mode='EDIT')
    index = {j: i for i, j in enumerate(JOINT_NAMES)}

    def bone(bname, head, tail, parent=None):
        eb = arm.edit_bones.new(bname)
        eb.head, eb.tail = to_data(head), to_data(tail)
        eb.roll = float(rng.uniform(-math.pi, math.pi)) if rng is not None else 0.0
        eb.parent = parent
        return eb

    ebs = {}
    for i, j in enumerate(JOINT_NAMES):
        child = TAIL_CHILD.get(j)
        if child is not None:
            tail = heads[index[child]]
        elif j.endswith("wrist"):                    # along the forearm, as hands are
            forearm = heads[i] - heads[PARENTS[i]]
            tail = heads[i] + 0.08 * scale * forearm / np.linalg.norm(forearm)
        else:
            tail = heads[i] + np.array(LEAF_TAIL[j]) * scale
        ebs[j] = bone(names[j], heads[i], tail)
    for i, j in enumerate(JOINT_NAMES):
        if PARENTS[i] >= 0:
            ebs[j].parent = ebs[JOINT_NAMES[PARENTS[i]]]
    if family == "rigify":
        ebs["pelvis"].parent = bone("root", (0.0, 0.0, 0.0), (0.0, 0.3 * scale, 0.0))
        neck, head = heads[index["neck"]], heads[index["head"]]
        mid = 0.5 * (neck + head)
        ebs["neck"].tail = to_data(mid)
        ebs["head"].parent = bone("DEF-spine.005", mid, head, ebs["neck"])
    bpy.ops.object.mode_set(mode='OBJECT')
    return ob


def target_scene(context, target: bpy.types.Object, mode: str = 'BOTH', fps: int = 30, frames=(1, 91)) -> dict:
    """The demo scene (a partner walking up to the ego) with `target` set as the target rig."""
    d = demo_scene(context, fps=fps, frames=frames)
    st = context.scene.remogen
    st.target = target
    st.target_mode = mode
    if mode == 'TARGET':
        ego = d.pop("ego")
        st.ego = None
        for ob in [ego, *ego.children]:
            bpy.data.objects.remove(ob)
    d["target"] = target
    return d
