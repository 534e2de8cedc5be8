"""The target: the user's own humanoid armature, posed from the ego's motion (retargeting).

Every mapped bone is turned so that its world direction (from its head to the next mapped joint down the
chain, or its own tail) is the ego's direction for that joint; its twist follows the ego's joint rotation.
Rest-pose differences (A-pose against the ego's T-pose, bone rolls, the rig's facing) are measured once,
as a per-bone rest rotation. The pelvis path is the ego's scaled by leg length (target hip-to-ankle over
the ego's), about the point where the motion starts, and the pelvis height likewise about the standing
height, so the steps fit the target's legs. Where the ego's foot is planted, a two-bone leg IK pins the
target's toe where it was when the contact began.

Units and transforms: the armature object may be scaled (0.01 with bones in centimetres, as imported from
FBX) and turned (a Y-up rig); everything is computed in world space and written in the armature's space.
"""
from __future__ import annotations

from dataclasses import dataclass

import bpy
import numpy as np

from .._runtime import UserError, api
from .ego import LEAF_TAIL, TAIL_CHILD
from .leg_ik import REACH, Leg, plant_legs
from .partner import check_armature
from .rotations import facing_yaw, quat_to_matrix, rotation_between, unit, yaw_matrix

_RT = api()   # the runtime's public package; these parts of it need no PyTorch
_INDEX = {n: i for i, n in enumerate(_RT.JOINT_NAMES)}

# The bones a target must have: enough for a body that walks, turns and gestures. Spine2/3, collars and
# toes are posed when mapped; without them their parent bone carries the chain.
REQUIRED = ("pelvis", "spine1", "neck", "head", "left_hip", "right_hip", "left_knee", "right_knee",
            "left_ankle", "right_ankle", "left_shoulder", "right_shoulder", "left_elbow", "right_elbow",
            "left_wrist", "right_wrist")
LEGS = (("left_hip", "left_knee", "left_ankle", "left_foot"), ("right_hip", "right_knee", "right_ankle", "right_foot"))


def _levels() -> list[tuple[np.ndarray, np.ndarray]]:
    """SMPL-X joints grouped by depth (joint indices, their parents): forward kinematics a level at a time."""
    depth = [0] * _RT.NUM_JOINTS
    for i, p in enumerate(_RT.PARENTS[1:], start=1):
        depth[i] = depth[p] + 1
    return [(np.array([i for i in range(_RT.NUM_JOINTS) if depth[i] == d]),
             np.array([_RT.PARENTS[i] for i in range(_RT.NUM_JOINTS) if depth[i] == d]))
            for d in range(1, max(depth) + 1)]


_LEVELS = _levels()
_EGO_REST = _RT.rest_joints_np()
_EGO_OFFSETS = np.array([_EGO_REST[i] - _EGO_REST[p] if p >= 0 else np.zeros(3) for i, p in enumerate(_RT.PARENTS)])


def _ego_world_rotations(local: np.ndarray) -> np.ndarray:
    """(T, 22, 3, 3) world rotations of the ego's joints from its local ones ([0] is already global)."""
    glob = np.empty_like(local)
    glob[:, 0] = local[:, 0]
    for idx, par in _LEVELS:
        glob[:, idx] = glob[:, par] @ local[:, idx]
    return glob


def _ego_joints(glob: np.ndarray, pelvis: np.ndarray) -> np.ndarray:
    """(T, 22, 3) world joint positions from world rotations and the pelvis."""
    joints = np.empty(glob.shape[:2] + (3,))
    joints[:, 0] = pelvis
    for idx, par in _LEVELS:
        joints[:, idx] = joints[:, par] + (glob[:, par] @ _EGO_OFFSETS[idx][..., None])[..., 0]
    return joints


def _leg_length(points: np.ndarray) -> float:
    """Mean hip-to-knee plus knee-to-ankle length of both legs; `points` (22, 3) in SMPL-X order."""
    return float(np.mean([np.linalg.norm(points[_INDEX[k]] - points[_INDEX[h]])
                          + np.linalg.norm(points[_INDEX[a]] - points[_INDEX[k]]) for h, k, a, _ in LEGS]))


def _parse(spec: str) -> tuple[str, list[str], float]:
    """A bone-map entry: ("bone" | "lerp" | "end", bone names, t); a malformed lerp gets t = NaN."""
    if spec.startswith("lerp:"):
        parts = spec.split(":")
        try:
            return "lerp", parts[1:3], float(parts[3]) if len(parts) == 4 else float("nan")
        except ValueError:
            return "lerp", parts[1:3], float("nan")
    if spec.startswith("end:"):
        return "end", [spec[4:]], 1.0
    return "bone", [spec], 0.0


def _resolve_specs(ob: bpy.types.Object, mapping: dict[str, str]) -> dict[int, tuple[str, list[str], float]]:
    """SMPL-X joint index -> (kind, the rig's real bone names, t) for the map entries whose bones exist; a
    one-line UserError when a required joint has no bone of its own or a bone serves two joints."""
    by_norm = {_RT.normalise_name(b.name): b.name for b in ob.data.bones}
    specs: dict[int, tuple[str, list[str], float]] = {}
    for j, joint in enumerate(_RT.JOINT_NAMES):
        kind, names, t = _parse(mapping.get(joint, ""))
        real = [by_norm.get(_RT.normalise_name(n)) for n in names]
        if all(names) and all(r is not None for r in real) and np.isfinite(t):
            specs[j] = (kind, real, t)
    missing = [j for j in REQUIRED if specs.get(_INDEX[j], ("",))[0] != "bone"]
    if missing:
        raise UserError(f"Target '{ob.name}' has no bones for {', '.join(missing)}: map them in the "
                        "Target Bone Map panel (or pick a humanoid armature)")
    used: dict[str, str] = {}
    for j, (kind, real, _t) in specs.items():
        if kind == "bone":
            if real[0] in used:
                raise UserError(f"Target '{ob.name}': bone '{real[0]}' is mapped to both {used[real[0]]} and "
                                f"{_RT.JOINT_NAMES[j]}; fix the Target Bone Map")
            used[real[0]] = _RT.JOINT_NAMES[j]
    return specs


def _ancestors(bone: bpy.types.Bone) -> list[str]:
    out = []
    while bone.parent is not None:
        bone = bone.parent
        out.append(bone.name)
    return out


@dataclass
class _Posed:
    """One mapped joint of the target and the constants that pose its bone."""
    joint: int              # SMPL-X joint index
    bone: str
    parent: int             # index (in TargetWriter.posed) of the nearest posed ancestor bone, -1: none
    chain: np.ndarray       # (4, 4) from that ancestor's posed frame (or armature space) to this bone's rest
    rest_to_world: np.ndarray   # (3, 3) world orientation of the bone when the ego's joint is at rest
    ego_rest_dir: np.ndarray    # (3,) the ego's direction for this joint at rest (yaw 0)
    child: int              # SMPL-X joint that direction points at, -1: the ego bone's own tail (a leaf)

    @property
    def skips(self) -> bool:
        """It aims past an unmapped joint (spine2 mapped by lerp, say): the ego's chain may bend in between."""
        return self.child >= 0 and _RT.PARENTS[self.child] != self.joint


class TargetWriter:
    """Poses a target armature from ego poses (world pelvis + SMPL-X local quaternions)."""

    def __init__(self, ob: bpy.types.Object, mapping: dict[str, str]) -> None:
        check_armature(ob, "Target")
        self.name = ob.name
        self._ob = ob
        bones = ob.data.bones
        self._specs = _resolve_specs(ob, mapping)
        mw = np.array(ob.matrix_world, dtype=np.float64)
        rest = {b.name: np.array(b.matrix_local, dtype=np.float64) for b in bones}
        points = np.array([self._rest_point(j, bones) if j in self._specs else np.full(3, np.nan)
                           for j in range(_RT.NUM_JOINTS)])
        world = points @ mw[:3, :3].T + mw[:3, 3]
        self.leg_scale = _leg_length(world) / _leg_length(_EGO_REST)
        if not np.isfinite(self.leg_scale) or self.leg_scale <= 1e-6:
            raise UserError(f"Target '{ob.name}' has legs of no length; check its hip, knee and ankle bones")
        # Facing from the hips, against the ego's rest hips (which are not quite level with its facing).
        hips = [_INDEX["left_hip"], _INDEX["right_hip"]]
        self.yaw = facing_yaw(np.subtract(*world[hips])) - facing_yaw(np.subtract(*_EGO_REST[hips]))
        self.rest_pelvis = world[0]                      # world, at rest
        self.floor = float(mw[2, 3])                     # the rig stands on its object origin's height
        self.posed = self._build_posed(bones, rest, _RT.rigid_rotation(mw))
        self._slot = {p.joint: k for k, p in enumerate(self.posed)}
        pelvis = self.posed[self._slot[0]]
        if pelvis.parent >= 0:
            raise UserError(f"Target '{ob.name}': the pelvis bone '{pelvis.bone}' is below another mapped bone; "
                            "map the rig's hip bone to the pelvis")
        if bones[pelvis.bone].use_connect:
            raise UserError(f"Target '{ob.name}': the pelvis bone '{pelvis.bone}' is connected to its parent and "
                            "cannot move; disconnect it (Edit Mode, Bone properties, Relations)")
        self._pelvis_chain_inv = np.linalg.inv(pelvis.chain)
        self._legs = [self._leg(leg, bones) for leg in LEGS]
        # Heads are needed only down to the legs (the leg IK): the legs' bones and their posed ancestors.
        need: set[int] = set()
        for leg in self._legs:
            for k in (leg.hip, leg.knee, leg.ankle):
                while k >= 0 and k not in need:
                    need.add(k)
                    k = self.posed[k].parent
        self._head_slots = sorted(need)
        # The knee's bend axis for a straight leg: the body's left, in the pelvis bone's frame.
        left = points[_INDEX["left_hip"]] - points[_INDEX["right_hip"]]
        self._left_in_pelvis = unit(rest[pelvis.bone][:3, :3].T @ left)
        self._joints = np.array([p.joint for p in self.posed])
        self._parents = np.array([p.parent for p in self.posed])
        self._rest_to_world = np.stack([p.rest_to_world for p in self.posed])
        self._chain_rot_t = np.stack([_RT.rigid_rotation(p.chain).T for p in self.posed])
        self._skips = np.array([k for k, p in enumerate(self.posed) if p.skips], dtype=np.intp)
        self._ego_rest_dir = np.stack([p.ego_rest_dir for p in self.posed])
        self._child = np.array([p.child for p in self.posed])
        self._inv_key: bytes | None = None
        self._inv = np.eye(4)
        self.follow(self.start_pose()[0], self.yaw)

    def _build_posed(self, bones, rest: dict[str, np.ndarray], rw: np.ndarray) -> list[_Posed]:
        """The mapped bones, parents before children, with their rest alignment to the ego."""
        bone_joint = {real[0]: j for j, (kind, real, _t) in self._specs.items() if kind == "bone"}
        basis = {pb.name: np.array(pb.matrix_basis, dtype=np.float64) for pb in self._ob.pose.bones}
        to_ego = yaw_matrix(-self.yaw)                   # the rig's facing turned to the ego's rest facing
        posed: list[_Posed] = []
        slot: dict[str, int] = {}
        for b in sorted(bone_joint, key=lambda name: len(_ancestors(bones[name]))):
            j = bone_joint[b]
            parent, chain = self._chain(bones[b], bone_joint, slot, rest, basis)
            point, child = self._chain_point(j, bones)
            d_tgt = unit(rw @ (point - rest[b][:3, 3]))
            d_ego = unit(_EGO_REST[child] - _EGO_REST[j] if child >= 0 else np.array(LEAF_TAIL[_RT.JOINT_NAMES[j]]))
            align = rotation_between(to_ego @ d_tgt, d_ego) @ to_ego
            slot[b] = len(posed)
            posed.append(_Posed(j, b, parent, chain, align @ rw @ rest[b][:3, :3], d_ego, child))
        return posed

    # ------------------------------------------------------------------ set-up
    def _rest_point(self, j: int, bones) -> np.ndarray:
        kind, real, t = self._specs[j]
        if kind == "end":
            return np.array(bones[real[0]].tail_local, dtype=np.float64)
        a = np.array(bones[real[0]].head_local, dtype=np.float64)
        if kind == "lerp":
            return (1.0 - t) * a + t * np.array(bones[real[1]].head_local, dtype=np.float64)
        return a

    def _chain(self, bone, bone_joint: dict[str, int], slot: dict[str, int], rest: dict, basis: dict
               ) -> tuple[int, np.ndarray]:
        """(nearest posed ancestor's slot or -1, the fixed transform from its posed frame to this bone's rest
        frame): unmapped bones in between keep the pose they have now."""
        path = [bone]
        while path[-1].parent is not None and path[-1].parent.name not in bone_joint:
            path.append(path[-1].parent)
        top = path[-1].parent
        m = np.eye(4)
        for x in reversed(path):
            rel = rest[x.name] if x.parent is None else np.linalg.inv(rest[x.parent.name]) @ rest[x.name]
            m = m @ rel
            if x is not bone:
                m = m @ basis[x.name]
        return (slot[top.name] if top is not None else -1), m

    def _chain_point(self, j: int, bones) -> tuple[np.ndarray, int]:
        """The rest point this joint's bone aims at, and the ego joint that matches it (-1: a leaf)."""
        bone = bones[self._specs[j][1][0]]
        name = _RT.JOINT_NAMES[j]
        c = TAIL_CHILD.get(name)
        while c is not None:
            spec = self._specs.get(_INDEX[c])
            if spec is not None and spec[0] == "bone" and bone.name in _ancestors(bones[spec[1][0]]):
                return np.array(bones[spec[1][0]].head_local, dtype=np.float64), _INDEX[c]
            if spec is not None and spec[0] == "end" and spec[1][0] == bone.name:
                return np.array(bone.tail_local, dtype=np.float64), _INDEX[c]
            c = TAIL_CHILD.get(c)
        first = TAIL_CHILD.get(name)
        return np.array(bone.tail_local, dtype=np.float64), (_INDEX[first] if first else -1)

    def _leg(self, leg: tuple[str, str, str, str], bones) -> Leg:
        """One leg's bones, toe point in the ankle bone's frame and reach."""
        hip, knee, ankle = (self._slot[_INDEX[n]] for n in leg[:3])
        for child, parent in ((knee, hip), (ankle, knee)):
            if self.posed[child].parent != parent:
                raise UserError(f"Target '{self.name}': bone '{self.posed[child].bone}' is not a child of "
                                f"'{self.posed[parent].bone}'; fix the Target Bone Map")
        toe = np.zeros(3)                               # no toe: the ankle itself is pinned
        foot = _INDEX[leg[3]]
        spec = self._specs.get(foot)
        if foot in self._slot and self.posed[self._slot[foot]].parent == ankle:
            toe = self.posed[self._slot[foot]].chain[:3, 3]
        elif spec is not None and spec[0] == "end" and spec[1][0] == self.posed[ankle].bone:
            toe = np.array((0.0, bones[spec[1][0]].length, 0.0))
        length = np.linalg.norm(self.posed[knee].chain[:3, 3]) + np.linalg.norm(self.posed[ankle].chain[:3, 3])
        return Leg(hip, knee, ankle, toe, REACH * float(length))

    @property
    def object(self) -> bpy.types.Object:
        return self._ob

    def start_pose(self) -> tuple[tuple[float, float, float], float]:
        """(floor point under the rest pelvis, yaw): where a session that drives only this rig starts."""
        return (float(self.rest_pelvis[0]), float(self.rest_pelvis[1]), self.floor), self.yaw

    def follow(self, root: tuple[float, float, float], yaw: float) -> None:
        """The ego's motion starts at floor point `root` facing `yaw`: the target does it from its own place."""
        self._ego_root = np.array(root, dtype=np.float64) + (0.0, 0.0, _RT.standing_pelvis_height())
        self._turn = yaw_matrix(self.yaw - yaw)

    # ------------------------------------------------------------------ posing
    def _world(self) -> tuple[np.ndarray, np.ndarray]:
        """(matrix_world, its inverse), the inverse recomputed only when the object moved (a LAPACK call per
        live frame costs about a millisecond)."""
        try:
            mw = np.array(self._ob.matrix_world, dtype=np.float64)
        except ReferenceError:
            raise UserError(f"Target '{self.name}' was deleted") from None
        key = mw.tobytes()
        if key != self._inv_key:
            self._inv, self._inv_key = np.linalg.inv(mw), key
        return mw, self._inv

    def pelvis_path(self, pelvis: np.ndarray) -> np.ndarray:
        """(T, 3) world pelvis of the target for the ego's (T, 3): scaled by leg length about the start."""
        rel = (np.asarray(pelvis, np.float64) - self._ego_root) * self.leg_scale
        return self.rest_pelvis + rel @ self._turn.T

    def _solve(self, pelvis: np.ndarray, local_rotations: np.ndarray, pins: np.ndarray | None = None,
               shifts: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(armature-space orientations (T, B, 3, 3), heads (T, B, 3), pelvis head (T, 3), toes (T, 2, 3)
        before the leg IK), bones in `posed` order."""
        mw, inv = self._world()
        rw = _RT.rigid_rotation(mw)
        glob = _ego_world_rotations(quat_to_matrix(local_rotations))
        g = glob[:, self._joints]                                         # (T, B, 3, 3)
        orient = g @ self._rest_to_world
        if len(self._skips):                # aim those bones along the ego's actual chain
            k = self._skips
            joints = _ego_joints(glob, pelvis)
            at_rest = (g[:, k] @ self._ego_rest_dir[k][..., None])[..., 0]
            now = joints[:, self._child[k]] - joints[:, self._joints[k]]
            orient[:, k] = rotation_between(at_rest, now) @ orient[:, k]
        q = (rw.T @ self._turn) @ orient                                  # armature space
        h = self.pelvis_path(pelvis) @ inv[:3, :3].T + inv[:3, 3]
        t = len(q)
        heads = np.full((t, len(self.posed), 3), np.nan)
        for k in self._head_slots:
            p = self.posed[k]
            if p.joint == 0:
                heads[:, k] = h
            elif p.parent < 0:
                heads[:, k] = p.chain[:3, 3]
            else:
                heads[:, k] = heads[:, p.parent] + q[:, p.parent] @ p.chain[:3, 3]
        toes = np.stack([heads[:, leg.ankle] + q[:, leg.ankle] @ leg.toe for leg in self._legs], axis=1)
        if pins is not None:
            goals = np.where(np.isfinite(pins), pins @ inv[:3, :3].T + inv[:3, 3], toes + shifts @ inv[:3, :3].T)
            hint = q[:, self._slot[0]] @ self._left_in_pelvis
            h = h + plant_legs(q, heads, self._legs, goals, hint)
        return q, heads, h, toes

    def pose_channels(self, pelvis: np.ndarray, local_rotations: np.ndarray, pins: np.ndarray | None = None,
                      shifts: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Blender channels for ego poses: ((T, 3) pelvis bone location, (T, B, 4) rotations of the posed bones).

        pelvis (T, 3) world, local_rotations (T, 22, 4). Feet, (T, 2, 3) world, NaN where not used: `pins`,
        points where planted toes stay; else `shifts`, moves of the retargeted toes (a correction fading out).
        None: the feet as retargeted.
        """
        q, _heads, h, _toes = self._solve(pelvis, local_rotations, pins, shifts)
        parent_q = np.where((self._parents >= 0)[:, None, None], q[:, np.maximum(self._parents, 0)], np.eye(3))
        basis = self._chain_rot_t @ np.swapaxes(parent_q, -1, -2) @ q
        loc = h @ self._pelvis_chain_inv[:3, :3].T + self._pelvis_chain_inv[:3, 3]
        return loc, _RT.matrix_to_quat_np(basis)

    def toes(self, pelvis: np.ndarray, local_rotations: np.ndarray) -> np.ndarray:
        """(T, 2, 3) world toe points (left, right) of the retargeted poses before any foot is pinned."""
        mw, _inv = self._world()
        toes = self._solve(pelvis, local_rotations)[3]
        return toes @ mw[:3, :3].T + mw[:3, 3]

    @property
    def bone_names(self) -> list[str]:
        return [p.bone for p in self.posed]

    @property
    def pelvis_bone(self) -> str:
        return self.posed[self._slot[0]].bone

    def write_channels(self, loc: np.ndarray, rot: np.ndarray) -> None:
        """One pose: (3,) pelvis location, (B, 4) quaternions, each bone in its own rotation mode."""
        from mathutils import Quaternion
        try:
            bones = self._ob.pose.bones
            for p, q in zip(self.posed, rot):
                pb = bones[p.bone]
                mode = pb.rotation_mode
                if mode == 'QUATERNION':
                    pb.rotation_quaternion = q
                elif mode == 'AXIS_ANGLE':
                    axis, angle = Quaternion(q).to_axis_angle()
                    pb.rotation_axis_angle = (angle, *axis)
                else:
                    pb.rotation_euler = Quaternion(q).to_euler(mode, pb.rotation_euler)
            bones[self.pelvis_bone].location = loc
            self._ob.update_tag()
        except (ReferenceError, KeyError):
            raise UserError(f"Target '{self.name}' was deleted or lost bones; pick it again") from None

    def key_channels(self, loc: np.ndarray, rot: np.ndarray) -> list[tuple[str, str, np.ndarray]]:
        """(bone, property, (T, n) values) for keying (T, 3) locations and (T, B, 4) rotations, each bone in
        its own rotation mode and continuous over time."""
        from mathutils import Euler, Quaternion
        rot = _RT.continuous_quaternions(rot)
        out = [(self.pelvis_bone, "location", np.asarray(loc))]
        for b, p in enumerate(self.posed):
            mode = self._ob.pose.bones[p.bone].rotation_mode
            q = rot[:, b]
            if mode == 'QUATERNION':
                out.append((p.bone, "rotation_quaternion", q))
            elif mode == 'AXIS_ANGLE':
                vals = [Quaternion(v).to_axis_angle() for v in q]
                out.append((p.bone, "rotation_axis_angle", np.array([(a, *ax) for ax, a in vals])))
            else:
                eul, prev = [], Euler(self._ob.pose.bones[p.bone].rotation_euler, mode)
                for v in q:
                    prev = Quaternion(v).to_euler(mode, prev)
                    eul.append(tuple(prev))
                out.append((p.bone, "rotation_euler", np.array(eul)))
        return out
