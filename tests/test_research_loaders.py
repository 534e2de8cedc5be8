"""Research dataset loaders on tiny synthetic fixtures written in each dataset's published layout.

No licensed data: every test writes a few frames of rest poses (SMPL-X/H parameters) in the layout the
loader expects, loads it back and checks shapes, 10 fps resampling, upright bodies in our Z-up world,
Inter-X's both-ego augmentation, and where occupancy lands.
"""
import json
import math
import pickle
import zipfile

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from model_runtime.data.amass import REST_PELVIS_YUP
from model_runtime.data.research import (DATASETS, load_egobody, load_humanml3d, load_interx_pairs, load_lingo,
                                         read_obj)
from model_runtime.errors import InputError
from model_runtime.skeleton import JOINT_INDEX, SOLE_BELOW_FOOT_JOINT

J0 = REST_PELVIS_YUP.numpy().astype(np.float64)      # betas = 0 rest pelvis, SMPL-X's own Y-up frame
HEAD, PELVIS = JOINT_INDEX["head"], JOINT_INDEX["pelvis"]
LHIP, RHIP = JOINT_INDEX["left_hip"], JOINT_INDEX["right_hip"]
FEET = [JOINT_INDEX["left_foot"], JOINT_INDEX["right_foot"]]
UPRIGHT_Z = [math.pi / 2, 0.0, 0.0]                   # stands a Y-up body up in a Z-up world


def assert_upright(joints):
    for f in joints:
        assert f[HEAD, 2] - f[FEET, 2].max() > 1.2, "head well above the feet"
        assert f[HEAD, 2] > f[PELVIS, 2] > f[FEET, 2].max()


def facing(joints):
    """Forward direction (Z-up world) of frame 0: left x up."""
    left = joints[0, LHIP] - joints[0, RHIP]
    fwd = np.cross(left, [0.0, 0.0, 1.0])
    return fwd / np.linalg.norm(fwd)


def test_datasets_describe_every_layout():
    assert set(DATASETS) == {"humanml3d", "interx", "lingo", "egobody"}
    for text in DATASETS.values():
        assert "Confirmed" in text and len(text) > 400


# ---------------------------------------------------------------------------------------- HumanML3D
def _amass_file(path, fps, seconds, speed):
    t = np.arange(int(round(fps * seconds))) / fps
    poses = np.zeros((len(t), 156), np.float32)
    poses[:, :3] = UPRIGHT_Z
    trans = np.zeros((len(t), 3), np.float32)
    trans[:, 0] = speed * t                            # x (metres) = seconds: positions tell the cut apart
    trans[:, 2] = 0.9
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(path, poses=poses, trans=trans, mocap_framerate=np.array(float(fps)), gender=np.array("male"),
             betas=np.zeros(16))


def _humanml3d_fixture(tmp_path):
    repo = tmp_path / "HumanML3D_repo"
    root, amass = repo / "HumanML3D", tmp_path / "amass_data"
    (root / "texts").mkdir(parents=True)
    _amass_file(amass / "CMU" / "01" / "01_01_poses.npz", 120, 5.0, 1.0)
    # AMASS unzipped under today's name (HDM05): found through HumanML3D's rename table; 60 fps, 3 s trim
    _amass_file(amass / "HDM05" / "bk" / "HDM_bk_01_poses.npz", 60, 6.0, 1.0)
    (repo / "index.csv").write_text(
        "source_path,start_frame,end_frame,new_name\n"
        "./pose_data/CMU/01/01_01_poses.npy,10,50,000000.npy\n"
        "./pose_data/MPI_HDM05/bk/HDM_bk_01_poses.npy,10,30,000001.npy\n"
        "./pose_data/humanact12/humanact12/P01G01R01F0001T0050A0101.npy,0,-1,000002.npy\n")
    t = root / "texts"
    (t / "000000.txt").write_text(
        "a person walks forward.#a/DET person/NOUN walk/VERB forward/ADV#0.0#0.0\n"
        "someone strolls ahead.#someone/PRON stroll/VERB ahead/ADV#0.0#0.0\n"
        "a person takes a step.#a/DET person/NOUN take/VERB a/DET step/NOUN#0.5#1.5\n")
    (t / "M000000.txt").write_text("a person walks forward.#a/DET person/NOUN walk/VERB forward/ADV#0.0#0.0\n")
    (t / "000001.txt").write_text("a man walks.#a/DET man/NOUN walk/VERB#nan#nan\n")
    (t / "000002.txt").write_text("a person jumps.#a/DET person/NOUN jump/VERB#0.0#0.0\n")
    (root / "train.txt").write_text("000000\nM000000\n000001\n000002\n")
    (root / "val.txt").write_text("000001\n")
    return root, amass


def test_humanml3d_cuts_clips_captions_splits_and_mirrors(tmp_path):
    root, amass = _humanml3d_fixture(tmp_path)
    with pytest.warns(UserWarning, match="humanact12"):
        clips = load_humanml3d(root, amass, split="train")
    by = {(m.source, m.caption): m for m in clips}
    assert [m.caption for m in clips] == ["a person walks forward.", "a person takes a step.",
                                         "a person walks forward.", "a man walks."]
    whole = by[("humanml3d:000000", "a person walks forward.")]
    # 20 fps frames [10, 50) = 2 s -> source frames 60..294 at 120 fps -> 20 frames at 10 fps
    assert whole.fps == 10 and whole.joints.shape == (20, 22, 3) and whole.local_rotations.shape == (20, 22, 4)
    assert whole.root[0, 0, 3] == pytest.approx(0.5 + J0[0], abs=1e-4)
    assert whole.root[-1, 0, 3] == pytest.approx(2.4 + J0[0], abs=1e-4)       # 10 fps steps of 0.1 s
    assert_upright(whole.joints)
    assert whole.joints[0, :, 2].min() == pytest.approx(SOLE_BELOW_FOOT_JOINT, abs=1e-5)   # grounded
    span = by[("humanml3d:000000@10-30", "a person takes a step.")]               # 0.5 s .. 1.5 s of the clip
    assert span.joints.shape == (10, 22, 3) and span.root[0, 0, 3] == pytest.approx(1.0 + J0[0], abs=1e-4)
    mirror = by[("humanml3d:M000000", "a person walks forward.")]
    assert mirror.root[0, 0, 3] == pytest.approx(-(0.5 + J0[0]), abs=1e-4)
    swap = list(range(22))
    for a, b in zip((1, 4, 7, 10, 13, 16, 18, 20), (2, 5, 8, 11, 14, 17, 19, 21)):
        swap[a], swap[b] = b, a
    reflected = whole.joints[:, swap] * np.array([-1.0, 1.0, 1.0])
    # x -> -x with left <-> right; the rest skeleton itself is asymmetric by up to 3.4 cm (neck)
    assert np.abs(mirror.joints - reflected).max() < 0.04
    assert np.abs(mirror.joints - reflected)[:, [0, 1, 2, 4, 5, 7, 8]].max() < 0.025   # pelvis and legs
    assert_upright(mirror.joints)
    hdm = by[("humanml3d:000001", "a man walks.")]     # 3 s trim + frames [10, 30) at 20 fps = 3.5 s .. 4.5 s
    assert hdm.joints.shape == (10, 22, 3) and hdm.root[0, 0, 3] == pytest.approx(3.5 + J0[0], abs=1e-4)

    with pytest.warns(UserWarning, match="humanact12"):
        many = load_humanml3d(root, amass, split="train", mirrored=False, all_captions=True)
    assert [m.caption for m in many].count("someone strolls ahead.") == 1
    assert not any("M000000" in m.source for m in many)
    shared = [m for m in many if m.source == "humanml3d:000000"]
    assert len(shared) == 2 and shared[0].joints is shared[1].joints
    assert [m.source for m in load_humanml3d(root, amass, split="val")] == ["humanml3d:000001"]


def test_humanml3d_errors_name_what_is_expected(tmp_path):
    root, amass = _humanml3d_fixture(tmp_path)
    with pytest.raises(InputError, match="AMASS folder"):
        load_humanml3d(root, tmp_path / "nowhere")
    with pytest.raises(InputError, match="test.txt"):
        load_humanml3d(root, amass, split="test")
    # the repository ships texts.zip: it is read in place when texts/ was not unzipped
    with zipfile.ZipFile(root / "texts.zip", "w") as zf:
        for p in sorted((root / "texts").iterdir()):
            zf.write(p, f"texts/{p.name}")
            p.unlink()
    (root / "texts").rmdir()
    assert [m.source for m in load_humanml3d(root, amass, split="val")] == ["humanml3d:000001"]
    (root / "texts.zip").unlink()
    with pytest.raises(InputError, match="texts"):
        load_humanml3d(root, amass)


# ---------------------------------------------------------------------------------------- Inter-X
def _interx_fixture(tmp_path):
    root, cid = tmp_path / "Inter-X_Dataset", "G001T000A000R000"
    (root / "splits").mkdir(parents=True)
    (root / "texts").mkdir()
    n = 121                                            # 1 s at 120 fps -> 11 frames at 10 fps
    t = np.arange(n) / 120.0
    for person in ("P1", "P2"):
        trans = np.zeros((n, 3), np.float32)
        root_orient = np.zeros((n, 3), np.float32)     # Y-up world: zero root_orient already stands upright
        trans[:, 1] = 0.95                              # Y-up: height in y
        if person == "P1":
            trans[:, 0] = 0.5 * t                       # walks along x
        else:
            trans[:, 2] = 1.5                           # 1.5 m in front of P1 (SMPL faces +z in Y-up) ...
            root_orient[:, 1] = math.pi                 # ... turned round to face P1
        d = root / "motions" / cid
        d.mkdir(parents=True, exist_ok=True)
        np.savez(d / f"{person}.npz", root_orient=root_orient, pose_body=np.zeros((n, 21, 3), np.float32),
                 pose_lhand=np.zeros((n, 15, 3), np.float32), pose_rhand=np.zeros((n, 15, 3), np.float32),
                 trans=trans, betas=np.zeros((1, 10), np.float32), gender=np.array("female"))
    (root / "splits" / "train.txt").write_text(cid + "\n")
    (root / "splits" / "test.txt").write_text("")
    (root / "texts" / f"{cid}.txt").write_text("one person waves at the other, who waves back.\n"
                                               "two people greet each other with a wave.\n")
    return root, cid


def test_interx_pairs_both_persons_as_ego(tmp_path):
    root, cid = _interx_fixture(tmp_path)
    pairs = load_interx_pairs(root, split="train")
    assert len(pairs) == 2                              # P1 as ego, then P2 as ego
    (ego1, partner1, text1), (ego2, partner2, text2) = pairs
    assert ego1.source.endswith(":P1") and ego2.source.endswith(":P2")
    assert text1 == text2 == "one person waves at the other, who waves back." == ego1.caption
    for ego, partner in ((ego1, partner1), (ego2, partner2)):
        assert ego.fps == 10 and ego.joints.shape == (11, 22, 3) and partner.shape == (11, 22, 3)
        assert_upright(ego.joints)
        assert_upright(partner)
        assert ego.joints[0, :, 2].min() == pytest.approx(SOLE_BELOW_FOOT_JOINT, abs=1e-5)
    np.testing.assert_allclose(partner1, ego2.joints)
    np.testing.assert_allclose(partner2, ego1.joints)
    # Y-up -> Z-up: Y-up z = +1.5 becomes y = -1.5; P1 walks 0.5 m along x in 1 s
    assert ego2.root[0, 1, 3] == pytest.approx(-1.5 - J0[2], abs=1e-4)
    assert ego1.root[-1, 0, 3] - ego1.root[0, 0, 3] == pytest.approx(0.5, abs=1e-4)
    # they face each other
    to_partner = ego2.joints[0, PELVIS] - ego1.joints[0, PELVIS]
    assert facing(ego1.joints) @ to_partner > 1.4 and facing(ego2.joints) @ -to_partner > 1.4
    roles = load_interx_pairs(root, role_texts={cid: ("a person waves.", "a person waves back.")})
    assert [p[2] for p in roles] == ["a person waves.", "a person waves back."]
    assert load_interx_pairs(root, split="test") == []
    with pytest.raises(InputError, match="splits/val.txt"):
        load_interx_pairs(root, split="val")
    (root / "motions" / cid / "P2.npz").unlink()
    with pytest.raises(InputError, match="P2.npz"):
        load_interx_pairs(root)


# ---------------------------------------------------------------------------------------- LINGO
def _lingo_fixture(tmp_path):
    root = tmp_path / "dataset"
    (root / "Scene").mkdir(parents=True)
    n = 122                                            # two segments of 61 frames (2 s at 30 fps)
    t = (np.arange(n) % 61) / 30.0
    transl = np.zeros((n, 3), np.float32)
    transl[:, 0] = 0.5 * t                              # Y-up x
    transl[:, 1] = 0.9                                  # Y-up height
    transl[:, 2] = -1.0                                 # Y-up z = -1 -> Z-up y = +1
    np.save(root / "human_orient.npy", np.zeros((n, 3), np.float32))
    np.save(root / "human_pose.npy", np.zeros((n, 63), np.float32))
    np.save(root / "transl_aligned.npy", transl)
    np.save(root / "start_idx.npy", np.array([0, 61]))
    np.save(root / "end_idx.npy", np.array([61, 122]))
    with open(root / "text_aug.pkl", "wb") as fh:
        pickle.dump([["walk to the table", "go to the table"], "sit down on the chair"], fh)
    with open(root / "scene_name.pkl", "wb") as fh:
        pickle.dump(["003"] * n, fh)
    occ = np.zeros((300, 100, 400), bool)               # Y-up [x, y(up), z] over x[-3,3] y[0,2] z[-4,4]
    occ[200:210, 0:25, 100:110] = True                  # x 1.0..1.2, height 0..0.5, z -2.0..-1.8
    np.save(root / "Scene" / "003.npy", occ)
    return root, transl


def test_lingo_scene_grids_and_world_motion(tmp_path):
    root, transl = _lingo_fixture(tmp_path)
    segs = load_lingo(root)
    assert len(segs) == 2
    (m0, g0, text0), (m1, g1, text1) = segs
    assert g0 is g1                                     # one grid per scene
    assert (text0, text1) == ("walk to the table", "sit down on the chair") and m0.caption == text0
    assert g0.shape == (300, 400, 100) and g0.voxel_size == pytest.approx(0.02)
    lo, hi = g0.bounds
    np.testing.assert_allclose(lo, [-3, -4, 0]) and np.testing.assert_allclose(hi, [3, 4, 2])
    assert g0.occupied([1.1, 1.9, 0.25]) and int(g0.occupancy.sum()) == 10 * 10 * 25
    assert not g0.occupied([1.1, -1.9, 0.25]) and not g0.occupied([1.1, 1.9, 0.6])
    # 61 frames at 30 fps = 2 s -> 21 frames at 10 fps; kept in scene coordinates (not grounded)
    assert m0.fps == 10 and m0.joints.shape == (21, 22, 3)
    assert_upright(m0.joints)
    yup_to_zup = np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]], float)
    np.testing.assert_allclose(m0.root[0, :3, 3], yup_to_zup @ (transl[0] + J0), atol=1e-4)
    np.testing.assert_allclose(m0.root[-1, :3, 3], yup_to_zup @ (transl[60] + J0), atol=1e-4)
    assert load_lingo(root, scenes=["nope"]) == []
    (root / "Scene" / "003.npy").unlink()
    with pytest.raises(InputError, match="scene '003'"):
        load_lingo(root)
    (root / "human_orient.npy").unlink()
    with pytest.raises(InputError, match="human_orient.npy"):
        load_lingo(root)


# ---------------------------------------------------------------------------------------- EgoBody
REC, SCENE = "recording_20220101_S01_S02_01", "room1"
CAM_R = np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]])   # camera (x right, y down, z forward) -> world Z-up
CAM_T = np.array([2.5, 0.5, 1.5])


def _egobody_fixture(tmp_path):
    root = tmp_path / "egobody_release"
    root.mkdir()
    (root / "data_info_release.csv").write_text(
        "recording_name,body_idx_0,body_idx_1,body_idx_fpv,start_frame,end_frame,scene_name\n"
        f"{REC},0 male,1 female,1 female,1,31,{SCENE}\n")
    (root / "data_splits.csv").write_text(f"train,val,test\n{REC},,\n")
    calib = root / "calibrations" / REC / "cal_trans" / "kinect12_to_world"
    calib.mkdir(parents=True)
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = CAM_R, CAM_T
    (calib / f"{SCENE}.json").write_text(json.dumps({"trans": m.tolist()}))
    # scene (world, Z-up): a 5 x 4 m floor at z = 0.3 and a 1 m box on it at x 3..4, y 1..2
    mesh = root / "scene_mesh" / SCENE
    mesh.mkdir(parents=True)
    box = [(x, y, z) for x in (3, 4) for y in (1, 2) for z in (0.3, 1.3)]
    lines = ["# floor quad then a box", "v 0 0 0.3", "v 5 0 0.3", "v 5 4 0.3", "v 0 4 0.3", "vn 0 0 1",
             "f 1//1 2//1 3//1 4//1"]
    lines += [f"v {x} {y} {z} 0.5 0.5 0.5" for x, y, z in box]
    # box vertex k (0-based in box) is OBJ index 5 + k; faces as quads, one written with negative indices
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    lines += ["f " + " ".join(f"{5 + k}/1" for k in q) for q in quads[:-1]]
    lines += ["f " + " ".join(str(k - 8) for k in quads[-1])]
    (mesh / f"{SCENE}.obj").write_text("\n".join(lines) + "\n")
    # bodies: upright in the world (root_orient = 90 deg about X), given in camera coordinates
    cam_orient = Rotation.from_matrix(CAM_R.T @ Rotation.from_rotvec(UPRIGHT_Z).as_matrix()).as_rotvec()
    for role, idx, y in (("camera_wearer", 0, 2.0), ("interactee", 1, 3.2)):
        for fr in range(1, 32):
            if role == "interactee" and fr == 16:
                continue                                # a missing fit splits the recording into two runs
            pelvis = np.array([1.5 + (0.03 * (fr - 1) if role == "interactee" else 0.0), y, 1.25])
            transl = CAM_R.T @ (pelvis - CAM_T) - J0
            d = root / f"smplx_{role}_train" / REC / f"body_idx_{idx}" / "results" / f"frame_{fr:05d}"
            d.mkdir(parents=True)
            with open(d / "000.pkl", "wb") as fh:
                pickle.dump({"transl": transl[None].astype(np.float32),
                             "global_orient": cam_orient[None].astype(np.float32),
                             "body_pose": np.zeros((1, 63), np.float32), "betas": np.zeros((1, 10), np.float32),
                             "left_hand_pose": np.zeros((1, 12), np.float32), "gender": "male"}, fh)
    return root


def test_egobody_normalised_scene_both_roles_and_gaps(tmp_path):
    root = _egobody_fixture(tmp_path)
    out = load_egobody(root, split="train", captions={REC: "two people talk"})
    assert len(out) == 4                                # 2 runs (frame 16 missing) x 2 roles
    (w, w_partner, grid), (i, i_partner, grid2) = out[:2]
    assert grid is grid2 is out[3][2]
    assert "wearer" in w.source and "interactee" in i.source and w.caption == "two people talk"
    for ego, partner, _ in out:
        assert ego.fps == 10 and ego.joints.shape == (5, 22, 3) and partner.shape == (5, 22, 3)  # frames 1..13 / 3
        assert_upright(ego.joints)
    np.testing.assert_allclose(w_partner, i.joints)
    np.testing.assert_allclose(i_partner, w.joints)
    # the scene's bounding box XY centre (2.5, 2) goes to the origin and its floor (0.3) to z = 0; so do the bodies
    np.testing.assert_allclose(w.root[0, :3, 3], [-1.0, 0.0, 0.95], atol=1e-4)
    np.testing.assert_allclose(i.root[0, :3, 3], [-1.0, 1.2, 0.95], atol=1e-4)
    np.testing.assert_allclose(out[2][0].root[0, :3, 3], [-1.0, 0.0, 0.95], atol=1e-4)
    assert out[3][0].root[0, 0, 3] == pytest.approx(1.5 + 0.03 * 18 - 2.5, abs=1e-4)   # second run: frame 19
    assert facing(w.joints) @ [0, 1, 0] < -0.99            # SMPL faces -y when stood up by +90 deg about X
    # LINGO configuration: Z-up x[-3,3] y[-4,4] z[0,2] at 0.02 m; box at x 0.5..1.5, y -1..0, z 0..1, filled
    assert grid.shape == (300, 400, 100)
    np.testing.assert_allclose(grid.bounds[0], [-3, -4, 0])
    assert grid.occupied([1.0, -0.5, 0.5]) and grid.occupied([0.51, -0.5, 0.99])
    assert not grid.occupied([1.0, -0.5, 1.1]) and not grid.occupied([1.6, -0.5, 0.5])
    assert grid.occupied([-1.0, 0.5, 0.01]) and not grid.occupied([-1.0, 0.5, 0.05])   # the floor, one layer
    assert load_egobody(root, split="val") == []
    assert len(load_egobody(root, both_ego=False)) == 2
    (root / "scene_mesh" / SCENE / f"{SCENE}.obj").unlink()
    with pytest.raises(InputError, match="scene_mesh"):
        load_egobody(root)


def test_obj_reader_and_safe_pickles(tmp_path):
    p = tmp_path / "quad.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1/1/1 2/2/1 3/3/1 4/4/1\nf -4 -2 -1\n")
    v, f = read_obj(p)
    assert v.shape == (4, 3) and f.tolist() == [[0, 1, 2], [0, 2, 3], [0, 2, 3]]
    with pytest.raises(InputError, match="no faces"):
        (tmp_path / "empty.obj").write_text("v 0 0 0\n")
        read_obj(tmp_path / "empty.obj")
    # a pickle that would call a function is refused, with a one-line message naming the file
    root, _ = _lingo_fixture(tmp_path)

    class Evil:
        def __reduce__(self):
            return (print, ("pwned",))
    with open(root / "text_aug.pkl", "wb") as fh:
        pickle.dump([Evil()], fh)
    with pytest.raises(InputError, match="text_aug.pkl"):
        load_lingo(root)
