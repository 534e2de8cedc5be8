import pytest

from model_runtime.data import bone_maps as bm
from model_runtime.errors import InputError
from model_runtime.skeleton import JOINT_NAMES

SIDES = ("Left", "Right")
MIXAMO = ["Hips", "Spine", "Spine1", "Spine2", "Neck", "Head"] + [
    f"{s}{b}" for s in SIDES for b in ("UpLeg", "Leg", "Foot", "ToeBase", "Shoulder", "Arm", "ForeArm", "Hand")]
RIGIFY = ["DEF-spine", "DEF-spine.001", "DEF-spine.002", "DEF-spine.003", "DEF-spine.004", "DEF-spine.005",
          "DEF-spine.006"] + [f"DEF-{b}.{s}" for s in "LR" for b in
                              ("thigh", "shin", "foot", "toe", "shoulder", "upper_arm", "forearm", "hand")]
CMU_ASF = ["hip", "lowerback", "upperback", "thorax", "lowerneck", "upperneck", "head"] + [
    f"{s}{b}" for s in "lr" for b in ("hipjoint", "femur", "tibia", "foot", "toes", "clavicle", "humerus",
                                      "radius", "wrist", "hand", "fingers", "thumb")]
BANDAI = ["joint_Root", "Hips", "Spine", "Chest", "Neck", "Head"] + [
    f"{b}_{s}" for s in "LR" for b in ("UpperLeg", "LowerLeg", "Foot", "Toes", "Shoulder", "UpperArm",
                                       "LowerArm", "Hand")]
CC = ["CC_Base_Hip", "CC_Base_Pelvis", "CC_Base_Waist", "CC_Base_Spine01", "CC_Base_Spine02",
      "CC_Base_NeckTwist01", "CC_Base_NeckTwist02", "CC_Base_Head"] + [
    f"CC_Base_{s}_{b}" for s in "LR" for b in ("Thigh", "Calf", "Foot", "ToeBase", "Clavicle", "Upperarm",
                                               "Forearm", "Hand", "ThighTwist01", "UpperarmTwist01")]
DAZ = ["hip", "abdomen", "chest", "neck", "head"] + [
    f"{s}{b}" for s in "lr" for b in ("Collar", "Shldr", "ForeArm", "Hand", "Buttock", "Thigh", "Shin", "Foot")]


@pytest.mark.parametrize("names, family", [
    (["mixamorig:" + n for n in MIXAMO], "mixamo"),
    (["Armature|mixamorig1:" + n for n in MIXAMO], "mixamo"),
    (MIXAMO, "bvh_plain"),
    (RIGIFY, "rigify"),
    (CMU_ASF, "cmu_asf"),
    (BANDAI, "bandai"),
    (CC, "cc"),
    (DAZ, "daz"),
    (list(JOINT_NAMES), "smplx"),
])
def test_families_are_recognised_whole(names, family):
    g = bm.guess_bone_map(names)
    assert g.family == family and g.missing == []
    bm.validate_bone_map(g.mapping, names)
    # the map names the rig's own bones, so a caller can look them up verbatim
    for spec in g.mapping.values():
        assert all(b in names for b in bm.spec_bones(spec))


def test_mixamo_map_uses_the_rigs_spelling():
    names = ["mixamorig:" + n for n in MIXAMO]
    g = bm.guess_bone_map(names)
    assert g.mapping["left_knee"] == "mixamorig:LeftLeg"
    assert g.mapping["right_collar"] == "mixamorig:RightShoulder"
    assert g.mapping["right_shoulder"] == "mixamorig:RightArm"


def test_matching_tolerates_case_separators_and_side_spelling():
    assert bm.side_key("mixamorig:LeftArm") == bm.side_key("left_arm") == bm.side_key("Arm.L") == "L|arm"
    assert bm.side_key("Armature|RightForeArm") == bm.side_key("forearm_R") == "R|forearm"
    snake = ["hips", "spine", "spine1", "spine2", "neck", "head"] + [
        f"{s}_{b}" for s in ("left", "right") for b in ("up_leg", "leg", "foot", "toe_base", "shoulder", "arm",
                                                         "fore_arm", "hand")]
    g = bm.guess_bone_map(snake)
    assert g.missing == [] and g.mapping["left_elbow"] == "left_fore_arm"


def test_short_spine_gets_an_interpolated_joint():
    names = ["Hips", "Spine", "Chest", "Neck", "Head"] + [
        f"{s}{b}" for s in SIDES for b in ("UpLeg", "Leg", "Foot", "ToeBase", "Shoulder", "Arm", "ForeArm", "Hand")]
    g = bm.guess_bone_map(names)
    assert g.missing == []
    assert g.mapping["spine2"] == "lerp:Spine:Chest:0.5" and g.mapping["spine3"] == "Chest"


def test_collar_and_shoulder_never_share_a_bone():
    # exporters that call the collar "LeftCollar" and the upper arm "LeftShoulder"
    names = ["Hips", "Spine", "Spine1", "Spine2", "Neck", "Head"] + [
        f"{s}{b}" for s in SIDES for b in ("Hip", "Knee", "Ankle", "Toe", "Collar", "Shoulder", "Elbow", "Wrist")]
    g = bm.guess_bone_map(names)
    assert g.missing == []
    assert g.mapping["left_collar"] == "LeftCollar" and g.mapping["left_shoulder"] == "LeftShoulder"


def test_end_sites_stand_in_for_missing_toes():
    names = [n for n in MIXAMO if "ToeBase" not in n]
    assert bm.guess_bone_map(names).mapping["left_foot"] == "end:LeftFoot"
    # a reader that knows which bones have tails can say so; without one the toes are missing
    assert "left_foot" in bm.guess_bone_map(names, end_sites=[]).missing


def test_non_humanoid_rig_reports_missing_joints():
    car = ["Body", "Wheel.FL", "Wheel.FR", "Wheel.BL", "Wheel.BR", "Steering"]
    g = bm.guess_bone_map(car)
    assert {"pelvis", "left_knee", "right_knee"} <= set(g.missing)
    with pytest.raises(InputError, match=r"^rig 'Car' is not humanoid enough: no bones for pelvis, .*"
                                         r"; map them in the bone map$"):
        bm.validate_bone_map(g.mapping, car, rig="Car")


def test_partial_rig_names_only_its_gaps():
    names = [n for n in MIXAMO if not n.endswith("Leg")]      # no knees, no thighs
    g = bm.guess_bone_map(names)
    assert set(g.missing) == {"left_hip", "right_hip", "left_knee", "right_knee"}
    with pytest.raises(InputError, match="no bones for left_hip, right_hip, left_knee, right_knee;"):
        bm.validate_bone_map(g.mapping, names, rig="Partner 'Bob'")


def test_bad_lerp_entry_is_explained():
    mapping = dict(bm.guess_bone_map(MIXAMO).mapping, spine2="lerp:Spine:Spine2")
    with pytest.raises(InputError, match="lerp:BoneA:BoneB:0.5"):
        bm.validate_bone_map(mapping, MIXAMO)


def test_default_maps_cover_every_joint():
    for family, table in bm.BONE_MAPS.items():
        assert set(table) == set(JOINT_NAMES), family
