"""Bone maps of the partner and of the target rig: guessed from bone names and stored in the scene settings
(editable there). Both use the runtime's maps (SMPL-X, Mixamo, Rigify, CC, DAZ, BVH/CMU, Bandai, UE)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import bpy

from .._runtime import UserError, api
from .partner import check_armature

_RT = api()   # the runtime's public package; these parts of it need no PyTorch


@dataclass(frozen=True)
class MapSlot:
    """Where one rig's bone map lives in the settings: the rows, the family found, the rig it was made for."""
    rows: str
    family: str
    rig: str
    what: str      # how messages name the rig


PARTNER = MapSlot("bone_map", "bone_map_family", "bone_map_rig", "Partner")
TARGET = MapSlot("target_bone_map", "target_bone_map_family", "target_bone_map_rig", "Target")


def bone_map_dict(settings: Any, slot: MapSlot = PARTNER) -> dict[str, str]:
    return {item.joint: item.bone for item in getattr(settings, slot.rows) if item.bone}


def fill_bone_map(settings: Any, rig: bpy.types.Object, quiet: bool = False, slot: MapSlot = PARTNER) -> list[str]:
    """Guess the rig's bone map and store it in `settings`; returns the SMPL-X joints left unmapped.

    A rig that is no armature raises a UserError, or with `quiet` (property callbacks, which must not
    raise) leaves the stored map as it is and returns every joint as unmapped.
    """
    try:
        check_armature(rig, slot.what)
    except UserError:
        if quiet:
            return list(_RT.JOINT_NAMES)
        raise
    guess = _RT.guess_bone_map([b.name for b in rig.data.bones])
    rows = getattr(settings, slot.rows)
    rows.clear()
    for joint in _RT.JOINT_NAMES:
        item = rows.add()
        item.joint = joint
        item.bone = guess.mapping.get(joint, "")
    setattr(settings, slot.family, guess.family if len(guess.missing) < len(_RT.JOINT_NAMES) else "")
    setattr(settings, slot.rig, rig.name)
    return list(guess.missing)


def ensure_bone_map(settings: Any, rig: bpy.types.Object, slot: MapSlot = PARTNER) -> dict[str, str]:
    """The stored map when it was made for `rig`, else a freshly guessed one."""
    if getattr(settings, slot.rig) != rig.name or len(getattr(settings, slot.rows)) == 0:
        fill_bone_map(settings, rig, slot=slot)
    return bone_map_dict(settings, slot)
