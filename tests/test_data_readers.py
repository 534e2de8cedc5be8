"""Motion readers (BVH, AMASS .npz), retargeting and resampling (model_runtime.data).

Synthetic files are written to tmp_path; real clips come from the optional test data (tests/paths.py),
read-only, and are skipped with a reason when it is absent.
"""
import math
import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from model_runtime.data import Motion, load_motion
from model_runtime.data.bvh import read_bvh
from model_runtime.data.motion import resample_positions
from model_runtime.errors import InputError
from model_runtime.skeleton import JOINT_INDEX
from paths import data_file
from synthetic import humanoid_bvh, write_npz

J = JOINT_INDEX



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


def hand_written_rest_frame(path):
    """Replace frame 0 of a BVH by a MotionBuilder-friendly CMU rest pose: whole-degree rotations (shoulders
    turned by 21 deg), the root position of frame 1."""
    lines = path.read_text().splitlines()
    i = lines.index("MOTION") + 3
    first, second = lines[i].split(), lines[i + 1].split()
    rest = ["0"] * (len(first) - 3)
    rest[6], rest[12] = "-21", "21"
    lines[i] = " ".join(second[:3] + rest)
    path.write_text("\n".join(lines) + "\n")
    return path


def test_hand_written_rest_frame_is_dropped(tmp_path):
    path = hand_written_rest_frame(humanoid_bvh(tmp_path / "mb.bvh", fps=120, amplitude=40)[0])
    assert read_bvh(path).rest_lead_in() == 1
    with pytest.warns(UserWarning, match="frame 0 is an added rest pose"):
        assert load_motion(path).joints.shape[0] == 20
    # a capture frame keeps its place even when its root holds still into frame 1
    still = humanoid_bvh(tmp_path / "still.bvh", fps=120, amplitude=40)[0]
    lines = still.read_text().splitlines()
    i = lines.index("MOTION") + 3
    lines[i] = " ".join(lines[i + 1].split()[:3] + lines[i].split()[3:])
    still.write_text("\n".join(lines) + "\n")
    assert read_bvh(still).rest_lead_in() == 0


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
        m = load_motion(data_file(rel))
    check_plausible(m)
    daz = "daz_friendly" in rel
    assert any("added rest pose" in str(w.message) for w in caught) == daz          # DAZ frame 0 only


def test_cc_clip_loads():
    m = load_motion(data_file("cmu/cc_retarget_60fps/002/002_05.bvh"))
    j = m.joints
    assert (j[:, J["head"], 2] > j[:, J["pelvis"], 2]).all()
    assert m.fit_error_mm["legs_mean"] < 30 and m.fit_error_mm["dir_deg"] < 10


def test_amc2bvh_needs_the_fps_override_or_the_index():
    path = data_file("cmu/amc2bvh_raw_30fps_header/16/16_01.bvh")
    with pytest.warns(UserWarning, match="usually 120 fps"):
        m30 = load_motion(path)
    m120 = load_motion(path, fps=120)
    assert m120.joints.shape[0] * 4 == pytest.approx(m30.joints.shape[0], abs=4)
    indexed = load_motion(path, index=data_file("cmu/index.csv"))
    assert indexed.joints.shape == m120.joints.shape and indexed.caption == "a person jumps"
    assert m120.fit_error_mm["unit_name"] == "CMU ASF units"



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
