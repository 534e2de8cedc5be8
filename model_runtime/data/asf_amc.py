"""Acclaim ASF (skeleton) + AMC (motion) reader, as used by the CMU database.

Each ASF bone has a direction and length in the root's frame at rest, an `axis` (its local frame as
Euler angles) and the degrees of freedom the AMC file animates. A bone's world rotation is
    R = R_parent @ C @ M(dofs) @ C^-1,   C = Euler(axis),   M = Rz @ Ry @ Rx of the dof angles,
and its end point is start + length * R @ direction. The root's TX TY TZ / RX RY RZ follow its
`order`. Positions are returned per bone *start* (the parent's end), which is where BVH converters put
the same-named joints, so the "cmu_asf" bone map serves both formats.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from .geometry import euler_matrix


def _euler(angles_deg: np.ndarray, order: str = "XYZ") -> np.ndarray:
    """(..., 3) angles for axes in `order` -> R = R_order[2] @ R_order[1] @ R_order[0] (applied first axis first)."""
    return euler_matrix(np.asarray(angles_deg)[..., ::-1], order[::-1])


@dataclass
class AsfBone:
    name: str
    direction: np.ndarray
    length: float
    axis: np.ndarray
    axis_order: str = "XYZ"
    dof: list[str] = field(default_factory=list)
    parent: str = "root"


@dataclass
class AsfSkeleton:
    bones: dict[str, AsfBone]
    order: list[str]                  # parents before children
    length_scale: float               # ':units length' (CMU: 0.45)
    angle_deg: bool
    root_order: list[str]
    root_axis: str
    root_position: np.ndarray
    root_orientation: np.ndarray

    @property
    def metres_per_unit(self) -> float:
        """Acclaim lengths are inches times ':units length' (CMU: 0.45, so 1 unit = 5.644 cm)."""
        return 0.0254 / self.length_scale


def read_asf(path: str | Path) -> AsfSkeleton:
    path = Path(path)
    try:
        lines = path.read_text(errors="replace").splitlines()
    except OSError as exc:
        raise InputError(f"cannot read ASF file {path}: {exc.strerror}") from None
    bones: dict[str, AsfBone] = {}
    section, cur = "", None
    length_scale, angle_deg = 1.0, True
    root_order, root_axis = ["TX", "TY", "TZ", "RX", "RY", "RZ"], "XYZ"
    root_pos, root_ori = np.zeros(3), np.zeros(3)
    children: dict[str, list[str]] = {}
    for n, raw in enumerate(lines, 1):
        tok = raw.split()
        if not tok or tok[0].startswith("#"):
            continue
        if tok[0].startswith(":"):
            section = tok[0][1:].lower()
            continue
        try:
            if section == "units":
                if tok[0] == "length":
                    length_scale = float(tok[1])
                elif tok[0] == "angle":
                    angle_deg = tok[1].lower().startswith("deg")
            elif section == "root":
                if tok[0] == "order":
                    root_order = [t.upper() for t in tok[1:]]
                elif tok[0] == "axis":
                    root_axis = tok[1].upper()
                elif tok[0] == "position":
                    root_pos = np.array([float(v) for v in tok[1:4]])
                elif tok[0] == "orientation":
                    root_ori = np.array([float(v) for v in tok[1:4]])
            elif section == "bonedata":
                if tok[0] == "begin":
                    cur = AsfBone("", np.zeros(3), 0.0, np.zeros(3))
                elif tok[0] == "end" and cur is not None:
                    bones[cur.name] = cur
                    cur = None
                elif cur is not None and tok[0] == "name":
                    cur.name = tok[1]
                elif cur is not None and tok[0] == "direction":
                    cur.direction = np.array([float(v) for v in tok[1:4]])
                elif cur is not None and tok[0] == "length":
                    cur.length = float(tok[1])
                elif cur is not None and tok[0] == "axis":
                    cur.axis = np.array([float(v) for v in tok[1:4]])
                    cur.axis_order = tok[4].upper() if len(tok) > 4 else "XYZ"
                elif cur is not None and tok[0] == "dof":
                    cur.dof = [t.lower() for t in tok[1:]]
            elif section == "hierarchy" and tok[0] not in ("begin", "end"):
                children.setdefault(tok[0], []).extend(tok[1:])
        except (ValueError, IndexError):
            raise InputError(f"{path.name} line {n}: cannot read '{raw.strip()}'") from None
    if not bones:
        raise InputError(f"{path.name} has no :bonedata; is it an ASF skeleton file?")
    order, queue = [], ["root"]
    while queue:
        p = queue.pop(0)
        for c in children.get(p, []):
            if c not in bones:
                raise InputError(f"{path.name}: hierarchy names bone '{c}' that :bonedata does not define")
            bones[c].parent = p
            order.append(c)
            queue.append(c)
    return AsfSkeleton(bones, order, length_scale, angle_deg, root_order, root_axis, root_pos, root_ori)


def read_amc(path: str | Path, skel: AsfSkeleton) -> dict[str, np.ndarray]:
    """{bone or 'root': (T, n values)} in file order of each bone's dofs."""
    path = Path(path)
    try:
        lines = path.read_text(errors="replace").splitlines()
    except OSError as exc:
        raise InputError(f"cannot read AMC file {path}: {exc.strerror}") from None
    frames: list[dict[str, list[float]]] = []
    for n, raw in enumerate(lines, 1):
        tok = raw.split()
        if not tok or tok[0].startswith((":", "#")):
            continue
        if len(tok) == 1 and tok[0].isdigit():
            frames.append({})
            continue
        if not frames:
            raise InputError(f"{path.name} line {n}: values before the first frame number")
        try:
            frames[-1][tok[0]] = [float(v) for v in tok[1:]]
        except ValueError:
            raise InputError(f"{path.name} line {n}: non-numeric values for '{tok[0]}'") from None
    if not frames:
        raise InputError(f"{path.name} has no frames; is it an AMC motion file?")
    out: dict[str, np.ndarray] = {}
    for name in ["root"] + skel.order:
        width = len(skel.root_order) if name == "root" else len(skel.bones[name].dof)
        arr = np.zeros((len(frames), width))
        for i, fr in enumerate(frames):
            if name in fr:
                vals = fr[name][:width]
                arr[i, :len(vals)] = vals
        if not np.isfinite(arr).all():
            raise InputError(f"{path.name}: values for '{name}' contain NaN or inf; fix or trim the file")
        out[name] = arr
    return out


def asf_amc_positions(skel: AsfSkeleton, motion: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """(T, J, 3) bone start positions, (T, J, 3) end positions (for end sites), names ('hip' = root)."""
    root = motion["root"]
    t = root.shape[0]
    vals = dict(zip(skel.root_order, root.T))
    pos = np.stack([vals.get(k, np.zeros(t)) for k in ("TX", "TY", "TZ")], -1) + skel.root_position
    rot_angles = np.stack([vals.get(k, np.zeros(t)) for k in ("RX", "RY", "RZ")], -1)
    if not skel.angle_deg:
        rot_angles = np.degrees(rot_angles)
    rorder = "".join(k[1] for k in skel.root_order if k.startswith("R")) or "XYZ"
    c_root = _euler(skel.root_orientation, skel.root_axis)
    rot_by_order = np.stack([rot_angles[:, "XYZ".index(a)] for a in rorder], -1)
    world_r = {"root": c_root @ _euler(rot_by_order, rorder) @ c_root.T}
    end = {"root": pos}
    names, starts, ends = ["hip"], [pos], [pos]
    for name in skel.order:
        b = skel.bones[name]
        c = _euler(b.axis, b.axis_order)
        angles = np.zeros((t, 3))
        dof_vals = motion[name]
        for k, d in enumerate(b.dof):
            if d in ("rx", "ry", "rz"):
                angles[:, "xyz".index(d[1])] = dof_vals[:, k]
        if not skel.angle_deg:
            angles = np.degrees(angles)
        m = c @ _euler(angles, "XYZ") @ c.T
        r = world_r[b.parent] @ m
        start = end[b.parent]
        stop = start + b.length * (r @ b.direction)
        world_r[name], end[name] = r, stop
        names.append(name)
        starts.append(start)
        ends.append(stop)
    return np.stack(starts, 1), np.stack(ends, 1), names
