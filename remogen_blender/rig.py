"""Rigs: the partner's bone map and joint reading, creating the SMPL-X ego, and writing its pose.

Pose-bone arrays are in Blender's depth-first hierarchy order, not SMPL-X order: every reader/writer
builds its index permutation once and reuses it per frame with `foreach_get` / `foreach_set`.
"""
from __future__ import annotations

from typing import Any

import bpy
import numpy as np

from ._runtime import UserError, api

_RT = api()   # the runtime's public package; these parts of it need no PyTorch

EGO_MARK = "remogen_ego"   # custom property set on armatures made by Create Ego


# ---------------------------------------------------------------------------- bone map

def bone_map_dict(settings: Any) -> dict[str, str]:
    return {item.joint: item.bone for item in settings.bone_map if item.bone}


def fill_bone_map(settings: Any, partner: bpy.types.Object, quiet: bool = False) -> list[str]:
    """Guess the partner's bone map and store it in `settings`; returns the SMPL-X joints left unmapped."""
    try:
        bm = sk = _RT
    except UserError:
        if quiet:
            return []
        raise
    guess = bm.guess_bone_map([b.name for b in partner.data.bones])
    settings.bone_map.clear()
    for joint in sk.JOINT_NAMES:
        item = settings.bone_map.add()
        item.joint = joint
        item.bone = guess.mapping.get(joint, "")
    settings.bone_map_family = guess.family if len(guess.missing) < len(sk.JOINT_NAMES) else ""
    settings.bone_map_rig = partner.name
    return list(guess.missing)


class PartnerReader:
    """World positions of the 22 SMPL-X joints on a partner armature, via its bone map."""

    def __init__(self, ob: bpy.types.Object, mapping: dict[str, str]) -> None:
        if ob is None or ob.type != 'ARMATURE':
            raise UserError("Pick a partner armature in the ReMoGen panel")
        bm = sk = _RT
        names = [pb.name for pb in ob.pose.bones]
        bm.validate_bone_map(mapping, names, rig=f"Partner '{ob.name}'")
        by_norm = {bm.normalise_name(n): i for i, n in enumerate(names)}
        n = len(names)
        # Rows index a stacked (heads; tails) array of 2n points: joint = (1 - t) * P[a] + t * P[b].
        a = np.zeros(sk.NUM_JOINTS, dtype=np.intp)
        b = np.zeros(sk.NUM_JOINTS, dtype=np.intp)
        t = np.zeros(sk.NUM_JOINTS, dtype=np.float32)
        for j, joint in enumerate(sk.JOINT_NAMES):
            spec = mapping[joint]
            if spec.startswith("lerp:"):
                _, b0, b1, frac = spec.split(":")
                a[j], b[j] = by_norm[bm.normalise_name(b0)], by_norm[bm.normalise_name(b1)]
                try:
                    t[j] = float(frac)
                except ValueError:
                    raise UserError(f"Bone map entry for {joint} has a bad fraction {frac!r}; "
                                    "write it as lerp:BoneA:BoneB:0.5") from None
            elif spec.startswith("end:"):
                a[j] = b[j] = n + by_norm[bm.normalise_name(spec[4:])]
            else:
                a[j] = b[j] = by_norm[bm.normalise_name(spec)]
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


# ---------------------------------------------------------------------------- ego creation

# Which joint each bone points at (tail); leaf bones get a fixed direction instead.
_TAIL_CHILD = {
    "pelvis": "spine1", "spine1": "spine2", "spine2": "spine3", "spine3": "neck", "neck": "head",
    "left_hip": "left_knee", "right_hip": "right_knee", "left_knee": "left_ankle", "right_knee": "right_ankle",
    "left_ankle": "left_foot", "right_ankle": "right_foot", "left_collar": "left_shoulder",
    "right_collar": "right_shoulder", "left_shoulder": "left_elbow", "right_shoulder": "right_elbow",
    "left_elbow": "left_wrist", "right_elbow": "right_wrist",
}
_LEAF_TAIL = {"head": (0.0, 0.0, 0.18), "left_foot": (0.0, -0.07, 0.0), "right_foot": (0.0, -0.07, 0.0),
              "left_wrist": (0.09, 0.0, 0.0), "right_wrist": (-0.09, 0.0, 0.0)}
# Proxy body: capsule radius per bone (metres).
_RADIUS = {
    "pelvis": 0.13, "spine1": 0.13, "spine2": 0.13, "spine3": 0.14, "neck": 0.05, "head": 0.095,
    "left_hip": 0.075, "left_knee": 0.055, "left_ankle": 0.04, "left_foot": 0.035, "left_collar": 0.05,
    "left_shoulder": 0.045, "left_elbow": 0.038, "left_wrist": 0.035,
}


def ego_rest_heads() -> tuple[list[str], list[int], np.ndarray]:
    """(joint names, parents, (22, 3) rest heads with the pelvis above the origin and soles at z = 0)."""
    sk = _RT
    heads = sk.rest_joints_np()
    heads[:, 2] += sk.standing_pelvis_height()
    return list(sk.JOINT_NAMES), list(sk.PARENTS), heads


def create_ego(context: bpy.types.Context, name: str = "SMPLX_Ego", location: Any = (0.0, 0.0, 0.0),
               yaw: float = 0.0, smplx_folder: str = "") -> bpy.types.Object:
    """An SMPL-X body armature (quaternion pose bones) with a skinned body, linked to the active collection."""
    names, parents, heads = ego_rest_heads()
    body_data = _smplx_body(smplx_folder, heads) if smplx_folder else None   # fail before touching the file
    if context.mode != 'OBJECT' and context.active_object is not None:
        bpy.ops.object.mode_set(mode='OBJECT')
    arm = bpy.data.armatures.new(name)
    ob = bpy.data.objects.new(name, arm)
    collection = context.collection or context.scene.collection
    collection.objects.link(ob)
    ob.location = tuple(float(v) for v in location)
    ob.rotation_euler = (0.0, 0.0, float(yaw))
    ob[EGO_MARK] = 1
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
            eb = arm.edit_bones.new(n)
            eb.head = heads[i]
            child = _TAIL_CHILD.get(n)
            tail = heads[index[child]] if child else heads[i] + np.array(_LEAF_TAIL[n])
            if np.linalg.norm(tail - heads[i]) < 0.02:   # keep bones a visible, valid length
                tail = heads[i] + np.array((0.0, 0.0, 0.05))
            eb.tail = tail
            eb.roll = 0.0
            ebones.append(eb)
        for i, p in enumerate(parents):
            if p >= 0:
                ebones[i].parent = ebones[p]
                ebones[i].use_connect = False
    finally:
        bpy.ops.object.mode_set(mode='OBJECT')
    for pb in ob.pose.bones:
        pb.rotation_mode = 'QUATERNION'
    arm.display_type = 'STICK'
    if body_data is not None:
        _link_body(context, ob, name + "_Body", *body_data)
    else:
        _link_body(context, ob, name + "_Body", *_proxy_body(names, heads, ob))
    return ob


def _proxy_body(names: list[str], heads: np.ndarray, ob: bpy.types.Object
                ) -> tuple[np.ndarray, np.ndarray, dict[str, tuple[np.ndarray, np.ndarray]]]:
    """Capsule-like prisms along every bone, each rigidly weighted to its bone."""
    sides = 8
    ang = np.linspace(0.0, 2.0 * np.pi, sides, endpoint=False)
    verts, faces, groups = [], [], {}
    for n in names:
        bone = ob.data.bones[n]
        h, t = np.array(bone.head_local), np.array(bone.tail_local)
        r = _RADIUS.get(n, _RADIUS.get("left_" + n[6:], 0.05) if n.startswith("right_") else 0.05)
        axis = t - h
        length = float(np.linalg.norm(axis))
        axis = axis / length
        ref = np.array((1.0, 0.0, 0.0)) if abs(axis[0]) < 0.9 else np.array((0.0, 1.0, 0.0))
        u = np.cross(axis, ref)
        u /= np.linalg.norm(u)
        v = np.cross(axis, u)
        ring = np.cos(ang)[:, None] * u + np.sin(ang)[:, None] * v
        # rings slightly beyond the joints so neighbouring parts overlap at the joints
        p0, p1 = h - axis * r * 0.5, t + axis * r * 0.5
        start = sum(len(x) for x in verts)
        block = np.concatenate((p0 + r * ring, p1 + r * ring, p0[None], p1[None]))
        verts.append(block)
        c0, c1 = start + 2 * sides, start + 2 * sides + 1
        for k in range(sides):
            k2 = (k + 1) % sides
            faces.append((start + k, start + k2, start + sides + k2, start + sides + k))
            faces.append((c0, start + k2, start + k))
            faces.append((c1, start + sides + k, start + sides + k2))
        idx = np.arange(start, start + len(block))
        groups[n] = (idx, np.ones(len(idx)))
    return np.concatenate(verts), np.array(faces, dtype=object), groups


def _link_body(context: bpy.types.Context, arm_ob: bpy.types.Object, name: str, verts: np.ndarray,
               faces: Any, groups: dict[str, tuple[np.ndarray, np.ndarray]]) -> bpy.types.Object:
    me = bpy.data.meshes.new(name)
    me.from_pydata([tuple(v) for v in verts], [], [tuple(int(i) for i in f) for f in faces])
    me.update()
    body = bpy.data.objects.new(name, me)
    for coll in arm_ob.users_collection:
        coll.objects.link(body)
    body.parent = arm_ob
    body[EGO_MARK] = 1
    for bone, (idx, w) in groups.items():
        vg = body.vertex_groups.new(name=bone)
        # one add() per distinct weight: rigid proxy parts have a single weight
        for weight in np.unique(w):
            sel = idx[w == weight]
            vg.add([int(i) for i in sel], float(weight), 'REPLACE')
    mod = body.modifiers.new("Armature", 'ARMATURE')
    mod.object = arm_ob
    return body


def _smplx_body(folder: str, heads: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, dict[str, tuple[np.ndarray, np.ndarray]]]:
    """The neutral SMPL-X mesh (betas = 0) from the user's model folder, skinned to the 22 body joints."""
    import os
    folder = bpy.path.abspath(folder)
    if not os.path.isdir(folder):
        raise UserError(f"SMPL-X model folder '{folder}' does not exist; fix it in the add-on preferences")
    try:
        import smplx  # the user's own install; optional
    except ImportError:
        raise UserError("The 'smplx' package is not installed; install it (pip install smplx) or clear the "
                        "SMPL-X model folder in the preferences to use the proxy body") from None
    sk = _RT
    try:
        model = smplx.create(folder, model_type="smplx", gender="neutral", use_pca=False)
        out = model(return_verts=True)
    except Exception as exc:  # the package raises assorted errors for a wrong folder
        raise UserError(f"Could not load SMPL-X from '{folder}' ({type(exc).__name__}: "
                        f"{str(exc).splitlines()[0] if str(exc) else ''}); it must hold SMPLX_NEUTRAL.npz") from None
    yup = out.vertices.detach().cpu().numpy()[0].astype(np.float64)
    j0 = out.joints.detach().cpu().numpy()[0, 0].astype(np.float64)
    to_zup = np.array(((1.0, 0.0, 0.0), (0.0, 0.0, -1.0), (0.0, 1.0, 0.0)))   # x, -z, y
    verts = (yup - j0) @ to_zup.T + heads[0]
    faces = np.asarray(model.faces, dtype=np.int64)
    weights = model.lbs_weights.detach().cpu().numpy()          # (V, 55)
    parents = [int(p) for p in model.parents.detach().cpu().numpy()]
    # Joints past the body (jaw, eyes, fingers) hand their weight to their nearest body ancestor.
    owner = []
    for j in range(weights.shape[1]):
        k = j
        while k >= sk.NUM_JOINTS:
            k = parents[k]
        owner.append(k)
    body_w = np.zeros((len(verts), sk.NUM_JOINTS))
    for j, k in enumerate(owner):
        body_w[:, k] += weights[:, j]
    groups = {}
    for k, n in enumerate(sk.JOINT_NAMES):
        w = np.round(body_w[:, k], 3)   # rounding bounds the number of distinct weights (one add() each)
        idx = np.flatnonzero(w > 0.0)
        groups[n] = (idx, w[idx])
    return verts, faces, groups


def is_ego(ob: bpy.types.Object | None) -> bool:
    return ob is not None and ob.type == 'ARMATURE' and EGO_MARK in ob


# ---------------------------------------------------------------------------- ego posing

class EgoWriter:
    """Writes model poses (world pelvis + SMPL-X local quaternions) onto an ego armature's pose bones.

    Blender's pose rotation of a bone is relative to its rest orientation R (bone.matrix_local), so the
    model's local rotation L becomes R^-1 L R; the root also moves into the armature object's space.
    """

    def __init__(self, ob: bpy.types.Object) -> None:
        if ob is None or ob.type != 'ARMATURE':
            raise UserError("No ego armature: press 'Create Ego' in the ReMoGen panel")
        sk = _RT
        bones = ob.pose.bones
        order = {pb.name: i for i, pb in enumerate(bones)}
        missing = [n for n in sk.JOINT_NAMES if n not in order]
        if missing:
            raise UserError(f"Ego '{ob.name}' is not an SMPL-X armature (no bones {', '.join(missing[:4])}"
                            f"{' ...' if len(missing) > 4 else ''}); press 'Create Ego'")
        self.name = ob.name
        self._ob = ob
        self._n = len(bones)
        self._idx = np.array([order[n] for n in sk.JOINT_NAMES], dtype=np.intp)
        rest = [ob.data.bones[n].matrix_local for n in sk.JOINT_NAMES]
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
