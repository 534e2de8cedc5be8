"""The Acclaim ASF + AMC reader (CMU's own format), and a folder that mixes it with BVH and AMASS files."""
import math

import numpy as np
import pytest

from model_runtime.data import load_motion
from model_runtime.errors import InputError
from model_runtime.skeleton import JOINT_INDEX, JOINT_NAMES
from synthetic import REST_YUP, write_npz

J = JOINT_INDEX


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

