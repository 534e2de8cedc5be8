"""Bone-name maps from common humanoid rigs to the 22 SMPL-X body joints.

A map sends each SMPL-X joint to a spec:
- a source bone name: the joint sits at that bone's head (BVH/ASF: the joint itself);
- "lerp:A:B:t": the point (1 - t) * head(A) + t * head(B), for rigs with fewer spine bones;
- "end:A": bone A's tail (BVH End Site), for rigs without toe bones.

Matching ignores case, namespaces ("mixamorig:", "Armature|"), separators and how the side is
written ("LeftArm", "left_arm", "Arm.L", "L_Arm" are one name). The maps are plain data so the
Blender UI can show and edit them; `guess_bone_map` picks the family that fits a rig best.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Iterable

from ..errors import InputError
from ..joints import JOINT_NAMES


def _mirror(left: dict[str, list[str]], to_right) -> dict[str, list[str]]:
    """Complete a left-side candidate table with its right side."""
    out = dict(left)
    for joint, specs in left.items():
        if joint.startswith("left_"):
            out["right_" + joint[5:]] = [_map_spec_bones(s, to_right) for s in specs]
    return out


def _map_spec_bones(spec: str, f) -> str:
    if spec.startswith("lerp:"):
        _, a, b, t = spec.split(":")
        return f"lerp:{f(a)}:{f(b)}:{t}"
    if spec.startswith("end:"):
        return "end:" + f(spec[4:])
    return f(spec)


def _swap(a: str, b: str):
    return lambda name: name.replace(a, b)


def _first_letter_lr(name: str) -> str:
    """DAZ/ASF style: 'lThigh' -> 'rThigh', 'lfemur' -> 'rfemur' (spine names have no side)."""
    return "r" + name[1:] if name[:1] == "l" else name


# Candidates per joint, best first. The first candidate is the family's default map (BONE_MAPS);
# later ones cover variants of the same family (DAZ Genesis 3+ bend bones, Rigify metarig names,
# plain BVH exporters that call the collar "LeftCollar"...).
_CANDIDATES: dict[str, dict[str, list[str]]] = {
    "smplx": {j: [j] for j in JOINT_NAMES},
    "bvh_plain": _mirror({
        "pelvis": ["Hips", "Hip", "Pelvis", "Root"], "spine1": ["Spine", "LowerBack", "Abdomen"],
        "spine2": ["Spine1", "lerp:Spine:Chest:0.5", "lerp:Spine:Neck:0.33", "MidBack"],
        "spine3": ["Spine2", "Chest", "UpperChest", "Spine3", "lerp:Spine1:Neck:0.5",
                   "lerp:Spine:Neck:0.67", "UpperBack"],
        "neck": ["Neck", "Neck1", "LowerNeck"], "head": ["Head"],
        "left_hip": ["LeftUpLeg", "LeftThigh", "LeftUpperLeg", "LeftHip"],
        "left_knee": ["LeftLeg", "LeftShin", "LeftLowerLeg", "LeftKnee", "LeftCalf"],
        "left_ankle": ["LeftFoot", "LeftAnkle"],
        "left_foot": ["LeftToeBase", "LeftToe", "LeftToes", "LeftBall", "end:LeftFoot", "end:LeftAnkle"],
        "left_collar": ["LeftCollar", "LeftClavicle", "LeftShoulder"],
        "left_shoulder": ["LeftArm", "LeftUpperArm", "LeftShoulder", "LeftHumerus"],
        "left_elbow": ["LeftForeArm", "LeftLowerArm", "LeftElbow"],
        "left_wrist": ["LeftHand", "LeftWrist"],
    }, _swap("Left", "Right")),
    "mixamo": _mirror({
        "pelvis": ["Hips"], "spine1": ["Spine"], "spine2": ["Spine1"],
        "spine3": ["Spine2", "lerp:Spine1:Neck:0.5"], "neck": ["Neck"], "head": ["Head"],
        "left_hip": ["LeftUpLeg"], "left_knee": ["LeftLeg"], "left_ankle": ["LeftFoot"],
        "left_foot": ["LeftToeBase", "end:LeftFoot"], "left_collar": ["LeftShoulder"],
        "left_shoulder": ["LeftArm"], "left_elbow": ["LeftForeArm"], "left_wrist": ["LeftHand"],
    }, _swap("Left", "Right")),
    "cmu_asf": _mirror({
        "pelvis": ["hip", "root"], "spine1": ["upperback"], "spine2": ["thorax"],
        "spine3": ["lerp:thorax:lowerneck:0.5"], "neck": ["lowerneck"], "head": ["head", "upperneck"],
        "left_hip": ["lfemur"], "left_knee": ["ltibia"], "left_ankle": ["lfoot"],
        "left_foot": ["ltoes", "end:lfoot"], "left_collar": ["lclavicle"], "left_shoulder": ["lhumerus"],
        "left_elbow": ["lradius"], "left_wrist": ["lwrist", "lhand"],
    }, _first_letter_lr),
    "daz": _mirror({
        "pelvis": ["hip"], "spine1": ["abdomen", "abdomenLower"],
        "spine2": ["lerp:abdomen:chest:0.5", "abdomenUpper", "abdomen2"],
        "spine3": ["chest", "chestLower"], "neck": ["neck", "neckLower"], "head": ["head"],
        "left_hip": ["lThigh", "lThighBend"], "left_knee": ["lShin"], "left_ankle": ["lFoot"],
        "left_foot": ["lToe", "end:lFoot"], "left_collar": ["lCollar"],
        "left_shoulder": ["lShldr", "lShldrBend"], "left_elbow": ["lForeArm", "lForearmBend"],
        "left_wrist": ["lHand"],
    }, _first_letter_lr),
    "cc": _mirror({
        "pelvis": ["CC_Base_Hip"], "spine1": ["CC_Base_Waist"], "spine2": ["CC_Base_Spine01"],
        "spine3": ["CC_Base_Spine02"], "neck": ["CC_Base_NeckTwist01"], "head": ["CC_Base_Head"],
        "left_hip": ["CC_Base_L_Thigh"], "left_knee": ["CC_Base_L_Calf"], "left_ankle": ["CC_Base_L_Foot"],
        "left_foot": ["CC_Base_L_ToeBase", "end:CC_Base_L_Foot"], "left_collar": ["CC_Base_L_Clavicle"],
        "left_shoulder": ["CC_Base_L_Upperarm"], "left_elbow": ["CC_Base_L_Forearm"],
        "left_wrist": ["CC_Base_L_Hand"],
    }, _swap("_L_", "_R_")),
    "bandai": _mirror({
        "pelvis": ["Hips"], "spine1": ["Spine"], "spine2": ["lerp:Spine:Chest:0.5"], "spine3": ["Chest"],
        "neck": ["Neck"], "head": ["Head"], "left_hip": ["UpperLeg_L"], "left_knee": ["LowerLeg_L"],
        "left_ankle": ["Foot_L"], "left_foot": ["Toes_L", "end:Foot_L"], "left_collar": ["Shoulder_L"],
        "left_shoulder": ["UpperArm_L"], "left_elbow": ["LowerArm_L"], "left_wrist": ["Hand_L"],
    }, _swap("_L", "_R")),
    "rigify": _mirror({
        "pelvis": ["DEF-spine", "spine"], "spine1": ["DEF-spine.001", "spine.001"],
        "spine2": ["DEF-spine.002", "spine.002"], "spine3": ["DEF-spine.003", "spine.003"],
        "neck": ["DEF-spine.004", "spine.004"], "head": ["DEF-spine.006", "spine.006"],
        "left_hip": ["DEF-thigh.L", "thigh.L"], "left_knee": ["DEF-shin.L", "shin.L"],
        "left_ankle": ["DEF-foot.L", "foot.L"], "left_foot": ["DEF-toe.L", "toe.L"],
        "left_collar": ["DEF-shoulder.L", "shoulder.L"], "left_shoulder": ["DEF-upper_arm.L", "upper_arm.L"],
        "left_elbow": ["DEF-forearm.L", "forearm.L"], "left_wrist": ["DEF-hand.L", "hand.L"],
    }, _swap(".L", ".R")),
    # Unreal Engine mannequin (also what many game rigs export)
    "unreal": _mirror({
        "pelvis": ["pelvis"], "spine1": ["spine_01"], "spine2": ["spine_02"], "spine3": ["spine_03"],
        "neck": ["neck_01"], "head": ["head"], "left_hip": ["thigh_l"], "left_knee": ["calf_l"],
        "left_ankle": ["foot_l"], "left_foot": ["ball_l", "end:foot_l"], "left_collar": ["clavicle_l"],
        "left_shoulder": ["upperarm_l"], "left_elbow": ["lowerarm_l"], "left_wrist": ["hand_l"],
    }, _swap("_l", "_r")),
}

BONE_MAPS: dict[str, dict[str, str]] = {fam: {j: c[0] for j, c in table.items()}
                                        for fam, table in _CANDIDATES.items()}

# Ties are broken by a family's signature in the names (a Mixamo rig is also a plain BVH rig), then
# by the order of _CANDIDATES (plain BVH names before Mixamo's).
_SIGNATURES = {"mixamo": re.compile(r"mixamorig", re.I), "cc": re.compile(r"^cc_base", re.I),
               "rigify": re.compile(r"^(def|org|mch)-", re.I)}
_PREFIX = re.compile(r"^(mixamorig\d*|[mf]_avg)[_:\-. ]*", re.I)
_SIDES = {"l": "L", "left": "L", "r": "R", "right": "R"}


def _strip(name: str) -> str:
    return _PREFIX.sub("", re.split(r"[:|]", name.strip())[-1])


def normalise_name(name: str) -> str:
    """'mixamorig:LeftArm' -> 'leftarm'; 'Armature|DEF-thigh.L' -> 'defthighl'."""
    return re.sub(r"[^a-z0-9]", "", _strip(name).lower())


def side_key(name: str) -> str:
    """Name with its side marker pulled out: 'Arm.L', 'L_Arm', 'left_arm', 'LeftArm' -> 'L|arm'."""
    words = re.sub(r"([a-z0-9])([A-Z])", r"\1 \2", _strip(name))
    tokens = [t for t in re.split(r"[^A-Za-z0-9]+", words.lower()) if t]
    side = ""
    rest = []
    for t in tokens:
        if t in _SIDES and not side:
            side = _SIDES[t]
        else:
            rest.append(t)
    return f"{side}|{''.join(rest)}"


def spec_bones(spec: str) -> list[str]:
    """The source bone names a map entry needs."""
    if spec.startswith("lerp:"):
        return spec.split(":")[1:3]
    if spec.startswith("end:"):
        return [spec[4:]]
    return [spec]


def parse_spec(spec: str) -> tuple[str, list[str], float]:
    """('bone' | 'lerp' | 'end', bones, t); raises InputError for a malformed entry."""
    if spec.startswith("lerp:"):
        parts = spec.split(":")
        try:
            if len(parts) != 4:
                raise ValueError
            t = float(parts[3])
        except ValueError:
            raise InputError(f"bone map entry '{spec}' is malformed; write it as lerp:BoneA:BoneB:0.5") from None
        return "lerp", parts[1:3], t
    if spec.startswith("end:"):
        return "end", [spec[4:]], 1.0
    return "bone", [spec], 0.0


class NameIndex:
    """Looks up a rig's real bone name from any spelling of it."""

    def __init__(self, bone_names: Iterable[str]):
        self.names = list(bone_names)
        self._norm: dict[str, str] = {}
        self._side: dict[str, str] = {}
        for b in self.names:
            self._norm.setdefault(normalise_name(b), b)
            self._side.setdefault(side_key(b), b)

    def find(self, bone: str) -> str | None:
        hit = self._norm.get(normalise_name(bone))
        return hit if hit is not None else self._side.get(side_key(bone))


@dataclass
class BoneMapGuess:
    family: str
    mapping: dict[str, str] = field(default_factory=dict)   # SMPL-X joint -> spec with the rig's own names
    missing: list[str] = field(default_factory=list)        # SMPL-X joints the rig has no bone for
    fallbacks: int = 0                                       # joints that needed a later candidate


def resolve_map(family_map: dict[str, str | list[str]], bone_names: Iterable[str],
                family: str = "", end_sites: Iterable[str] | None = None) -> BoneMapGuess:
    """Resolve a family's specs against a rig: each joint takes its first candidate whose bones exist.

    A bone used directly by one joint is not used directly by another (so "LeftShoulder" is not both
    collar and shoulder). `end_sites` limits "end:" specs to bones with a tail (default: all bones).
    """
    index = NameIndex(bone_names)
    ends = None if end_sites is None else {normalise_name(b) for b in end_sites}
    guess = BoneMapGuess(family)
    used: set[str] = set()
    for joint in JOINT_NAMES:
        specs = family_map.get(joint) or []
        specs = [specs] if isinstance(specs, str) else specs
        for k, spec in enumerate(specs):
            kind, bones, _ = parse_spec(spec)
            real = [index.find(b) for b in bones]
            if any(r is None for r in real):
                continue
            if kind == "bone" and real[0] in used:
                continue
            if kind == "end" and ends is not None and normalise_name(real[0]) not in ends:
                continue
            if kind == "bone":
                used.add(real[0])
            guess.mapping[joint] = _map_spec_bones(spec, dict(zip(bones, real)).get)
            guess.fallbacks += k > 0
            break
        else:
            guess.missing.append(joint)
    return guess


def guess_bone_map(bone_names: Iterable[str], end_sites: Iterable[str] | None = None) -> BoneMapGuess:
    """The family whose map matches the most SMPL-X joints on this rig (ties: fewer fallbacks, then
    the family's naming signature, e.g. a 'mixamorig:' prefix)."""
    names = list(bone_names)
    ends = None if end_sites is None else list(end_sites)
    best, best_score = None, None
    for family, table in _CANDIDATES.items():
        g = resolve_map(table, names, family, ends)
        sig = _SIGNATURES.get(family)
        # a family with a naming signature wins ties only when the rig carries it
        signed = sig is None or any(sig.search(_strip_ns_only(n)) for n in names)
        score = (len(g.mapping), signed, -g.fallbacks)
        if best_score is None or score > best_score:
            best, best_score = g, score
    return best


def _strip_ns_only(name: str) -> str:
    """Armature|mixamorig:Hips -> mixamorig:Hips (keep the prefix a signature looks for)."""
    return name.split("|")[-1]


def validate_bone_map(mapping: dict[str, str], bone_names: Iterable[str], rig: str = "rig") -> None:
    """Raise InputError naming every SMPL-X joint without a usable bone in `bone_names`.

    `rig` names the rig in the message: a plain name is quoted ("rig 'Car'"); a label that already
    has quotes is used as given ("Partner 'Car'").
    """
    index = NameIndex(bone_names)
    label = rig if ("'" in rig or rig == "rig") else f"rig '{rig}'"
    bad = []
    for joint in JOINT_NAMES:
        spec = mapping.get(joint, "")
        if not spec or any(index.find(b) is None for b in parse_spec(spec)[1]):
            bad.append(joint)
    if bad:
        raise InputError(f"{label} is not humanoid enough: no bones for {', '.join(bad)}; "
                         "map them in the bone map")
