"""Writing model poses (world pelvis + SMPL-X local quaternions) onto the ego armature's pose bones."""
from __future__ import annotations

import bpy
import numpy as np

from .._runtime import UserError, api

_RT = api()   # the runtime's public package; these parts of it need no PyTorch


class EgoWriter:
    """Writes model poses (world pelvis + SMPL-X local quaternions) onto an ego armature's pose bones.

    Blender's pose rotation of a bone is relative to its rest orientation R (bone.matrix_local), so the
    model's local rotation L becomes R^-1 L R; the root also moves into the armature object's space.
    """

    def __init__(self, ob: bpy.types.Object) -> None:
        if ob is None or ob.type != 'ARMATURE':
            raise UserError("No ego armature: press 'Create Ego' in the ReMoGen panel")
        bones = ob.pose.bones
        order = {pb.name: i for i, pb in enumerate(bones)}
        missing = [n for n in _RT.JOINT_NAMES if n not in order]
        if missing:
            raise UserError(f"Ego '{ob.name}' is not an SMPL-X armature (no bones {', '.join(missing[:4])}"
                            f"{' ...' if len(missing) > 4 else ''}); press 'Create Ego'")
        self.name = ob.name
        self._ob = ob
        self._n = len(bones)
        self._idx = np.array([order[n] for n in _RT.JOINT_NAMES], dtype=np.intp)
        rest = [ob.data.bones[n].matrix_local for n in _RT.JOINT_NAMES]
        self._q_rest = _RT.matrix_to_quat_np(np.array([np.array(m)[:3, :3] for m in rest]))
        self._q_rest_inv = _RT.qconj(self._q_rest)
        self._r0_t = np.array(rest[0])[:3, :3].T
        self._h0 = np.array(rest[0])[:3, 3]
        self._non_quat = [pb.name for pb in bones if pb.rotation_mode != 'QUATERNION']
        self._rot = np.zeros((self._n, 4), dtype=np.float32)
        self._rot[:, 0] = 1.0
        self._loc = np.zeros((self._n, 3), dtype=np.float32)
        self._inv_key: bytes | None = None
        self._inv = np.eye(4)
        self._q_obj_inv = np.array((1.0, 0.0, 0.0, 0.0))

    @property
    def object(self) -> bpy.types.Object:
        return self._ob

    def pose_channels(self, pelvis_world: np.ndarray, local_rotations: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray]:
        """Blender channels for world poses: ((..., 22, 3) locations, (..., 22, 4) quaternions), SMPL-X order.

        pelvis_world (..., 3), local_rotations (..., 22, 4): one pose or a batch of them.
        """
        inv, q_obj_inv = self._object_inverse()
        q = np.array(local_rotations, dtype=np.float64)
        # Global orientation in the armature's space: W^-1 G.
        q[..., 0, :] = _RT.qmul(q_obj_inv, q[..., 0, :])
        rot = _RT.qmul(_RT.qmul(self._q_rest_inv, q), self._q_rest)
        p_arm = np.asarray(pelvis_world, dtype=np.float64) @ inv[:3, :3].T + inv[:3, 3]
        loc = np.zeros(q.shape[:-1] + (3,))
        loc[..., 0, :] = (p_arm - self._h0) @ self._r0_t.T
        return loc, rot

    def _object_inverse(self) -> tuple[np.ndarray, np.ndarray]:
        """(W^-1, conjugate quaternion of W's rotation), recomputed only when the object moved.

        Cached because a LAPACK call per frame cost ~1 ms under load (thread start-up), more than the rest.
        """
        mw = np.array(self._ob.matrix_world, dtype=np.float64)
        key = mw.tobytes()
        if key != self._inv_key:
            self._inv = np.linalg.inv(mw)
            self._q_obj_inv = _RT.qconj(_RT.matrix_to_quat_np(_RT.rigid_rotation(mw)))
            self._inv_key = key
        return self._inv, self._q_obj_inv

    def write_channels(self, loc: np.ndarray, rot: np.ndarray) -> None:
        try:
            bones = self._ob.pose.bones
            if self._non_quat:
                for name in self._non_quat:
                    bones[name].rotation_mode = 'QUATERNION'
                self._non_quat = []
            self._rot[self._idx] = rot
            self._loc[self._idx] = loc
            bones.foreach_set("rotation_quaternion", self._rot.ravel())
            bones.foreach_set("location", self._loc.ravel())
            self._ob.update_tag()   # foreach_set does not tag the object; without this the pose stays stale
        except ReferenceError:
            raise UserError(f"Ego '{self.name}' was deleted") from None

    def write(self, pelvis_world: np.ndarray, local_rotations: np.ndarray) -> None:
        self.write_channels(*self.pose_channels(pelvis_world, local_rotations))

    def write_rest(self) -> None:
        """Back to the rest pose (identity rotations, no offsets)."""
        try:
            self._rot[:] = (1.0, 0.0, 0.0, 0.0)
            self._loc[:] = 0.0
            bones = self._ob.pose.bones
            bones.foreach_set("rotation_quaternion", self._rot.ravel())
            bones.foreach_set("location", self._loc.ravel())
            self._ob.update_tag()
        except ReferenceError:
            pass

    def start_pose(self) -> tuple[tuple[float, float, float], float]:
        """(floor point under the rest pelvis, yaw) of the ego object in the world: where a session starts."""
        mw = np.array(self._ob.matrix_world, dtype=np.float64)
        p = mw[:3, :3] @ self._h0 + mw[:3, 3]
        r = _RT.rigid_rotation(mw)
        # yaw 0 faces -Y; the object's -Y axis projected on the floor gives its facing
        fwd = -r[:, 1]
        yaw = float(np.arctan2(fwd[0], -fwd[1])) if np.hypot(fwd[0], fwd[1]) > 1e-6 else 0.0
        return (float(p[0]), float(p[1]), float(mw[2, 3])), yaw

    def world_heads(self, depsgraph: bpy.types.Depsgraph | None = None) -> np.ndarray:
        """(22, 3) evaluated world bone heads in SMPL-X order (tests and checks)."""
        ob = self._ob.evaluated_get(depsgraph) if depsgraph is not None else self._ob
        buf = np.empty(self._n * 3, dtype=np.float32)
        ob.pose.bones.foreach_get("head", buf)
        mw = np.array(ob.matrix_world, dtype=np.float32)
        p = buf.reshape(self._n, 3)[self._idx]
        return p @ mw[:3, :3].T + mw[:3, 3]
