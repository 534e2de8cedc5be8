import math

import numpy as np
import pytest

from model_runtime.data import bone_maps as bm
from model_runtime.data.bvh import read_bvh
from model_runtime.data.captions import bandai_caption, cmu_caption, hdm05_caption
from model_runtime.data.motion import load_motion, resample_positions
from model_runtime.errors import InputError
from model_runtime.skeleton import JOINT_NAMES
from paths import SHARED

CHAIN_BVH = """HIERARCHY
ROOT Hips
{{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition {order}
  JOINT Spine
  {{
    OFFSET 0 10 0
    CHANNELS {n} {spine_channels}
    End Site
    {{
      OFFSET 0 5 0
    }}
  }}
}}
MOTION
Frames: 2
Frame Time: 0.0333333
{rows}
"""


def euler_matrix(order, angles):
    m = np.eye(3)
    for ax, a in zip(order, np.radians(angles)):
        c, s = math.cos(a), math.sin(a)
        r = {"X": [[1, 0, 0], [0, c, -s], [0, s, c]], "Y": [[c, 0, s], [0, 1, 0], [-s, 0, c]],
             "Z": [[c, -s, 0], [s, c, 0], [0, 0, 1]]}[ax]
        m = m @ np.array(r)
    return m


def write_chain(tmp_path, order, angles, name, six=False):
    chans = " ".join(f"{a}rotation" for a in order)
    spine = ("Xposition Yposition Zposition " + chans) if six else chans
    spine_vals = ("0 10 0 " if six else "") + " ".join(str(v) for v in angles)
    row = f"1 2 3 {' '.join(str(v) for v in angles)} {spine_vals}"
    p = tmp_path / name
    p.write_text(CHAIN_BVH.format(order=chans, n=6 if six else 3, spine_channels=spine, rows=row + "\n" + row))
    return p


def test_rotation_order_is_respected(tmp_path):
    target = euler_matrix("ZXY", [30, 20, -40])
    # the same rotation expressed in two channel orders must give the same joints
    zxy = read_bvh(write_chain(tmp_path, "ZXY", [30, 20, -40], "a.bvh"))
    from scipy.spatial.transform import Rotation
    xyz_angles = Rotation.from_matrix(target).as_euler("XYZ", degrees=True)
    xyz = read_bvh(write_chain(tmp_path, "XYZ", list(xyz_angles), "b.bvh"))
    pa, ea = zxy.world_positions()
    pb, eb = xyz.world_positions()
    assert np.allclose(pa, pb, atol=1e-6) and np.allclose(ea[:, 1], eb[:, 1], atol=1e-6)
    assert np.allclose(pa[0, 1], np.array([1, 2, 3]) + target @ [0, 10, 0], atol=1e-6)
    assert np.allclose(ea[0, 1], pa[0, 1] + target @ target @ [0, 5, 0], atol=1e-6)


def test_six_channel_joints_parse(tmp_path):
    m = read_bvh(write_chain(tmp_path, "ZXY", [0, 0, 90], "six.bvh", six=True))
    assert len(m.joints[1].channels) == 6
    p, _ = m.world_positions()
    assert np.allclose(p[0, 1], [1, 2, 3] + euler_matrix("ZXY", [0, 0, 90]) @ [0, 10, 0], atol=1e-6)


def test_bad_bvh_says_what(tmp_path):
    p = tmp_path / "bad.bvh"
    p.write_text("HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 3 Zrotation Xrotation Yrotation\n}\n"
                 "MOTION\nFrames: 1\nFrame Time: 0.1\n1 2\n")
    with pytest.raises(InputError, match="3 channels"):
        read_bvh(p)
    with pytest.raises(InputError, match="unknown motion file type"):
        load_motion(tmp_path / "x.fbx")


def test_resampling_frame_counts():
    x = np.arange(121, dtype=float)[:, None]
    assert resample_positions(x, 120.0).shape[0] == 11          # 1 s at 120 fps -> 11 frames at 10 fps
    assert resample_positions(np.arange(31.0)[:, None], 30.0).shape[0] == 11
    assert np.allclose(resample_positions(x, 120.0)[:, 0], np.arange(0, 121, 12))


def check_walk(m, lo=0.7, hi=2.0):
    assert m.fps == 10
    j = m.joints
    assert (j[:, 15, 2] > j[:, 0, 2]).all() and (j[:, 0, 2] > j[:, [7, 8], 2].max(1)).all()   # upright
    assert abs(float(j[:, [7, 8, 10, 11], 2].min()) - 0.0) < 0.03                               # soles on floor
    speed = np.linalg.norm(np.diff(m.root[:, :2, 3], axis=0), axis=1).mean() * 10
    assert lo < speed < hi
    assert np.allclose(np.linalg.norm(m.local_rotations, axis=-1), 1, atol=1e-4)


@pytest.mark.parametrize("rel, fps", [
    ("bandai/dataset-1/data/dataset-1_walk_normal_001.bvh", None),
    ("cmu/daz_friendly_120fps/07/07_01.bvh", None),
])
def test_real_walks_load(rel, fps):
    path = SHARED / "data" / rel
    if not path.exists():
        pytest.skip("shared data not present")
    m = load_motion(path, fps=fps)
    check_walk(m)
    assert m.fit_error_mm["mean"] < 150  # proportions differ from SMPL-X; directions match


def test_amc2bvh_header_fps_needs_the_override():
    path = SHARED / "data" / "cmu" / "amc2bvh_raw_30fps_header" / "16" / "16_01.bvh"
    if not path.exists():
        pytest.skip("shared data not present")
    m30 = load_motion(path)
    m120 = load_motion(path, fps=120)
    assert m120.joints.shape[0] * 4 == pytest.approx(m30.joints.shape[0], abs=4)


def test_amass_npz_upright_with_root_orient(tmp_path):
    poses = np.zeros((60, 165), np.float32)
    poses[:, 0] = math.pi / 2          # AMASS bodies are stood up by a 90 deg root_orient about X
    p = tmp_path / "clip.npz"
    np.savez(p, poses=poses, trans=np.zeros((60, 3)), mocap_frame_rate=np.array(60.0))
    m = load_motion(p)
    assert m.joints.shape == (10, 22, 3)
    head, pelvis, foot = m.joints[0, 15], m.joints[0, 0], m.joints[0, 10]
    assert head[2] > pelvis[2] > foot[2]
    # a quarter turn about Z more turns the facing: the body's left moves from +X to +Y
    poses2 = poses.copy()
    poses2[:, :3] = [0.0, 0.0, 0.0]
    from scipy.spatial.transform import Rotation
    poses2[:, :3] = (Rotation.from_euler("z", 90, degrees=True) * Rotation.from_euler("x", 90, degrees=True)).as_rotvec()
    np.savez(p, poses=poses2, trans=np.zeros((60, 3)), mocap_frame_rate=np.array(60.0))
    m2 = load_motion(p)
    assert m.joints[0, 1, 0] > m.joints[0, 2, 0]          # left hip at +X
    assert m2.joints[0, 1, 1] > m2.joints[0, 2, 1]        # turned: left hip at +Y
    with pytest.raises(InputError, match="trans"):
        np.savez(p, poses=poses)
        load_motion(p)


@pytest.mark.parametrize("names, family", [
    (["mixamorig:Hips", "mixamorig:Spine", "mixamorig:Spine1", "mixamorig:Spine2", "mixamorig:Neck",
      "mixamorig:Head"] + [f"mixamorig:{s}{b}" for s in ("Left", "Right") for b in
                           ("UpLeg", "Leg", "Foot", "ToeBase", "Shoulder", "Arm", "ForeArm", "Hand")], "mixamo"),
    (["DEF-spine", "DEF-spine.001", "DEF-spine.002", "DEF-spine.003", "DEF-spine.004", "DEF-spine.006"]
     + [f"DEF-{b}.{s}" for s in "LR" for b in ("thigh", "shin", "foot", "toe", "shoulder", "upper_arm",
                                                "forearm", "hand")], "rigify"),
    (["Hips", "Spine", "Chest", "Neck", "Head"] + [f"{b}_{s}" for s in "LR" for b in
                                                    ("UpperLeg", "LowerLeg", "Foot", "Toes", "Shoulder",
                                                     "UpperArm", "LowerArm", "Hand")], "bandai"),
    (list(JOINT_NAMES), "smplx"),
])
def test_bone_map_guessing(names, family):
    g = bm.guess_bone_map(names)
    assert g.family == family and g.missing == []
    bm.validate_bone_map(g.mapping, names)


def test_non_humanoid_rig_names_missing_joints():
    car = ["Body", "Wheel.FL", "Wheel.FR", "Wheel.BL", "Wheel.BR", "Steering"]
    g = bm.guess_bone_map(car)
    assert "left_knee" in g.missing
    with pytest.raises(InputError, match="not humanoid enough: no bones for pelvis"):
        bm.validate_bone_map(g.mapping, car, rig="Car")


def test_captions():
    assert bandai_caption("walk-left", "tired") == "a person walks to the left, tired"
    assert bandai_caption("bow", "happy") == "a person bows, happily"
    assert bandai_caption("walk", "normal") == "a person walks forward"
    assert hdm05_caption("walkRightCircle4StepsRstart") == "a person walks in a circle to the right"
    assert cmu_caption('"walk"') == "a person: walk"


ASF = """:version 1.10
:name tiny
:units
  mass 1.0
  length 0.45
  angle deg
:root
   order TX TY TZ RX RY RZ
   axis XYZ
   position 0 0 0
   orientation 0 0 0
:bonedata
  begin
     id 1
     name upper
     direction 0 1 0
     length 10
     axis 0 0 0 XYZ
     dof rx ry rz
  end
  begin
     id 2
     name lower
     direction 1 0 0
     length 5
     axis 0 0 90 XYZ
     dof rz
  end
:hierarchy
  begin
    root upper
    upper lower
  end
"""


def test_asf_amc_forward_kinematics(tmp_path):
    from model_runtime.data.asf_amc import asf_amc_positions, read_amc, read_asf
    (tmp_path / "s.asf").write_text(ASF)
    (tmp_path / "s_01.amc").write_text(":FULLY-SPECIFIED\n:DEGREES\n1\nroot 1 2 3 0 0 0\nupper 0 0 90\nlower 0\n"
                                       "2\nroot 1 2 3 0 0 0\nupper 0 0 0\nlower 90\n")
    skel = read_asf(tmp_path / "s.asf")
    starts, ends, names = asf_amc_positions(skel, read_amc(tmp_path / "s_01.amc", skel))
    assert names == ["hip", "upper", "lower"]
    # frame 0: 'upper' (+Y, 10) turned 90 deg about Z points to -X; 'lower' (+X, 5) turns with it -> +Y
    assert np.allclose(ends[0, 1], [1 - 10, 2, 3], atol=1e-9)
    assert np.allclose(ends[0, 2], [1 - 10, 2 + 5, 3], atol=1e-9)
    assert np.allclose(starts[0, 2], ends[0, 1])
    # frame 1: 'lower' rotates 90 deg about its own axis frame (its local Z = world Z here) -> +Y
    assert np.allclose(ends[1, 2], [1, 2 + 10 + 5, 3], atol=1e-9)


def test_amc_needs_its_skeleton(tmp_path):
    (tmp_path / "x_01.amc").write_text(":DEGREES\n1\nroot 0 0 0 0 0 0\n")
    with pytest.raises(InputError, match="no skeleton"):
        load_motion(tmp_path / "x_01.amc")
