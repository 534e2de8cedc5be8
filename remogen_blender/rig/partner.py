"""The partner: checking that it is an armature, and reading its 22 SMPL-X joints through a bone map."""
from __future__ import annotations

import bpy
import numpy as np

from .._runtime import UserError, api

_RT = api()   # the runtime's public package; these parts of it need no PyTorch


def check_armature(ob: bpy.types.Object | None, what: str = "Partner") -> bpy.types.Object:
    """`ob` when it is an armature; else a one-line UserError that says what to pick instead."""
    if ob is None:
        raise UserError(f"Pick a {what.lower()} armature in the ReMoGen panel")
    if ob.type != 'ARMATURE':
        article = "an" if ob.type[:1] in "AEIOU" else "a"
        raise UserError(f"{what} '{ob.name}' is {article} {ob.type}, not an armature: pick the "
                        f"{what.lower()}'s armature")
    return ob


def check_partner(ob: bpy.types.Object | None) -> bpy.types.Object:
    return check_armature(ob, "Partner")


class PartnerReader:
    """World positions of the 22 SMPL-X joints on a partner armature, via its bone map."""

    def __init__(self, ob: bpy.types.Object, mapping: dict[str, str]) -> None:
        check_partner(ob)
        names = [pb.name for pb in ob.pose.bones]
        _RT.validate_bone_map(mapping, names, rig=f"Partner '{ob.name}'")
        by_norm = {_RT.normalise_name(n): i for i, n in enumerate(names)}
        n = len(names)
        # Rows index a stacked (heads; tails) array of 2n points: joint = (1 - t) * P[a] + t * P[b].
        a = np.zeros(_RT.NUM_JOINTS, dtype=np.intp)
        b = np.zeros(_RT.NUM_JOINTS, dtype=np.intp)
        t = np.zeros(_RT.NUM_JOINTS, dtype=np.float32)
        for j, joint in enumerate(_RT.JOINT_NAMES):
            spec = mapping[joint]
            if spec.startswith("lerp:"):
                _, b0, b1, frac = spec.split(":")
                a[j], b[j] = by_norm[_RT.normalise_name(b0)], by_norm[_RT.normalise_name(b1)]
                try:
                    t[j] = float(frac)
                except ValueError:
                    raise UserError(f"Bone map entry for {joint} has a bad fraction {frac!r}; "
                                    "write it as lerp:BoneA:BoneB:0.5") from None
            elif spec.startswith("end:"):
                a[j] = b[j] = n + by_norm[_RT.normalise_name(spec[4:])]
            else:
                a[j] = b[j] = by_norm[_RT.normalise_name(spec)]
        self.name = ob.name
        self._ob = ob
        self._n = n
        self._a, self._b, self._t = a, b, t[:, None]
        self._buf = np.empty(2 * n * 3, dtype=np.float32)

    @property
    def object(self) -> bpy.types.Object:
        return self._ob

    def read(self, depsgraph: bpy.types.Depsgraph | None = None) -> np.ndarray:
        """(22, 3) float32 world joints of the evaluated pose. Raises UserError if the partner is gone."""
        try:
            ob = self._ob.evaluated_get(depsgraph) if depsgraph is not None else self._ob
            bones = ob.pose.bones
            n = self._n
            if len(bones) != n:
                raise UserError(f"Partner '{self.name}' changed its bones; restart to rebuild its bone map")
            bones.foreach_get("head", self._buf[:3 * n])
            bones.foreach_get("tail", self._buf[3 * n:])
            mw = np.array(ob.matrix_world, dtype=np.float32)
        except ReferenceError:
            raise UserError(f"Partner '{self.name}' was deleted") from None
        p = self._buf.reshape(2 * n, 3)
        local = p[self._a] * (1.0 - self._t) + p[self._b] * self._t
        return local @ mw[:3, :3].T + mw[:3, 3]
