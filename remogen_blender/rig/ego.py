"""Creating the SMPL-X ego: an armature with quaternion pose bones at the SMPL-X rest joints, and its body."""
from __future__ import annotations

from typing import Any

import bpy
import numpy as np

from .._runtime import api
from .body import EGO_MARK, link_body, proxy_body, smplx_body

_RT = api()   # the runtime's public package; these parts of it need no PyTorch

# Which joint each bone points at (tail); leaf bones get a fixed direction instead. A retargeted rig's
# bones are aimed along the same joint-to-joint directions (rig/target.py).
TAIL_CHILD = {
    "pelvis": "spine1", "spine1": "spine2", "spine2": "spine3", "spine3": "neck", "neck": "head",
    "left_hip": "left_knee", "right_hip": "right_knee", "left_knee": "left_ankle", "right_knee": "right_ankle",
    "left_ankle": "left_foot", "right_ankle": "right_foot", "left_collar": "left_shoulder",
    "right_collar": "right_shoulder", "left_shoulder": "left_elbow", "right_shoulder": "right_elbow",
    "left_elbow": "left_wrist", "right_elbow": "right_wrist",
}
LEAF_TAIL = {"head": (0.0, 0.0, 0.18), "left_foot": (0.0, -0.07, 0.0), "right_foot": (0.0, -0.07, 0.0),
              "left_wrist": (0.09, 0.0, 0.0), "right_wrist": (-0.09, 0.0, 0.0)}


def ego_rest_heads() -> tuple[list[str], list[int], np.ndarray]:
    """(joint names, parents, (22, 3) rest heads with the pelvis above the origin and soles at z = 0)."""
    heads = _RT.rest_joints_np()
    heads[:, 2] += _RT.standing_pelvis_height()
    return list(_RT.JOINT_NAMES), list(_RT.PARENTS), heads


def create_ego(context: bpy.types.Context, name: str = "SMPLX_Ego", location: Any = (0.0, 0.0, 0.0),
               yaw: float = 0.0, smplx_folder: str = "") -> bpy.types.Object:
    """An SMPL-X body armature (quaternion pose bones) with a skinned body, linked to the active collection."""
    names, _parents, heads = ego_rest_heads()
    body_data = smplx_body(smplx_folder, heads) if smplx_folder else None   # fail before touching the file
    ob = build_armature(context, name, heads, location=location, yaw=yaw)
    ob[EGO_MARK] = 1
    if body_data is not None:
        link_body(ob, name + "_Body", *body_data)
    else:
        link_body(ob, name + "_Body", *proxy_body(names, ob))
    return ob


def build_armature(context: bpy.types.Context, name: str, heads: np.ndarray, bone_names: list[str] | None = None,
                   location: Any = (0.0, 0.0, 0.0), yaw: float = 0.0) -> bpy.types.Object:
    """A 22-bone armature with the SMPL-X hierarchy, its bones' heads at `heads` (22, 3) and named
    `bone_names` (default: the SMPL-X joint names), made the active object of the active collection."""
    names = list(_RT.JOINT_NAMES)
    bone_names = bone_names or names
    if context.mode != 'OBJECT' and context.active_object is not None:
        bpy.ops.object.mode_set(mode='OBJECT')
    arm = bpy.data.armatures.new(name)
    ob = bpy.data.objects.new(name, arm)
    collection = context.collection or context.scene.collection
    collection.objects.link(ob)
    ob.location = tuple(float(v) for v in location)
    ob.rotation_euler = (0.0, 0.0, float(yaw))
    view_layer = context.view_layer
    for other in context.selected_objects:
        other.select_set(False)
    view_layer.objects.active = ob
    ob.select_set(True)
    bpy.ops.object.mode_set(mode='EDIT')
    try:
        index = {n: i for i, n in enumerate(names)}
        ebones = []
        for i, n in enumerate(names):
            eb = arm.edit_bones.new(bone_names[i])
            eb.head = heads[i]
            child = TAIL_CHILD.get(n)
            tail = heads[index[child]] if child else heads[i] + np.array(LEAF_TAIL[n])
            if np.linalg.norm(tail - heads[i]) < 0.02:   # keep bones a visible, valid length
                tail = heads[i] + np.array((0.0, 0.0, 0.05))
            eb.tail = tail
            eb.roll = 0.0
            ebones.append(eb)
        for i, p in enumerate(_RT.PARENTS):
            if p >= 0:
                ebones[i].parent = ebones[p]
                ebones[i].use_connect = False
    finally:
        bpy.ops.object.mode_set(mode='OBJECT')
    for pb in ob.pose.bones:
        pb.rotation_mode = 'QUATERNION'
    arm.display_type = 'STICK'
    return ob
