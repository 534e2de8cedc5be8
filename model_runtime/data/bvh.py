"""BVH reader: any hierarchy, 3 or 6 (or any) channels per joint, any rotation order per joint.

Returns the source skeleton's world joint positions per frame in the file's own units and axes
(retargeting converts units, up axis and skeleton). Rotation channels compose in the order listed:
"Zrotation Xrotation Yrotation" means R = Rz @ Rx @ Ry. A joint with position channels uses them as
its local translation (Bandai files give every joint 6 channels), otherwise its OFFSET.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..errors import InputError
from .geometry import euler_matrix

_CHANNELS = {f"{a}{k}" for a in "xyz" for k in ("position", "rotation")}


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

    @property
    def fps(self) -> float:
        return 1.0 / self.frame_time

    def _columns(self) -> list[tuple[int, int, str]]:
        """(joint, data column, channel name lower-cased) for every channel."""
        out, col = [], 0
        for j, jt in enumerate(self.joints):
            for ch in jt.channels:
                out.append((j, col, ch.lower()))
                col += 1
        return out

    def world_positions(self) -> tuple[np.ndarray, np.ndarray]:
        """(T, J, 3) joint positions and (T, J, 3) End Site positions (NaN where a joint has none)."""
        t, n = self.data.shape[0], len(self.joints)
        glob_r = np.zeros((t, n, 3, 3))
        glob_p = np.zeros((t, n, 3))
        ends = np.full((t, n, 3), np.nan)
        cols = self._columns()
        for j, jt in enumerate(self.joints):
            local_p = np.broadcast_to(jt.offset, (t, 3)).copy()
            mine = [(c, ch) for jj, c, ch in cols if jj == j]
            pos = [(c, "xyz".index(ch[0])) for c, ch in mine if ch.endswith("position")]
            if pos:                             # position channels replace the OFFSET as a whole
                local_p[:] = 0.0
                for c, axis in pos:
                    local_p[:, axis] = self.data[:, c]
            turns = [(c, ch[0]) for c, ch in mine if ch.endswith("rotation")]
            rot = euler_matrix(self.data[:, [c for c, _ in turns]], "".join(a for _, a in turns))
            if jt.parent < 0:
                glob_r[:, j], glob_p[:, j] = rot, local_p
            else:
                pr = glob_r[:, jt.parent]
                glob_r[:, j] = pr @ rot
                glob_p[:, j] = glob_p[:, jt.parent] + (pr @ local_p[..., None])[..., 0]
            if jt.end_site is not None:
                ends[:, j] = glob_p[:, j] + glob_r[:, j] @ jt.end_site
        return glob_p, ends

    def rest_lead_in(self, rest_deg: float = 5.0, jump_deg: float = 10.0, max_s: float = 0.1) -> int:
        """How many leading frames to drop: 0, or 1 + the lead-in when frame 0 is an added rest pose.

        Frame 0 counts as added when the pose jumps by more than `jump_deg` into frame 1 and either
        - every rotation channel that moves in the clip is within `rest_deg` of 0 (channels that never
          move, like uncaptured fingers, say nothing): the DAZ-friendly CMU files; or
        - it is a hand-written T-pose: every rotation a whole number of degrees, the root where it is in
          frame 1 (the MotionBuilder-friendly CMU files, whose rest pose turns the shoulders by 21 deg).
        The DAZ-friendly files then blend from the rest pose into the capture over a few frames; those
        frames, changing far faster than anything later, go too (at most `max_s` seconds)."""
        cols = self._columns()
        rot = [c for _, c, ch in cols if ch.endswith("rotation")]
        if self.data.shape[0] < 4 or not rot:
            return 0
        r = self.data[:, rot]
        moving = np.ptp(r, axis=0) > 1e-3
        if not moving.any():
            return 0
        near_zero = np.abs(r[0, moving]).max() <= rest_deg
        root_pos = [c for j, c, ch in cols if j == 0 and ch.endswith("position")]
        written = bool(np.all(r[0] == np.round(r[0]))) and bool(root_pos) and \
            np.allclose(self.data[0, root_pos], self.data[1, root_pos], rtol=0.0, atol=1e-4)
        if not (near_zero or written):
            return 0
        step = np.abs((np.diff(r[:, moving], axis=0) + 180.0) % 360.0 - 180.0).max(axis=1)  # (T-1,)
        if step[0] <= jump_deg:
            return 0
        typical = float(np.median(step[1:]))
        drop, limit = 1, 1 + int(round(max_s * self.fps))
        while drop < min(limit, len(step)) and step[drop] > max(3.0 * typical, jump_deg / 2):
            drop += 1
        return drop

    def drop_frames(self, n: int) -> "BvhMotion":
        return replace(self, data=self.data[n:])

    def looks_like_amc2bvh(self) -> bool:
        """CMU ASF joint names with a 30 fps header: the amc2bvh default that hides 120 fps captures."""
        names = {j.name.lower() for j in self.joints}
        return abs(self.fps - 30.0) < 0.5 and {"lfemur", "ltibia", "lhumerus", "thorax"} <= names


def _numbers(tok: list[str], n: int, name: str, line: int, what: str) -> np.ndarray:
    try:
        vals = [float(v) for v in tok[:n]]
    except ValueError:
        vals = []
    if len(vals) != n:
        raise InputError(f"bad BVH line {line} in {name}: {what} needs {n} numbers")
    return np.array(vals)


def read_bvh(path: str | Path) -> BvhMotion:
    """Parse a BVH file; every problem is an InputError naming the line."""
    path = Path(path)
    try:
        lines = path.read_text(errors="replace").splitlines()
    except OSError as exc:
        raise InputError(f"cannot read BVH file {path}: {exc.strerror}") from None
    joints: list[BvhJoint] = []
    stack: list[int] = []            # open joint blocks
    depth_end = 0                    # >0 while inside an End Site block
    pending: str | None = None       # what the next '{' opens: 'joint' or 'end'
    i = 0
    while i < len(lines):
        tok = lines[i].split()
        i += 1
        if not tok:
            continue
        key = tok[0].upper()
        if key in ("HIERARCHY",):
            continue
        if key in ("ROOT", "JOINT"):
            if len(tok) < 2:
                raise InputError(f"bad BVH line {i} in {path.name}: {key} without a name")
            if key == "JOINT" and not stack:
                raise InputError(f"bad BVH line {i} in {path.name}: JOINT outside any parent block")
            joints.append(BvhJoint(" ".join(tok[1:]), stack[-1] if stack else -1, np.zeros(3)))
            pending = "joint"
        elif key == "END":
            if not stack:
                raise InputError(f"bad BVH line {i} in {path.name}: End Site outside any joint")
            pending = "end"
        elif key == "{":
            if pending == "end" or depth_end:
                depth_end += 1
            elif pending == "joint":
                stack.append(len(joints) - 1)
            else:
                raise InputError(f"bad BVH line {i} in {path.name}: '{{' without a joint")
            pending = None
        elif key == "}":
            if depth_end:
                depth_end -= 1
            elif stack:
                stack.pop()
            else:
                raise InputError(f"bad BVH line {i} in {path.name}: unmatched '}}'")
        elif key == "OFFSET":
            off = _numbers(tok[1:], 3, path.name, i, "OFFSET")
            if depth_end:
                joints[stack[-1]].end_site = off
            elif joints:
                joints[-1].offset = off
        elif key == "CHANNELS":
            try:
                n = int(tok[1])
            except (ValueError, IndexError):
                n = -1
            chans = tok[2:]
            if n < 0 or len(chans) != n or not joints or any(c.lower() not in _CHANNELS for c in chans):
                raise InputError(f"bad BVH line {i} in {path.name}: CHANNELS needs a count and that many "
                                 "X/Y/Z position/rotation names")
            joints[-1].channels = chans
        elif key == "MOTION":
            break
        else:
            raise InputError(f"bad BVH line {i} in {path.name}: unexpected '{tok[0]}' in the HIERARCHY")
    if not joints:
        raise InputError(f"{path.name} has no HIERARCHY joints; is it a BVH file?")
    if stack or depth_end:
        raise InputError(f"{path.name}: the HIERARCHY has unclosed '{{' blocks; the file is truncated or malformed")
    frames, frame_time = None, None
    while i < len(lines) and frame_time is None:
        tok = lines[i].split()
        i += 1
        if tok[:1] == ["Frames:"]:
            frames = int(_numbers(tok[1:], 1, path.name, i, "Frames:")[0])
        elif tok[:2] == ["Frame", "Time:"]:
            frame_time = float(_numbers(tok[2:], 1, path.name, i, "Frame Time:")[0])
        elif tok:
            raise InputError(f"bad BVH line {i} in {path.name}: expected 'Frames:' and 'Frame Time:'")
    if frame_time is None or not frame_time > 0:
        raise InputError(f"{path.name} has no valid 'Frame Time:' line; the MOTION header is malformed")
    data = _motion_rows(lines, i, sum(len(j.channels) for j in joints), path.name)
    if frames is not None and data.shape[0] > frames:
        data = data[:frames]           # trailing junk after the declared frames
    if data.shape[0] == 0:
        raise InputError(f"{path.name} has no motion frames")
    if not np.isfinite(data).all():
        bad = int(np.argwhere(~np.isfinite(data))[0, 0])
        raise InputError(f"{path.name}: motion frame {bad} contains NaN or inf values; fix or trim the file")
    return BvhMotion(joints, frame_time, data)


def _motion_rows(lines: list[str], start: int, nch: int, name: str) -> np.ndarray:
    """Frame rows -> (T, nch). Rows must hold nch numbers each (tabs, trailing blanks are fine)."""
    rows = []
    for k in range(start, len(lines)):
        tok = lines[k].split()
        if not tok:
            continue
        if len(tok) != nch:
            raise InputError(f"bad BVH line {k + 1} in {name}: {len(tok)} values, the hierarchy declares "
                             f"{nch} channels")
        try:
            rows.append([float(v) for v in tok])
        except ValueError:
            raise InputError(f"bad BVH line {k + 1} in {name}: non-numeric motion data") from None
    return np.array(rows, dtype=np.float64).reshape(-1, nch)
