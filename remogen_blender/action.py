"""Writing keyframes into a NEW action, on Blender 4.2/4.3 (action.fcurves) and 4.4+ (slots, layers,
channel bags; 5.0 removed action.fcurves). Keys go in with `foreach_set`, one call per channel."""
from __future__ import annotations

from typing import Any

import bpy
import numpy as np


def _linear() -> int:
    return bpy.types.Keyframe.bl_rna.properties["interpolation"].enum_items["LINEAR"].value


def new_action(ob: bpy.types.Object, name: str) -> tuple[bpy.types.Action, Any, Any, str | None]:
    """A new action assigned to `ob`: (action, fcurves, groups, name of the action it replaced or None).

    The replaced action is never deleted or edited; if `ob` was its only user it gets a fake user so
    that saving the file does not drop it.
    """
    ad = ob.animation_data or ob.animation_data_create()
    old = ad.action
    if old is not None and old.users <= 1 and not old.use_fake_user:
        old.use_fake_user = True
    act = bpy.data.actions.new(name)
    if hasattr(act, "slots"):        # 4.4+
        slot = act.slots.new(id_type='OBJECT', name=ob.name)
        strip = act.layers.new("Layer").strips.new(type='KEYFRAME')
        bag = strip.channelbag(slot, ensure=True)
        ad.action = act
        ad.action_slot = slot
        return act, bag.fcurves, bag.groups, (old.name if old else None)
    ad.action = act
    return act, act.fcurves, act.groups, (old.name if old else None)


def write_channel(fcurves: Any, group: Any, data_path: str, index: int, frames: np.ndarray,
                  values: np.ndarray) -> Any:
    fc = fcurves.new(data_path, index=index)
    fc.group = group
    n = len(frames)
    fc.keyframe_points.add(n)
    co = np.empty(2 * n, dtype=np.float32)
    co[0::2] = frames
    co[1::2] = values
    fc.keyframe_points.foreach_set("co", co)
    fc.keyframe_points.foreach_set("interpolation", np.full(n, _linear(), dtype=np.int32))
    fc.update()
    return fc


def pose_channels(bone_names: list[str], locations: np.ndarray, rotations: np.ndarray, root: str
                  ) -> list[tuple[str, str, np.ndarray]]:
    """(bone, property, (T, n) values): rotation_quaternion of each bone, location of the root bone.

    locations: (T, B, 3); rotations: (T, B, 4), bones in `bone_names` order.
    """
    out = []
    for b, bone in enumerate(bone_names):
        if bone == root:
            out.append((bone, "location", locations[:, b]))
        out.append((bone, "rotation_quaternion", rotations[:, b]))
    return out


def write_bone_keys(ob: bpy.types.Object, name: str, frames: np.ndarray,
                    channels: list[tuple[str, str, np.ndarray]]) -> tuple[bpy.types.Action, str | None]:
    """Keys for every frame into a new action on `ob`: channels are (bone, pose-bone property, (T, n)
    values), grouped by bone. Returns (the action, the name of the action it replaced or None)."""
    act, fcurves, groups, replaced = new_action(ob, name)
    made = {}
    for bone, prop, values in channels:
        if bone not in made:
            made[bone] = groups.new(bone)
        g = made[bone]
        path = ob.pose.bones[bone].path_from_id(prop)
        for i in range(values.shape[1]):
            write_channel(fcurves, g, path, i, frames, values[:, i])
    return act, replaced


def write_pose_keys(ob: bpy.types.Object, name: str, frames: np.ndarray, bone_names: list[str],
                    locations: np.ndarray, rotations: np.ndarray, root: str
                    ) -> tuple[bpy.types.Action, str | None]:
    """Keys for every frame: rotation_quaternion of each bone, location of the root bone.

    frames: (T,); locations: (T, B, 3); rotations: (T, B, 4), bones in `bone_names` order.
    """
    return write_bone_keys(ob, name, frames, pose_channels(bone_names, locations, rotations, root))
