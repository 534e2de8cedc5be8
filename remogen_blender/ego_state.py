"""What Live and the bake borrow from the ego (and the target rig) and give back: its pose and its own action.

Live poses the ego directly, so the ego's action must be taken off it while Live runs (it would
overwrite the pose on every frame). `HeldAction` keeps that action safe meanwhile (a fake user, so no
save or autosave can drop it) and puts it back, slot and fake-user flag as they were, for a save and
when Live ends.
"""
from __future__ import annotations

from dataclasses import dataclass

import bpy
import numpy as np


@dataclass
class PoseSnapshot:
    """The pose bones' rotations (in every rotation mode) and locations, flat, in pose-bone order."""
    rotations: np.ndarray
    locations: np.ndarray
    eulers: np.ndarray
    axis_angles: np.ndarray

    _CHANNELS = (("rotations", "rotation_quaternion", 4), ("locations", "location", 3),
                 ("eulers", "rotation_euler", 3), ("axis_angles", "rotation_axis_angle", 4))

    @classmethod
    def take(cls, ob: bpy.types.Object) -> "PoseSnapshot":
        n = len(ob.pose.bones)
        values = {}
        for field_name, prop, size in cls._CHANNELS:
            values[field_name] = np.empty(n * size, dtype=np.float32)
            ob.pose.bones.foreach_get(prop, values[field_name])
        return cls(**values)

    def restore(self, ob: bpy.types.Object) -> None:
        """Put the pose back; nothing happens when the object was deleted meanwhile."""
        try:
            for field_name, prop, _size in self._CHANNELS:
                ob.pose.bones.foreach_set(prop, getattr(self, field_name))
            ob.update_tag()
        except ReferenceError:
            pass


class HeldAction:
    """The action an object had, taken off it and kept safe until it is put back."""

    def __init__(self, ob: bpy.types.Object) -> None:
        ad = ob.animation_data
        act = ad.action if ad is not None else None
        self.action: bpy.types.Action | None = act
        self.action_name = act.name if act is not None else ""
        slot = getattr(ad, "action_slot", None) if act is not None else None   # 4.4+
        self.slot_identifier = slot.identifier if slot is not None else ""
        self.had_fake_user = bool(act.use_fake_user) if act is not None else False

    def _action(self) -> bpy.types.Action | None:
        if self.action is None:
            return None
        try:
            self.action.name   # noqa: B018 - raises ReferenceError when undo replaced the datablock
            return self.action
        except ReferenceError:
            self.action = bpy.data.actions.get(self.action_name)
            return self.action

    def take_off(self, ob: bpy.types.Object) -> None:
        """Unassign the action; a fake user keeps it in every save meanwhile."""
        act = self._action()
        if act is None:
            return
        act.use_fake_user = True
        ad = ob.animation_data
        if ad is not None and ad.action == act:
            ad.action = None

    def put_back(self, ob: bpy.types.Object | None) -> None:
        """Assign the action (and its slot) again with its own fake-user flag.

        With the object gone, or another action assigned to it meanwhile, the fake user stays: the action
        must not vanish with the next save.
        """
        act = self._action()
        if act is None:
            return
        try:
            ad = ob.animation_data or ob.animation_data_create()
            if ad.action is not None and ad.action != act:
                return      # the user assigned another action meanwhile: keep it, and keep ours safe too
            ad.action = act
        except (ReferenceError, AttributeError):
            return
        if self.slot_identifier and hasattr(ad, "action_slot"):
            slot = next((s for s in act.slots if s.identifier == self.slot_identifier), None)
            if slot is not None:
                ad.action_slot = slot
        act.use_fake_user = self.had_fake_user
