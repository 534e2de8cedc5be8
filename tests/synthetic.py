"""Small synthetic motion for tests: rest bodies walking and turning, and BVH files of a humanoid with
SMPL-X's proportions (no licensed data)."""
from __future__ import annotations

import math

import numpy as np
import torch

from model_runtime.data.library import ClipLibrary
from model_runtime.skeleton import (JOINT_INDEX, JOINT_NAMES, PARENTS, REST_JOINTS_ZUP, axis_angle_to_matrix,
                                    matrix_to_quat, standing_pelvis_height, yaw_matrix)

J = JOINT_INDEX


def walking_clip(frames: int, speed: float, turn: float, start=(0.0, 0.0), yaw0: float = 0.0, phase: float = 0.0):
    """(local quats (T,22,4), pelvis (T,3)): a body walking forward, turning `turn` rad over the clip."""
    t = np.arange(frames) / 10.0
    yaw = yaw0 + turn * np.clip(t / max(t[-1], 1e-6), 0, 1)
    heading = np.stack((np.sin(yaw), -np.cos(yaw)), -1)  # rest faces -Y; yaw turns it counter-clockwise
    xy = np.asarray(start) + np.cumsum(heading * speed / 10.0, axis=0)
    aa = torch.zeros(frames, 22, 3)
    swing = 0.4 * torch.sin(torch.tensor(2 * math.pi * 1.0 * t + phase, dtype=torch.float32))
    aa[:, 1, 0], aa[:, 2, 0] = swing, -swing          # hips
    aa[:, 16, 2], aa[:, 17, 2] = -1.2, 1.2             # arms down
    rot = axis_angle_to_matrix(aa)
    rot[:, 0] = yaw_matrix(torch.tensor(yaw, dtype=torch.float32)) @ rot[:, 0]
    pel = np.concatenate((xy, np.full((frames, 1), standing_pelvis_height())), 1).astype(np.float32)
    return matrix_to_quat(rot).numpy(), pel


def synthetic_library(n: int = 8, frames: int = 40, seed: int = 0) -> ClipLibrary:
    rng = np.random.default_rng(seed)
    rots, pels, off, names, caps = [], [], [0], [], []
    for i in range(n):
        turn = float(rng.choice([0.0, math.pi / 2, -math.pi / 2]))
        q, p = walking_clip(frames, float(rng.uniform(0.8, 1.5)), turn, start=tuple(rng.uniform(-2, 2, 2)),
                            yaw0=float(rng.uniform(-3, 3)), phase=float(rng.uniform(0, 6)))
        rots.append(q)
        pels.append(p)
        off.append(off[-1] + frames)
        names.append(f"synthetic_{i:03d}")
        caps.append("a person walks" if turn == 0 else ("a person turns left" if turn > 0 else "a person turns right"))
    return ClipLibrary(names, caps, ["cmu"] * (n // 2) + ["bandai"] * (n - n // 2), np.concatenate(rots),
                       np.concatenate(pels), np.asarray(off, np.int64), [0.0] * n)


def rigid_clip(xy: np.ndarray, yaw: float) -> tuple[np.ndarray, np.ndarray]:
    """(local quats (T,22,4), pelvis (T,3)): a rest body gliding along the floor path xy (T, 2), facing `yaw`,
    with one arm moving (so that copies can be told from frozen poses)."""
    t = len(xy)
    rot = torch.eye(3).repeat(t, 22, 1, 1)
    rot[:, 0] = yaw_matrix(torch.full((t,), yaw))
    rot[:, 16] = yaw_matrix(torch.linspace(0, 1, t))          # some real motion: an arm moving
    pel = np.concatenate((xy, np.full((t, 1), standing_pelvis_height())), 1).astype(np.float32)
    return matrix_to_quat(rot).numpy(), pel


def library_of(clips: list[tuple[str, str, str, tuple[np.ndarray, np.ndarray]]]) -> ClipLibrary:
    """A ClipLibrary of (name, caption, source, (quats, pelvis)) clips."""
    rot = np.concatenate([c[3][0] for c in clips])
    pel = np.concatenate([c[3][1] for c in clips])
    off = np.cumsum([0] + [len(c[3][1]) for c in clips]).astype(np.int64)
    return ClipLibrary([c[0] for c in clips], [c[1] for c in clips], [c[2] for c in clips], rot, pel, off,
                       [0.0] * len(clips))


# A humanoid with SMPL-X's own proportions and plain BVH names: retargeting it must be near exact.
NAMES = {"pelvis": "Hips", "spine1": "Spine", "spine2": "Spine1", "spine3": "Spine2", "neck": "Neck",
         "head": "Head"}
for _s, _S in (("left", "Left"), ("right", "Right")):
    NAMES.update({f"{_s}_hip": f"{_S}UpLeg", f"{_s}_knee": f"{_S}Leg", f"{_s}_ankle": f"{_S}Foot",
                  f"{_s}_foot": f"{_S}ToeBase", f"{_s}_collar": f"{_S}Shoulder",
                  f"{_s}_shoulder": f"{_S}Arm", f"{_s}_elbow": f"{_S}ForeArm", f"{_s}_wrist": f"{_S}Hand"})
REST_YUP = np.array(REST_JOINTS_ZUP) @ np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]]).T   # Z-up -> Y-up


def humanoid_bvh(path, fps=120.0, seconds=2.0, unit=0.01, order="ZXY", up="Y", rest_frame=False,
                 amplitude=25.0, seed=0):
    """Write a walking-ish SMPL-X-proportioned humanoid; returns (path, world joints (T, 22, 3) metres Z-up)."""
    from scipy.spatial.transform import Rotation
    rng = np.random.default_rng(seed)
    t = np.arange(int(round(seconds * fps)) + 1) / fps
    n = len(t)
    phase = rng.uniform(0, 2 * np.pi, (22, 3))
    freq = rng.uniform(0.5, 1.5, (22, 3))
    ang = amplitude * np.sin(2 * np.pi * freq * t[:, None, None] + phase)          # (T, 22, 3) degrees
    ang[:, 0] *= 0.4                                                                  # keep it upright
    ang[:, [J["left_collar"], J["right_collar"]]] *= 0.3
    rest = REST_YUP - REST_YUP[0]
    root = np.stack([0.05 * np.sin(t), np.full(n, 0.95), 1.2 * t], -1)               # forward = +Z (Y-up)
    if rest_frame:
        ang[0] = 0.0
    kids = {j: [c for c in range(22) if PARENTS[c] == j] for j in range(22)}

    def block(j, depth):
        pad = "\t" * depth
        name = NAMES[JOINT_NAMES[j]]
        head = f"{pad}ROOT {name}" if j == 0 else f"{pad}JOINT {name}"
        off = np.zeros(3) if j == 0 else (rest[j] - rest[PARENTS[j]])
        off = _to_file_axes(off, up) / unit
        ch = " ".join(f"{a}rotation" for a in order)
        ch = f"CHANNELS 6 Xposition Yposition Zposition {ch}" if j == 0 else f"CHANNELS 3 {ch}"
        out = [head, pad + "{", f"{pad}\tOFFSET {off[0]:.6f} {off[1]:.6f} {off[2]:.6f}", f"{pad}\t{ch}"]
        for c in kids[j]:
            out += block(c, depth + 1)
        if not kids[j]:
            out += [f"{pad}\tEnd Site", f"{pad}\t{{", f"{pad}\t\tOFFSET 0 {0.05 / unit:.6f} 0", f"{pad}\t}}"]
        return out + [pad + "}"]

    order_js = []

    def visit(j):
        order_js.append(j)
        for c in kids[j]:
            visit(c)
    visit(0)
    # the file's rotations live in its own axes: conjugate Y-up rotations when the file is Z-up
    a = Rotation.from_matrix(_axes_matrix(up) @ Rotation.from_euler("XYZ", ang.reshape(-1, 3), degrees=True)
                             .as_matrix() @ _axes_matrix(up).T).as_euler(order.upper(), degrees=True)
    a = a.reshape(n, 22, 3)
    rows = []
    for f in range(n):
        vals = list(_to_file_axes(root[f], up) / unit) + list(a[f, 0])
        for j in order_js[1:]:
            vals += list(a[f, j])
        rows.append(" ".join(f"{v:.6f}" for v in vals))
    text = "\n".join(["HIERARCHY"] + block(0, 0) + ["MOTION", f"Frames: {n}", f"Frame Time: {1 / fps:.8f}"]
                     + rows) + "\n"
    path.write_text(text)
    # ground truth: Y-up FK -> Z-up metres
    glob = np.zeros((n, 22, 3, 3))
    pos = np.zeros((n, 22, 3))
    local = Rotation.from_euler("XYZ", ang.reshape(-1, 3), degrees=True).as_matrix().reshape(n, 22, 3, 3)
    for j in range(22):
        if j == 0:
            glob[:, 0], pos[:, 0] = local[:, 0], root
        else:
            p = PARENTS[j]
            glob[:, j] = glob[:, p] @ local[:, j]
            pos[:, j] = pos[:, p] + glob[:, p] @ (rest[j] - rest[p])
    zup = pos @ np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]]).T
    return path, zup


def _axes_matrix(up):
    """Y-up coordinates -> the file's coordinates."""
    return np.eye(3) if up == "Y" else np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])


def _to_file_axes(v, up):
    return _axes_matrix(up) @ v


def write_npz(path, root_orient, frames=60, rate_key="mocap_frame_rate", width=165, **extra):
    """An AMASS-style .npz at 60 fps: zero body pose, the given root orientation, no translation."""
    poses = np.zeros((frames, width), np.float32)
    poses[:, :3] = root_orient
    np.savez(path, poses=poses, trans=np.zeros((frames, 3), np.float32), **{rate_key: np.array(60.0)}, **extra)
    return path


def scaled_copy(src, dst, scale=1.0, shift_x=0.0):
    """The same take for a second actor: a body `scale` times taller (bones and hip height) walking the same
    path, moved sideways by shift_x file units."""
    lines = src.read_text().splitlines()
    out, motion = [], False
    for line in lines:
        tok = line.split()
        if tok[:1] == ["OFFSET"]:
            pad = line[:len(line) - len(line.lstrip())]
            line = pad + "OFFSET " + " ".join(f"{float(v) * scale:.6f}" for v in tok[1:])
        elif motion and len(tok) > 3:
            root = [float(v) for v in tok[:3]]
            root[0] += shift_x
            root[1] *= scale                                              # Y up: the hips higher
            line = " ".join([f"{v:.6f}" for v in root] + tok[3:])
        elif tok[:2] == ["Frame", "Time:"]:
            motion = True
        out.append(line)
    dst.write_text("\n".join(out) + "\n")
    return dst
