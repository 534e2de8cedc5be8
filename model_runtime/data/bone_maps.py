"""Bone-name maps from common humanoid rigs to the 22 SMPL-X body joints.

A map sends each SMPL-X joint to a source bone name, to "lerp:A:B:t" (a point between two bones'
heads, for rigs with fewer spine bones) or to "end:A" (bone A's end / BVH End Site, for rigs without
toe bones). Matching ignores case, namespace prefixes ("mixamorig:", "Armature|") and separators.
The maps are plain data so the Blender UI can show and edit them.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Iterable

from ..errors import InputError
from ..skeleton import JOINT_NAMES


def _sided(left: dict[str, str], right_of) -> dict[str, str]:
    out = dict(left)
    for j, b in left.items():
        if j.startswith("left_"):
            out["right_" + j[5:]] = right_of(b)
    return out


def _swap(a: str, b: str):
    def f(name: str) -> str:
        return name.replace(a, b)
    return f


_SMPLX = {j: j for j in JOINT_NAMES}

_DAZ = _sided({
    "pelvis": "hip", "spine1": "abdomen", "spine2": "lerp:abdomen:chest:0.5", "spine3": "chest",
    "neck": "neck", "head": "head", "left_hip": "lThigh", "left_knee": "lShin", "left_ankle": "lFoot",
    "left_foot": "end:lFoot", "left_collar": "lCollar", "left_shoulder": "lShldr", "left_elbow": "lForeArm",
    "left_wrist": "lHand"}, lambda b: "end:r" + b[5:] if b.startswith("end:") else "r" + b[1:])

_CC = _sided({
    "pelvis": "CC_Base_Hip", "spine1": "CC_Base_Waist", "spine2": "CC_Base_Spine01", "spine3": "CC_Base_Spine02",
    "neck": "CC_Base_NeckTwist01", "head": "CC_Base_Head", "left_hip": "CC_Base_L_Thigh",
    "left_knee": "CC_Base_L_Calf", "left_ankle": "CC_Base_L_Foot", "left_foot": "CC_Base_L_ToeBase",
    "left_collar": "CC_Base_L_Clavicle", "left_shoulder": "CC_Base_L_Upperarm", "left_elbow": "CC_Base_L_Forearm",
    "left_wrist": "CC_Base_L_Hand"}, _swap("_L_", "_R_"))

_BANDAI = _sided({
    "pelvis": "Hips", "spine1": "Spine", "spine2": "lerp:Spine:Chest:0.5", "spine3": "Chest", "neck": "Neck",
    "head": "Head", "left_hip": "UpperLeg_L", "left_knee": "LowerLeg_L", "left_ankle": "Foot_L",
    "left_foot": "Toes_L", "left_collar": "Shoulder_L", "left_shoulder": "UpperArm_L", "left_elbow": "LowerArm_L",
    "left_wrist": "Hand_L"}, _swap("_L", "_R"))

_CMU_ASF = _sided({
    "pelvis": "hip", "spine1": "upperback", "spine2": "thorax", "spine3": "lerp:thorax:lowerneck:0.5",
    "neck": "lowerneck", "head": "head", "left_hip": "lfemur", "left_knee": "ltibia", "left_ankle": "lfoot",
    "left_foot": "ltoes", "left_collar": "lclavicle", "left_shoulder": "lhumerus", "left_elbow": "lradius",
    "left_wrist": "lwrist"}, lambda b: b.replace(":l", ":r") if b.startswith("lerp") else "r" + b[1:])

_MIXAMO = _sided({
    "pelvis": "Hips", "spine1": "Spine", "spine2": "Spine1", "spine3": "Spine2", "neck": "Neck", "head": "Head",
    "left_hip": "LeftUpLeg", "left_knee": "LeftLeg", "left_ankle": "LeftFoot", "left_foot": "LeftToeBase",
    "left_collar": "LeftShoulder", "left_shoulder": "LeftArm", "left_elbow": "LeftForeArm",
    "left_wrist": "LeftHand"}, _swap("Left", "Right"))

_RIGIFY = _sided({
    "pelvis": "DEF-spine", "spine1": "DEF-spine.001", "spine2": "DEF-spine.002", "spine3": "DEF-spine.003",
    "neck": "DEF-spine.004", "head": "DEF-spine.006", "left_hip": "DEF-thigh.L", "left_knee": "DEF-shin.L",
    "left_ankle": "DEF-foot.L", "left_foot": "DEF-toe.L", "left_collar": "DEF-shoulder.L",
    "left_shoulder": "DEF-upper_arm.L", "left_elbow": "DEF-forearm.L", "left_wrist": "DEF-hand.L"},
    _swap(".L", ".R"))

BONE_MAPS: dict[str, dict[str, str]] = {
    "smplx": _SMPLX, "mixamo": _MIXAMO, "bvh_plain": _MIXAMO, "daz": _DAZ, "cc": _CC, "bandai": _BANDAI,
    "cmu_asf": _CMU_ASF, "rigify": _RIGIFY,
}


def normalise_name(name: str) -> str:
    """'mixamorig:LeftArm' -> 'leftarm'; 'Armature|DEF-thigh.L' -> 'defthighl'."""
    name = re.split(r"[:|]", name)[-1]
    return re.sub(r"[^a-z0-9]", "", name.lower())


def spec_bones(spec: str) -> list[str]:
    """The source bone names a map entry needs."""
    if spec.startswith("lerp:"):
        return spec.split(":")[1:3]
    if spec.startswith("end:"):
        return [spec[4:]]
    return [spec]


@dataclass
class BoneMapGuess:
    family: str
    mapping: dict[str, str]      # SMPL-X joint -> spec with the rig's own bone names
    missing: list[str]           # SMPL-X joints the rig has no bone for


def resolve_map(family_map: dict[str, str], bone_names: Iterable[str]) -> BoneMapGuess:
    by_norm = {normalise_name(b): b for b in bone_names}

    def real(b: str) -> str | None:
        return by_norm.get(normalise_name(b))

    mapping, missing = {}, []
    for joint in JOINT_NAMES:
        spec = family_map.get(joint)
        bones = [real(b) for b in spec_bones(spec)] if spec else [None]
        if any(b is None for b in bones):
            missing.append(joint)
            continue
        if spec.startswith("lerp:"):
            mapping[joint] = f"lerp:{bones[0]}:{bones[1]}:{spec.split(':')[3]}"
        elif spec.startswith("end:"):
            mapping[joint] = f"end:{bones[0]}"
        else:
            mapping[joint] = bones[0]
    return BoneMapGuess("", mapping, missing)


def guess_bone_map(bone_names: Iterable[str]) -> BoneMapGuess:
    """The family whose map matches most of the rig's bones."""
    names = list(bone_names)
    best: BoneMapGuess | None = None
    for family, fmap in BONE_MAPS.items():
        g = resolve_map(fmap, names)
        g.family = family
        if best is None or len(g.missing) < len(best.missing):
            best = g
    return best


def validate_bone_map(mapping: dict[str, str], bone_names: Iterable[str], rig: str = "rig") -> None:
    """Raise InputError naming the SMPL-X joints without a usable bone."""
    norm = {normalise_name(b) for b in bone_names}
    bad = [j for j in JOINT_NAMES if j not in mapping
           or any(normalise_name(b) not in norm for b in spec_bones(mapping[j]))]
    if bad:
        raise InputError(f"{rig} is not humanoid enough: no bones for {', '.join(bad[:6])}"
                         f"{' ...' if len(bad) > 6 else ''}; map them in the bone map")
