"""Measurements of a retargeted bake, independent of the retargeting code: the ego's joints come from the
runtime's forward kinematics of the baked model poses, the target's from its evaluated pose bones."""
from __future__ import annotations

from dataclasses import dataclass

import bpy
import numpy as np

import torch
from model_runtime.skeleton import JOINT_NAMES, forward_kinematics_np, quat_to_matrix, rest_joints
from remogen_blender.rig.ego import LEAF_TAIL, TAIL_CHILD

LEGS = (("left_hip", "left_knee", "left_ankle"), ("right_hip", "right_knee", "right_ankle"))
INDEX = {n: i for i, n in enumerate(JOINT_NAMES)}


@dataclass
class Worst:
    direction_deg: float      # largest angle between a target bone and the ego's matching direction
    pelvis_cm: float          # largest distance of the target pelvis from the ego's path scaled by leg length
    planted_cm: float         # largest motion of a planted toe from where its contact began
    planted_frames: int       # scene frames with a foot planted (so the last number means something)
    direction_by_joint: dict  # joint -> its largest direction error (deg)


def ego_joints_and_rotations(driver, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(T, 22, 3) world joints and (T, 22, 3, 3) world rotations of the ego poses at model times."""
    poses = driver.poses_at(times)
    rots = quat_to_matrix(torch.as_tensor(poses.local_rotations, dtype=torch.float64)).numpy()
    out_j, out_g = [], []
    for r, p in zip(rots, poses.pelvis):
        j, g = forward_kinematics_np(r, p, world_rotations=True)
        out_j.append(j)
        out_g.append(g)
    return np.array(out_j), np.array(out_g)


def _world(ob, dg):
    ev = ob.evaluated_get(dg)
    mw = np.array(ev.matrix_world)
    pb = ev.pose.bones
    return {b.name: (mw[:3, :3] @ np.array(b.head) + mw[:3, 3], mw[:3, :3] @ np.array(b.tail) + mw[:3, 3])
            for b in pb}


def leg_length(points: dict[str, np.ndarray]) -> float:
    return float(np.mean([np.linalg.norm(points[k] - points[h]) + np.linalg.norm(points[a] - points[k])
                          for h, k, a in LEGS]))


def rest_points(ob, mapping: dict[str, str]) -> dict[str, np.ndarray]:
    mw = np.array(ob.matrix_world)
    return {j: mw[:3, :3] @ np.array(ob.data.bones[b].head_local) + mw[:3, 3] for j, b in mapping.items()}


def measure(scene, job, target, mapping: dict[str, str], ego_start: np.ndarray, toe_bones: dict[int, str]) -> Worst:
    """Replay the baked frames and measure the three quantities. ego_start: the ego's standing pelvis where
    the motion began (world); toe_bones: side -> the target bone whose head is the toe."""
    rest = rest_points(target, mapping)
    ego_rest = rest_joints().numpy().astype(np.float64)
    s = leg_length(rest) / leg_length({n: ego_rest[i] for i, n in enumerate(JOINT_NAMES)})
    frames = np.arange(job.f0, job.f1 + 1)
    times = (frames - job.f0) / job.fps
    joints, glob = ego_joints_and_rotations(job.driver, times)
    worst_pelvis = 0.0
    by_joint = dict.fromkeys(mapping, 0.0)
    toes = []
    for k, f in enumerate(frames):
        scene.frame_set(int(f))
        dg = bpy.context.evaluated_depsgraph_get()
        w = _world(target, dg)
        for j, bone in mapping.items():
            i = INDEX[j]
            child = TAIL_CHILD.get(j)
            if child is not None and child in mapping:
                got = w[mapping[child]][0] - w[bone][0]
                want = joints[k, INDEX[child]] - joints[k, i]
            else:                                                 # a leaf: the bone's own tail
                got = w[bone][1] - w[bone][0]
                want = glob[k, i] @ np.array(LEAF_TAIL[j]) if j in LEAF_TAIL else joints[k, INDEX[child]] - joints[k, i]
            cos = got @ want / (np.linalg.norm(got) * np.linalg.norm(want))
            by_joint[j] = max(by_joint[j], float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))))
        want_pelvis = rest["pelvis"] + s * (joints[k, 0] - ego_start)
        worst_pelvis = max(worst_pelvis, float(np.linalg.norm(w[mapping["pelvis"]][0] - want_pelvis)))
        toes.append([w[toe_bones[side]][0] for side in (0, 1)])
    toes = np.array(toes)
    # planted: scene frames whose model time lies inside a contact (both model frames around it planted)
    contacts = np.array([fr.contacts for fr in job.driver.frames])
    x = times / job.driver.dt
    lo, hi = np.floor(x + 1e-6).astype(int), np.ceil(x - 1e-6).astype(int)
    worst_planted, planted = 0.0, 0
    for side in (0, 1):
        on = contacts[lo, side] & contacts[np.minimum(hi, len(contacts) - 1), side]
        start = None
        for k in range(len(frames)):
            if on[k]:
                b = lo[k]                     # back to the model frame where this contact began
                while b > 0 and contacts[b - 1, side]:
                    b -= 1
                if start is None or start[0] != b:
                    start = (b, toes[k, side])
                worst_planted = max(worst_planted, float(np.linalg.norm(toes[k, side] - start[1])))
                planted += 1
            else:
                start = None
    return Worst(max(by_joint.values()), worst_pelvis * 100.0, worst_planted * 100.0, planted,
                 {j: round(v, 2) for j, v in by_joint.items() if v > 1.0})
