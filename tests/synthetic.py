"""Small synthetic motion for tests: rest bodies walking and turning (no licensed data)."""
from __future__ import annotations

import math

import numpy as np
import torch

from model_runtime.data.library import ClipLibrary
from model_runtime.skeleton import axis_angle_to_matrix, matrix_to_quat, standing_pelvis_height, yaw_matrix


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
