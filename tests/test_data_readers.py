"""Motion readers, retargeting, resampling and captions (model_runtime.data).

Synthetic files are written to tmp_path; real clips come from the optional test data (tests/paths.py),
read-only, and are skipped with a reason when it is absent.
"""
import math
import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from model_runtime.data import Motion, load_motion
from model_runtime.data.bvh import read_bvh
from model_runtime.data.captions import bandai_caption, caption_for, cmu_caption, hdm05_caption
from model_runtime.data.motion import resample_positions
from model_runtime.errors import InputError
from model_runtime.skeleton import JOINT_INDEX, JOINT_NAMES
from paths import DATA, shared_file
from synthetic import REST_YUP, humanoid_bvh

J = JOINT_INDEX


def shared(rel: str) -> Path:
    """A file of the public motion data (tests/paths.py), or skip."""
    return shared_file(f"data/{rel}")


# ------------------------------------------------------------------------------ synthetic BVH

def euler(order: str, angles_deg) -> np.ndarray:
    """R = R_order[0] @ R_order[1] @ R_order[2] (BVH: channels compose in the order listed)."""
    return Rotation.from_euler(order.upper(), angles_deg, degrees=True).as_matrix()


CHAIN = """HIERARCHY
ROOT Hips
{{
\tOFFSET 0 0 0
\tCHANNELS 6 Xposition Yposition Zposition {root}
\tJOINT Spine
\t{{
\t\tOFFSET 0 10 0
\t\tCHANNELS {n} {spine}
\t\tEnd Site
\t\t{{
\t\t\tOFFSET 0 5 0
\t\t}}
\t}}
}}
MOTION
Frames: 2
Frame Time: 0.0333333
{rows}
"""


def write_chain(tmp_path, order, angles, name, six=False):
    chans = " ".join(f"{a}rotation" for a in order)
    spine = ("Xposition Yposition Zposition " + chans) if six else chans
    vals = " ".join(f"{v:.9f}" for v in angles)
    row = f"1 2 3 {vals} {'0 10 0 ' if six else ''}{vals}\t \n"          # tabs and trailing blanks
    p = tmp_path / name
    p.write_text(CHAIN.format(root=chans, n=6 if six else 3, spine=spine, rows=row + row))
    return p


def test_rotation_channel_order_is_respected(tmp_path):
    target = euler("ZXY", [30, 20, -40])
    xyz_angles = Rotation.from_matrix(target).as_euler("XYZ", degrees=True)
    a = read_bvh(write_chain(tmp_path, "ZXY", [30, 20, -40], "a.bvh"))
    b = read_bvh(write_chain(tmp_path, "XYZ", list(xyz_angles), "b.bvh"))
    pa, ea = a.world_positions()
    pb, eb = b.world_positions()
    assert np.allclose(pa, pb, atol=1e-6) and np.allclose(ea[:, 1], eb[:, 1], atol=1e-6)
    assert np.allclose(pa[0, 1], np.array([1, 2, 3]) + target @ [0, 10, 0], atol=1e-6)
    assert np.allclose(ea[0, 1], pa[0, 1] + target @ target @ [0, 5, 0], atol=1e-6)
    assert np.isnan(ea[0, 0]).all()                     # Hips has no End Site of its own


@pytest.mark.parametrize("order", ["XYZ", "ZXY", "YXZ", "ZYX", "xzy"])
def test_euler_matrix_against_scipy(order):
    """The one Euler helper both readers use: axes compose in the order listed (SciPy's intrinsic order)."""
    from model_runtime.data.geometry import euler_matrix
    angles = np.random.default_rng(0).uniform(-180, 180, (5, 3))
    assert np.allclose(euler_matrix(angles, order), euler(order, angles), atol=1e-12)


def test_six_channel_joints_parse(tmp_path):
    m = read_bvh(write_chain(tmp_path, "ZXY", [0, 0, 90], "six.bvh", six=True))
    assert len(m.joints[1].channels) == 6
    p, _ = m.world_positions()
    assert np.allclose(p[0, 1], [1, 2, 3] + euler("ZXY", [0, 0, 90]) @ [0, 10, 0], atol=1e-6)


@pytest.mark.parametrize("motion, match", [
    ("1 2\n", r"bad BVH line 10 in bad.bvh: 2 values, the hierarchy declares 3 channels"),
    ("1 2 x\n", r"bad BVH line 10 in bad.bvh: non-numeric"),
    ("1 2 nan\n", r"NaN"),
])
def test_bad_bvh_says_what_and_where(tmp_path, motion, match):
    p = tmp_path / "bad.bvh"
    p.write_text("HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 3 Zrotation Xrotation Yrotation\n}\n"
                 "MOTION\nFrames: 1\nFrame Time: 0.1\n" + motion)
    with pytest.raises(InputError, match=match):
        read_bvh(p)


def test_bad_files_are_named(tmp_path):
    p = tmp_path / "trunc.bvh"
    p.write_text("HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 3 Zrotation Xrotation Yrotation\n")
    with pytest.raises(InputError, match="unclosed"):
        read_bvh(p)
    with pytest.raises(InputError, match="unknown motion file type '.fbx'"):
        load_motion(tmp_path / "x.fbx")
    with pytest.raises(InputError, match="does not exist"):
        load_motion(tmp_path / "missing.bvh")


def grounded(truth):
    feet = [J["left_ankle"], J["right_ankle"], J["left_foot"], J["right_foot"]]
    return truth - np.array([0, 0, truth[:, feet, 2].min() - 0.02])


def test_same_proportions_retarget_almost_exactly(tmp_path):
    path, truth = humanoid_bvh(tmp_path / "h.bvh", fps=120)
    m = load_motion(path)
    assert isinstance(m, Motion) and m.fps == 10 and m.joints.shape == (21, 22, 3)
    assert m.joints.dtype == np.float32 and m.local_rotations.shape == (21, 22, 4) and m.root.shape == (21, 4, 4)
    err = np.linalg.norm(m.joints - grounded(truth)[::12], axis=-1) * 1000
    assert err.mean() < 5 and err.max() < 25, (err.mean(), err.max())
    assert m.fit_error_mm["mean"] < 5 and m.fit_error_mm["scale"] == pytest.approx(1.0, abs=1e-3)
    assert m.fit_error_mm["unit_name"] == "cm" and m.fit_error_mm["up"] == "+Y"
    assert np.allclose(m.root[:, :3, 3], m.joints[:, 0], atol=1e-6)
    assert np.allclose(np.linalg.norm(m.local_rotations, axis=-1), 1, atol=1e-5)


def test_units_axes_and_channel_orders_do_not_matter(tmp_path):
    ref = load_motion(humanoid_bvh(tmp_path / "cm.bvh", unit=0.01)[0]).joints
    m = load_motion(humanoid_bvh(tmp_path / "m.bvh", unit=1.0, order="XYZ")[0])
    assert m.fit_error_mm["unit_name"] == "m"
    assert np.abs(m.joints - ref).max() < 2e-3
    z = load_motion(humanoid_bvh(tmp_path / "z.bvh", unit=0.01, up="Z", order="YXZ")[0])
    assert z.fit_error_mm["up"] == "+Z"
    assert np.abs(z.joints - ref).max() < 2e-3


def test_resampling_gives_the_right_frame_count(tmp_path):
    assert resample_positions(np.arange(121.0)[:, None], 120.0).shape[0] == 11    # 1 s at 120 fps
    assert resample_positions(np.arange(31.0)[:, None], 30.0).shape[0] == 11      # 1 s at 30 fps
    assert np.allclose(resample_positions(np.arange(121.0)[:, None], 120.0)[:, 0], np.arange(0, 121, 12))
    m120 = load_motion(humanoid_bvh(tmp_path / "a.bvh", fps=120, seconds=3.0)[0])
    m30 = load_motion(humanoid_bvh(tmp_path / "b.bvh", fps=30, seconds=3.0)[0])
    assert m120.joints.shape[0] == m30.joints.shape[0] == 31
    # a wrong header: the same file read with fps=30 override lasts 4x longer
    assert load_motion(tmp_path / "a.bvh", fps=30).joints.shape[0] == 121


def test_added_rest_frame_is_dropped_with_a_warning(tmp_path):
    path, _ = humanoid_bvh(tmp_path / "r.bvh", fps=120, rest_frame=True, amplitude=40)
    with pytest.warns(UserWarning, match="frame 0 is an added rest pose"):
        m = load_motion(path)
    assert read_bvh(path).rest_lead_in() >= 1
    with warnings.catch_warnings():
        warnings.simplefilter("error")                  # a normal clip keeps its frames, silently
        load_motion(humanoid_bvh(tmp_path / "n.bvh", fps=120)[0])
    assert m.joints.shape[0] == 20


# ------------------------------------------------------------------------------ real clips

def check_plausible(m, lo=0.7, hi=2.0):
    j = m.joints
    assert m.fps == 10
    feet = [J["left_ankle"], J["right_ankle"]]
    assert (j[:, J["head"], 2] > j[:, J["pelvis"], 2]).all() and (j[:, J["pelvis"], 2] > j[:, feet, 2].max(1)).all()
    assert abs(float(j[:, [7, 8, 10, 11], 2].min()) - 0.02) < 0.005             # soles on z = 0
    speed = np.linalg.norm(j[-1, 0, :2] - j[0, 0, :2]) / ((len(j) - 1) / m.fps)
    assert lo < speed < hi, speed
    assert 1.3 < float(np.median(j[:, J["head"], 2])) < 1.8                          # a standing adult
    e = m.fit_error_mm
    assert e["legs_mean"] < 30 and e["dir_deg"] < 10 and e["mean"] < 100, e


@pytest.mark.parametrize("rel", ["bandai/dataset-1/data/dataset-1_walk_normal_001.bvh",
                                 "cmu/daz_friendly_120fps/07/07_01.bvh"])
def test_real_walks_load(rel):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        m = load_motion(shared(rel))
    check_plausible(m)
    daz = "daz_friendly" in rel
    assert any("added rest pose" in str(w.message) for w in caught) == daz          # DAZ frame 0 only


def test_cc_clip_loads():
    m = load_motion(shared("cmu/cc_retarget_60fps/002/002_05.bvh"))
    j = m.joints
    assert (j[:, J["head"], 2] > j[:, J["pelvis"], 2]).all()
    assert m.fit_error_mm["legs_mean"] < 30 and m.fit_error_mm["dir_deg"] < 10


def test_amc2bvh_needs_the_fps_override_or_the_index():
    path = shared("cmu/amc2bvh_raw_30fps_header/16/16_01.bvh")
    with pytest.warns(UserWarning, match="usually 120 fps"):
        m30 = load_motion(path)
    m120 = load_motion(path, fps=120)
    assert m120.joints.shape[0] * 4 == pytest.approx(m30.joints.shape[0], abs=4)
    indexed = load_motion(path, index=shared("cmu/index.csv"))
    assert indexed.joints.shape == m120.joints.shape and indexed.caption == "a person jumps"
    assert m120.fit_error_mm["unit_name"] == "CMU ASF units"


# ------------------------------------------------------------------------------ AMASS .npz

def write_npz(path, root_orient, frames=60, rate_key="mocap_frame_rate", width=165, **extra):
    poses = np.zeros((frames, width), np.float32)
    poses[:, :3] = root_orient
    np.savez(path, poses=poses, trans=np.zeros((frames, 3), np.float32), **{rate_key: np.array(60.0)}, **extra)
    return path


def test_amass_axes(tmp_path):
    # zero pose + zero trans: the Y-up body model as it is, i.e. lying along +Y in AMASS's Z-up world
    m0 = load_motion(write_npz(tmp_path / "zero.npz", [0, 0, 0]))
    assert m0.joints.shape == (10, 22, 3)
    assert m0.joints[0, J["head"], 1] - m0.joints[0, J["left_ankle"], 1] > 1.3
    assert np.allclose(m0.joints[0, 0], [0.003123, -0.351407, 0.012037], atol=1e-5)   # trans + rest pelvis
    # AMASS clips stand the body up with +90 degrees about X: then it is upright, facing -Y, left at +X
    up = load_motion(write_npz(tmp_path / "up.npz", [math.pi / 2, 0, 0], rate_key="mocap_framerate",
                               betas=np.zeros(16), gender=np.array("neutral")))
    j = up.joints[0]
    assert j[J["head"], 2] > j[J["pelvis"], 2] > j[J["left_ankle"], 2] + 0.7
    assert j[J["left_hip"], 0] > j[J["right_hip"], 0] and j[J["left_foot"], 1] < j[J["left_ankle"], 1]
    assert np.allclose(up.local_rotations[0, 0], [1, 0, 0, 0], atol=1e-6)   # standing = identity here
    # and a further quarter turn about Z turns it: left now at +Y
    turn = (Rotation.from_euler("z", 90, degrees=True) * Rotation.from_euler("x", 90, degrees=True)).as_rotvec()
    t = load_motion(write_npz(tmp_path / "turn.npz", turn, width=156)).joints[0]
    assert t[J["left_hip"], 1] > t[J["right_hip"], 1] and t[J["head"], 2] > t[J["pelvis"], 2]


def test_amass_errors(tmp_path):
    p = tmp_path / "bad.npz"
    np.savez(p, poses=np.zeros((5, 165)))
    with pytest.raises(InputError, match="no 'trans'"):
        load_motion(p)
    np.savez(p, poses=np.zeros((5, 165)), trans=np.zeros((5, 3)))
    with pytest.raises(InputError, match="mocap_frame_rate"):
        load_motion(p)
    assert load_motion(p, fps=30).joints.shape[0] == 2
    np.savez(p, poses=np.full((5, 165), np.nan), trans=np.zeros((5, 3)), mocap_frame_rate=30.0)
    with pytest.raises(InputError, match="NaN"):
        load_motion(p)


# ------------------------------------------------------------------------------ ASF / AMC

TINY_ASF = """:version 1.10
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
    (tmp_path / "s.asf").write_text(TINY_ASF)
    (tmp_path / "s_01.amc").write_text(":FULLY-SPECIFIED\n:DEGREES\n1\nroot 1 2 3 0 0 0\nupper 0 0 90\nlower 0\n"
                                       "2\nroot 1 2 3 0 0 0\nupper 0 0 0\nlower 90\n")
    skel = read_asf(tmp_path / "s.asf")
    assert skel.metres_per_unit == pytest.approx(0.0254 / 0.45)
    starts, ends, names = asf_amc_positions(skel, read_amc(tmp_path / "s_01.amc", skel))
    assert names == ["hip", "upper", "lower"]
    # frame 0: 'upper' (+Y, 10) turned 90 deg about Z points to -X; 'lower' (+X, 5) turns with it -> +Y
    assert np.allclose(ends[0, 1], [1 - 10, 2, 3], atol=1e-9)
    assert np.allclose(ends[0, 2], [1 - 10, 2 + 5, 3], atol=1e-9)
    assert np.allclose(starts[0, 2], ends[0, 1])
    # frame 1: 'lower' rotates 90 deg about its own axis frame (its local Z = world Z here) -> +Y
    assert np.allclose(ends[1, 2], [1, 2 + 10 + 5, 3], atol=1e-9)


# CMU-style bone chain (bone -> its start and end as SMPL-X joints; None = a short stub)
ASF_BONES = [("lhipjoint", "root", "pelvis", "left_hip"), ("lfemur", "lhipjoint", "left_hip", "left_knee"),
             ("ltibia", "lfemur", "left_knee", "left_ankle"), ("lfoot", "ltibia", "left_ankle", "left_foot"),
             ("ltoes", "lfoot", "left_foot", None),
             ("lowerback", "root", "pelvis", "spine1"), ("upperback", "lowerback", "spine1", "spine2"),
             ("thorax", "upperback", "spine2", "spine3"), ("lowerneck", "thorax", "spine3", "neck"),
             ("upperneck", "lowerneck", "neck", "head"), ("head", "upperneck", "head", None),
             ("lclavicle", "thorax", "spine3", "left_shoulder"),
             ("lhumerus", "lclavicle", "left_shoulder", "left_elbow"),
             ("lradius", "lhumerus", "left_elbow", "left_wrist"), ("lwrist", "lradius", "left_wrist", None)]
ASF_BONES += [("r" + b[1:], ("r" + p[1:]) if p[0] == "l" else p, s.replace("left", "right"),
               e.replace("left", "right") if e else None) for b, p, s, e in ASF_BONES if b[0] == "l"]


def write_asf_amc_and_bvh(tmp_path, frames=25):
    """The same CMU-style skeleton and motion as ASF + AMC and as the BVH amc2bvh would write."""
    inch = 0.0254
    rest = {n: REST_YUP[i] / inch for i, n in enumerate(JOINT_NAMES)}
    vec = {}
    for b, _, s, e in ASF_BONES:
        vec[b] = (rest[e] - rest[s]) if e else np.array([0.0, 2.0, 0.0] if b == "head" else [0, 0, 1.5]
                                                       if "toes" in b else [2.0 if b[0] == "l" else -2.0, 0, 0])
    asf = [":version 1.10", ":name synth", ":units", "  mass 1.0", "  length 1.0", "  angle deg",
           ":root", "   order TX TY TZ RX RY RZ", "   axis XYZ", "   position 0 0 0", "   orientation 0 0 0",
           ":bonedata"]
    for k, (b, _, _, _) in enumerate(ASF_BONES):
        v = vec[b]
        d = v / np.linalg.norm(v)
        asf += ["  begin", f"     id {k + 1}", f"     name {b}", f"     direction {d[0]:.8f} {d[1]:.8f} {d[2]:.8f}",
                f"     length {np.linalg.norm(v):.8f}", "     axis 0 0 0 XYZ", "     dof rx ry rz", "  end"]
    kids = {}
    for b, p, _, _ in ASF_BONES:
        kids.setdefault(p, []).append(b)
    asf += [":hierarchy", "  begin"] + [f"    {p} {' '.join(c)}" for p, c in kids.items()] + ["  end"]
    (tmp_path / "synth.asf").write_text("\n".join(asf) + "\n")
    rng = np.random.default_rng(1)
    t = np.arange(frames) / 120.0
    ang = {b: 15 * np.sin(2 * np.pi * rng.uniform(0.5, 2, 3) * t[:, None] + rng.uniform(0, 6, 3))
           for b, *_ in ASF_BONES}
    root_t = np.stack([np.zeros(frames), np.full(frames, rest["pelvis"][1] - rest["left_foot"][1] + 2),
                       40 * t], -1)
    root_r = 5 * np.sin(2 * np.pi * t[:, None] + np.array([0, 1, 2]))
    amc = [":FULLY-SPECIFIED", ":DEGREES"]
    for f in range(frames):
        amc.append(str(f + 1))
        amc.append("root " + " ".join(f"{v:.6f}" for v in list(root_t[f]) + list(root_r[f])))
        amc += [f"{b} " + " ".join(f"{v:.6f}" for v in ang[b][f]) for b, *_ in ASF_BONES]
    (tmp_path / "synth_01.amc").write_text("\n".join(amc) + "\n")

    # BVH: joint = bone start, OFFSET = the parent bone's vector, ZYX channels (M = Rz Ry Rx)
    def block(b, depth):
        pad = "  " * depth
        parent = next((p for bb, p, *_ in ASF_BONES if bb == b), None)
        off = vec[parent] if parent not in (None, "root") else np.zeros(3)
        out = [f"{pad}JOINT {b}", pad + "{", f"{pad}  OFFSET {off[0]:.8f} {off[1]:.8f} {off[2]:.8f}",
               f"{pad}  CHANNELS 3 Zrotation Yrotation Xrotation"]
        for c in kids.get(b, []):
            out += block(c, depth + 1)
        if b not in kids:
            v = vec[b]
            out += [f"{pad}  End Site", pad + "  {", f"{pad}    OFFSET {v[0]:.8f} {v[1]:.8f} {v[2]:.8f}", pad + "  }"]
        return out + [pad + "}"]

    order = []

    def visit(b):
        order.append(b)
        for c in kids.get(b, []):
            visit(c)
    for c in kids["root"]:
        visit(c)
    bvh = ["HIERARCHY", "ROOT hip", "{", "  OFFSET 0 0 0",
           "  CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation"]
    for c in kids["root"]:
        bvh += block(c, 1)
    bvh += ["}", "MOTION", f"Frames: {frames}", "Frame Time: 0.00833333"]
    for f in range(frames):
        vals = list(root_t[f]) + list(root_r[f][::-1])
        for b in order:
            vals += list(ang[b][f][::-1])
        bvh.append(" ".join(f"{v:.6f}" for v in vals))
    (tmp_path / "synth_01.bvh").write_text("\n".join(bvh) + "\n")


def test_asf_amc_round_trip_matches_the_equivalent_bvh(tmp_path):
    write_asf_amc_and_bvh(tmp_path)
    with pytest.warns(UserWarning, match="no frame rate"):
        amc = load_motion(tmp_path / "synth_01.amc")                 # finds synth.asf, assumes 120 fps
    bvh = load_motion(tmp_path / "synth_01.bvh", fps=120)
    assert amc.joints.shape == bvh.joints.shape == (3, 22, 3)
    assert np.abs(amc.joints - bvh.joints).max() < 1e-4
    assert amc.fit_error_mm["unit_name"] == "declared" and bvh.fit_error_mm["unit_name"] == "inches"
    j = amc.joints
    assert (j[:, J["head"], 2] > j[:, J["pelvis"], 2] + 0.3).all()


def test_prepare_reads_a_folder_of_mixed_formats(tmp_path):
    """BVH, ASF + AMC and AMASS .npz side by side: every motion file is a clip (the .asf is none), the AMC's rate
    comes from captions.csv, and two files differing only in their suffix keep apart names."""
    from model_runtime.data.prepare import build_library
    write_asf_amc_and_bvh(tmp_path, frames=150)
    (tmp_path / "amass").mkdir()
    write_npz(tmp_path / "amass" / "stand_up.npz", [math.pi / 2, 0, 0], frames=90)
    (tmp_path / "captions.csv").write_text("file,caption,fps\nsynth_01.amc,a person sways,120\n"
                                           "synth_01.bvh,,120\n")
    lib = build_library(tmp_path, progress=False)
    assert dict(zip(lib.names, lib.captions)) == {"user/amass/stand_up": "stand up",
                                                  "user/synth_01.amc": "a person sways", "user/synth_01.bvh": "synth"}
    assert lib.frames(lib.names.index("user/synth_01.amc")) == lib.frames(lib.names.index("user/synth_01.bvh")) == 13


def test_amc_needs_its_skeleton(tmp_path):
    (tmp_path / "x_01.amc").write_text(":DEGREES\n1\nroot 0 0 0 0 0 0\n")
    with pytest.raises(InputError, match="no skeleton"):
        load_motion(tmp_path / "x_01.amc")


# ------------------------------------------------------------------------------ captions

def test_caption_phrases():
    assert bandai_caption("walk-left", "tired") == "a person walks to the left, tired"
    assert bandai_caption("bow", "happy") == "a person bows, happily"
    assert bandai_caption("walk", "normal") == "a person walks forward"
    assert hdm05_caption("walkRightCircle4StepsRstart") == "a person walks in a circle to the right"
    assert hdm05_caption("kickLFront1Reps") == "a person kicks forward with the left leg"
    assert hdm05_caption("sitDownChair") == "a person sits down on a chair"
    assert cmu_caption('"slow walk"') == "a person walks slowly"
    assert cmu_caption("playground - climb, sit") == "a person plays on a playground: climbs and sits"
    assert cmu_caption("bend over, scoop up, rise, lift arm") == "a person bends over, scoops up, rises and lifts arm"
    assert caption_for("HDM_bd_jumpingJack1Reps_001_120.amc") == "a person does jumping jacks"
    assert caption_for("somewhere/else.bvh") is None


def test_every_bandai_label_has_a_phrase():
    from model_runtime.data.captions import BANDAI_CONTENT, BANDAI_STYLE, _labels
    cfgs = sorted(DATA.glob("bandai/dataset-*/cfg"))
    if not cfgs:
        pytest.skip("Bandai Namco test data not present beside the repository")
    for cfg in cfgs:
        assert set(_labels(cfg / "content_label.txt")) <= set(BANDAI_CONTENT)
        assert set(_labels(cfg / "style_label.txt")) <= set(BANDAI_STYLE)


@pytest.mark.parametrize("rel, caption", [
    ("bandai/dataset-1/data/dataset-1_walk-left_tired_001.bvh", "a person walks to the left, tired"),
    ("bandai/dataset-1/data/dataset-1_bow_happy_001.bvh", "a person bows, happily"),
    ("bandai/dataset-1/data/dataset-1_dash_giant_001.bvh", "a person dashes forward, like a giant"),
    ("bandai/dataset-2/data/dataset-2_wave-left-hand_elderly_001.bvh",
     "a person waves the left hand, like an elderly person"),
])
def test_bandai_captions_from_json_ids(rel, caption):
    assert caption_for(shared(rel)) == caption


def test_cmu_captions_from_the_index():
    index = shared("cmu/index.csv")
    assert caption_for(shared("cmu/daz_friendly_120fps/07/07_01.bvh"), index) == "a person walks"
    assert caption_for(shared("cmu/cc_retarget_60fps/002/002_05.bvh"), index) == "a person punches"
    assert caption_for(shared("cmu/daz_friendly_120fps/07/07_01.bvh")) is None


# ------------------------------------------------------------------------------ Bandai repository checkout

def test_bandai_repository_adds_only_takes_the_data_folder_lacks(tmp_path):
    """--bandai-repo reads the repository layout, takes content/style from the file name and skips clips
    the data folder already has, so a larger run never counts a clip twice."""
    from model_runtime.data.clip_files import bandai_repository_files
    src = shared("bandai/dataset-2/data/dataset-2_walk-turn-left_normal_001.bvh")
    data = tmp_path / "repo" / "dataset" / "Bandai-Namco-Research-Motiondataset-2" / "data"
    data.mkdir(parents=True)
    (data / src.name).write_bytes(src.read_bytes())                                   # already in the data folder
    (data / "dataset-2_walk-turn-left_normal_042.bvh").write_bytes(src.read_bytes())  # a take it lacks
    (data / "README.bvh").write_text("not a take")                                     # not a take name
    files = bandai_repository_files(tmp_path / "repo", skip={src.stem})
    assert [(f.path.name, f.name, f.source, f.caption) for f in files] == [
        ("dataset-2_walk-turn-left_normal_042.bvh", "bandai/dataset-2_walk-turn-left_normal_042", "bandai",
         "a person walks and turns left")]
