"""Mirrored training copies: an exact reflection of the pose, captions with sides swapped, splits kept."""
import numpy as np
import torch

from model_runtime.data.library import ClipLibrary, source_name
from model_runtime.data.mirror import MIRROR_JOINTS, add_mirrors, mirror_caption, mirror_pose
from model_runtime.joints import JOINT_NAMES
from model_runtime.skeleton import quat_to_matrix, yaw_matrix
from model_runtime.quat import matrix_to_quat_np

S = torch.diag(torch.tensor([-1.0, 1.0, 1.0], dtype=torch.float64))


def _random_clip(frames: int = 12, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(frames, 22, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    return q.astype(np.float64), rng.normal(size=(frames, 3))


def test_joint_twins():
    for i, j in enumerate(MIRROR_JOINTS):
        a, b = JOINT_NAMES[i], JOINT_NAMES[j]
        assert MIRROR_JOINTS[j] == i
        assert a.replace("left", "right") == b or b.replace("left", "right") == a or a == b


def test_rotations_are_reflected_and_twins_swapped():
    rot, pel = _random_clip()
    mrot, mpel = mirror_pose(rot, pel)
    r = quat_to_matrix(torch.as_tensor(rot))
    m = quat_to_matrix(torch.as_tensor(mrot))
    for i, j in enumerate(MIRROR_JOINTS):
        assert torch.allclose(m[:, i], S @ r[:, j] @ S, atol=1e-6)
    assert np.allclose(mpel, pel * [-1, 1, 1])
    back, pel2 = mirror_pose(mrot, mpel)
    assert np.allclose(back, rot) and np.allclose(pel2, pel)


def test_a_left_turn_becomes_a_right_turn():
    frames = 10
    yaw = np.linspace(0.0, 1.0, frames)                      # counter-clockwise: a turn to the left
    rot = np.tile(np.array([1.0, 0, 0, 0]), (frames, 22, 1))
    rot[:, 0] = matrix_to_quat_np(yaw_matrix(torch.as_tensor(yaw)).numpy())
    mrot, _ = mirror_pose(rot, np.zeros((frames, 3)))
    fwd = quat_to_matrix(torch.as_tensor(mrot[:, 0]))[:, :, 1]   # where the body's +Y points
    heading = np.unwrap(np.arctan2(fwd[:, 1].numpy(), fwd[:, 0].numpy()))
    assert np.allclose(heading - heading[0], -yaw, atol=1e-6)


def test_captions_swap_sides():
    assert mirror_caption("a person turns left") == "a person turns right"
    assert mirror_caption("Right then left, clockwise") == "Left then right, counterclockwise"
    assert mirror_caption("a person walks forward") == "a person walks forward"
    assert mirror_caption("leftover") == "leftover"


def test_copies_keep_source_split_and_licence():
    clips = [_random_clip(8 + k, seed=k) for k in range(3)]
    lib = ClipLibrary(["cmu/a", "bandai/b", "cmu/a#turn0"], ["turns left", "waves", "x"], ["cmu", "bandai", "cmu"],
                      np.concatenate([c[0] for c in clips]).astype(np.float32),
                      np.concatenate([c[1] for c in clips]).astype(np.float32),
                      np.cumsum([0] + [len(c[0]) for c in clips]).astype(np.int64))
    out, new = add_mirrors(lib, [0, 1, 2])
    assert len(new) == 2                                      # derived clips are not mirrored
    assert [out.names[i] for i in new] == ["cmu/a#mirror0", "bandai/b#mirror0"]
    assert [out.captions[i] for i in new] == ["turns right", "waves"]
    assert [out.sources[i] for i in new] == ["cmu", "bandai"]
    for i in new:
        src = out.names.index(source_name(out.names[i]))
        assert out.is_held_out(i) == out.is_held_out(src) and out.frames(i) == out.frames(src)


def test_denoising_stages_train_on_mirrored_copies_unless_told_not_to():
    from model_runtime import load_model
    from model_runtime.training.setup import build_samplers
    from synthetic import synthetic_library
    lib = synthetic_library(20, 40)
    model = load_model(config="tiny")
    with_copies, _ = build_samplers("prior", model, lib, seed=0, rank=0)
    without, _ = build_samplers("prior", model, lib, seed=0, rank=0, mirror=False)
    vae, _ = build_samplers("vae", model, lib, seed=0, rank=0)
    count = lambda s: sum(s.lib.names[i].endswith("#mirror0") for i, _ in s.items)  # noqa: E731
    assert count(with_copies) > 0 and count(without) == 0 and count(vae) == 0
