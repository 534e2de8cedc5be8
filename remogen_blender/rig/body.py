"""The ego's body mesh, skinned to its armature: capsules along the bones, or the user's SMPL-X model."""
from __future__ import annotations

import os
from typing import Any

import bpy
import numpy as np

from .._runtime import UserError, api

_RT = api()   # the runtime's public package; these parts of it need no PyTorch

EGO_MARK = "remogen_ego"   # custom property set on the armature and body made by Create Ego

# Proxy body: capsule radius per bone (metres).
_RADIUS = {
    "pelvis": 0.13, "spine1": 0.13, "spine2": 0.13, "spine3": 0.14, "neck": 0.05, "head": 0.095,
    "left_hip": 0.075, "left_knee": 0.055, "left_ankle": 0.04, "left_foot": 0.035, "left_collar": 0.05,
    "left_shoulder": 0.045, "left_elbow": 0.038, "left_wrist": 0.035,
}


def proxy_body(names: list[str], ob: bpy.types.Object, radius_names: list[str] | None = None
               ) -> tuple[np.ndarray, np.ndarray, dict[str, tuple[np.ndarray, np.ndarray]]]:
    """Capsule-like prisms along every bone, each rigidly weighted to its bone. The capsules' radii are
    looked up by `radius_names` (SMPL-X joint names, one per bone; default: the bone names)."""
    sides = 8
    ang = np.linspace(0.0, 2.0 * np.pi, sides, endpoint=False)
    verts, faces, groups = [], [], {}
    for n, rn in zip(names, radius_names or names):
        bone = ob.data.bones[n]
        h, t = np.array(bone.head_local), np.array(bone.tail_local)
        r = _RADIUS.get(rn, _RADIUS.get("left_" + rn[6:], 0.05) if rn.startswith("right_") else 0.05)
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


def link_body(arm_ob: bpy.types.Object, name: str, verts: np.ndarray, faces: Any,
              groups: dict[str, tuple[np.ndarray, np.ndarray]]) -> bpy.types.Object:
    """A mesh object parented to the armature, with one vertex group per bone and an Armature modifier."""
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


def smplx_body(folder: str, heads: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, dict[str, tuple[np.ndarray, np.ndarray]]]:
    """The neutral SMPL-X mesh (betas = 0) from the user's model folder, skinned to the 22 body joints."""
    folder = bpy.path.abspath(folder)
    if not os.path.isdir(folder):
        raise UserError(f"SMPL-X model folder '{folder}' does not exist; fix it in the add-on preferences")
    try:
        import smplx  # the user's own install; optional
    except ImportError:
        raise UserError("The 'smplx' package is not installed; install it (pip install smplx) or clear the "
                        "SMPL-X model folder in the preferences to use the proxy body") from None
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
        while k >= _RT.NUM_JOINTS:
            k = parents[k]
        owner.append(k)
    body_w = np.zeros((len(verts), _RT.NUM_JOINTS))
    for j, k in enumerate(owner):
        body_w[:, k] += weights[:, j]
    groups = {}
    for k, n in enumerate(_RT.JOINT_NAMES):
        w = np.round(body_w[:, k], 3)   # rounding bounds the number of distinct weights (one add() each)
        idx = np.flatnonzero(w > 0.0)
        groups[n] = (idx, w[idx])
    return verts, faces, groups
