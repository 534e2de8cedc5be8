"""BVH reader: any hierarchy, 3 or 6 channels per joint, any rotation channel order per joint.

Returns the source skeleton's world joint positions per frame in the file's own units and axes
(retargeting converts units, up axis and skeleton). Rotation channels compose in the order listed:
"Zrotation Xrotation Yrotation" means R = Rz @ Rx @ Ry. A joint with position channels uses them
as its local translation (Bandai files give every joint 6 channels), otherwise its OFFSET.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError


@dataclass
class BvhJoint:
    name: str
    parent: int
    offset: np.ndarray
    channels: list[str] = field(default_factory=list)
    end_site: np.ndarray | None = None   # offset of the End Site child, if any


@dataclass
class BvhMotion:
    joints: list[BvhJoint]
    frame_time: float
    data: np.ndarray                     # (T, total channels) float64 as read
    names: dict[str, int] = field(default_factory=dict)

    @property
    def fps(self) -> float:
        return 1.0 / self.frame_time

    def world_positions(self) -> tuple[np.ndarray, np.ndarray]:
        """(T, J, 3) joint positions and (T, J, 3) End Site positions (NaN where a joint has none)."""
        t = self.data.shape[0]
        n = len(self.joints)
        glob_r = np.zeros((t, n, 3, 3))
        glob_p = np.zeros((t, n, 3))
        ends = np.full((t, n, 3), np.nan)
        col = 0
        for j, jt in enumerate(self.joints):
            k = len(jt.channels)
            vals = self.data[:, col:col + k]
            col += k
            local_p = np.broadcast_to(jt.offset, (t, 3)).copy()
            rot = np.broadcast_to(np.eye(3), (t, 3, 3)).copy()
            pos_seen = False
            for c, ch in enumerate(jt.channels):
                axis = "xyz".index(ch[0].lower())
                if ch[1:].lower() == "position":
                    if not pos_seen:
                        local_p = np.zeros((t, 3))
                        pos_seen = True
                    local_p[:, axis] = vals[:, c]
                else:
                    rot = rot @ _axis_rotation(axis, np.radians(vals[:, c]))
            if jt.parent < 0:
                glob_r[:, j], glob_p[:, j] = rot, local_p
            else:
                pr = glob_r[:, jt.parent]
                glob_r[:, j] = pr @ rot
                glob_p[:, j] = glob_p[:, jt.parent] + (pr @ local_p[..., None])[..., 0]
            if jt.end_site is not None:
                ends[:, j] = glob_p[:, j] + (glob_r[:, j] @ jt.end_site)
        return glob_p, ends


def _axis_rotation(axis: int, ang: np.ndarray) -> np.ndarray:
    c, s = np.cos(ang), np.sin(ang)
    m = np.zeros(ang.shape + (3, 3))
    a, b = [(1, 2), (2, 0), (0, 1)][axis]
    m[..., axis, axis] = 1.0
    m[..., a, a], m[..., a, b], m[..., b, a], m[..., b, b] = c, -s, s, c
    return m


def read_bvh(path: str | Path) -> BvhMotion:
    path = Path(path)
    try:
        lines = path.read_text(errors="replace").splitlines()
    except OSError as exc:
        raise InputError(f"cannot read BVH file {path}: {exc.strerror}") from None
    joints: list[BvhJoint] = []
    stack: list[int] = []
    i, in_end, pending_end = 0, False, None
    while i < len(lines):
        tok = lines[i].split()
        i += 1
        if not tok:
            continue
        key = tok[0].upper()
        if key in ("ROOT", "JOINT"):
            if len(tok) < 2:
                raise InputError(f"{path.name} line {i}: {key} without a name; the BVH hierarchy is malformed")
            joints.append(BvhJoint(tok[1], stack[-1] if stack else -1, np.zeros(3)))
            pending_end = None
        elif key == "END":
            in_end = True
        elif key == "{":
            if not in_end:
                stack.append(len(joints) - 1)
        elif key == "}":
            if in_end:
                in_end = False
            elif stack:
                stack.pop()
        elif key == "OFFSET":
            try:
                off = np.array([float(v) for v in tok[1:4]])
            except ValueError:
                raise InputError(f"{path.name} line {i}: OFFSET needs three numbers") from None
            if in_end:
                joints[stack[-1]].end_site = off
            else:
                joints[-1].offset = off
        elif key == "CHANNELS":
            joints[-1].channels = tok[2:2 + int(tok[1])]
        elif key == "MOTION":
            break
    if not joints:
        raise InputError(f"{path.name} has no HIERARCHY joints; is it a BVH file?")
    frames, frame_time = None, None
    while i < len(lines):
        tok = lines[i].split()
        i += 1
        if tok[:1] == ["Frames:"]:
            frames = int(tok[1])
        elif tok[:2] == ["Frame", "Time:"]:
            frame_time = float(tok[2])
            break
    if frame_time is None or frame_time <= 0:
        raise InputError(f"{path.name} has no valid 'Frame Time:' line; the MOTION header is malformed")
    nch = sum(len(j.channels) for j in joints)
    rows = [ln for ln in lines[i:] if ln.strip()]
    try:
        data = np.array([[float(v) for v in ln.split()] for ln in rows], dtype=np.float64)
    except ValueError:
        raise InputError(f"{path.name}: non-numeric motion data") from None
    if data.ndim != 2 or data.shape[1] != nch:
        raise InputError(f"{path.name}: motion rows have {data.shape[-1] if data.ndim == 2 else '?'} values, "
                         f"the hierarchy declares {nch} channels")
    if frames is not None and frames != data.shape[0]:
        data = data[:frames]
    if not np.isfinite(data).all():
        raise InputError(f"{path.name}: motion data contains NaN or inf")
    return BvhMotion(joints, frame_time, data, {j.name: k for k, j in enumerate(joints)})


def leading_rest_frame(m: BvhMotion, jump_deg: float = 10.0) -> bool:
    """True when frame 0 is an added rest/T-pose frame (all rotations ~0, then a jump into frame 1)."""
    if m.data.shape[0] < 3:
        return False
    rot_cols = []
    col = 0
    for j in m.joints:
        for ch in j.channels:
            if ch.lower().endswith("rotation"):
                rot_cols.append(col)
            col += 1
    r0, r1 = m.data[0, rot_cols], m.data[1, rot_cols]
    return bool(np.abs(r0).max() < 1e-3 and np.abs(r1 - r0).max() > jump_deg)


def drop_first_frame(m: BvhMotion) -> BvhMotion:
    return BvhMotion(m.joints, m.frame_time, m.data[1:], m.names)

