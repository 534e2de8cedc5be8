"""The partner's bone map: guessed from its bone names and stored in the scene settings (editable there)."""
from __future__ import annotations

from typing import Any

import bpy

from .._runtime import UserError, api
from .partner import check_partner

_RT = api()   # the runtime's public package; these parts of it need no PyTorch


def bone_map_dict(settings: Any) -> dict[str, str]:
    return {item.joint: item.bone for item in settings.bone_map if item.bone}


def fill_bone_map(settings: Any, partner: bpy.types.Object, quiet: bool = False) -> list[str]:
    """Guess the partner's bone map and store it in `settings`; returns the SMPL-X joints left unmapped.

    A partner that is no armature raises a UserError, or with `quiet` (property callbacks, which must not
    raise) leaves the stored map as it is and returns every joint as unmapped.
    """
    try:
        check_partner(partner)
    except UserError:
        if quiet:
            return list(_RT.JOINT_NAMES)
        raise
    guess = _RT.guess_bone_map([b.name for b in partner.data.bones])
    settings.bone_map.clear()
    for joint in _RT.JOINT_NAMES:
        item = settings.bone_map.add()
        item.joint = joint
        item.bone = guess.mapping.get(joint, "")
    settings.bone_map_family = guess.family if len(guess.missing) < len(_RT.JOINT_NAMES) else ""
    settings.bone_map_rig = partner.name
    return list(guess.missing)
