"""Rotation maths checked against SciPy's Rotation (an independent implementation), not only by round trips.

Our quaternions are (w, x, y, z); SciPy's are (x, y, z, w). Two quaternions are the same rotation when
they are equal up to sign, so comparisons go through |q . q_ref| = 1 or through rotation matrices.
"""
from __future__ import annotations

import numpy as np
import pytest
import torch

from model_runtime import continuous_quaternions, matrix_to_quat_np, qconj, qmul, qslerp
from model_runtime.skeleton import (axis_angle_to_matrix, matrix_to_axis_angle, matrix_to_quat, matrix_to_rot6d,
                                    quat_slerp, quat_to_matrix, rot6d_to_matrix, yaw_matrix)

scipy = pytest.importorskip("scipy")
from scipy.spatial.transform import Rotation, Slerp  # noqa: E402

SCIPY_VERSION = tuple(int(p) for p in scipy.__version__.split(".")[:2])

TOL = 1e-9     # float64 throughout


def to_wxyz(r: "Rotation") -> np.ndarray:
    return np.roll(r.as_quat(), 1, axis=-1)


def from_wxyz(q: np.ndarray) -> "Rotation":
    return Rotation.from_quat(np.roll(np.asarray(q, dtype=np.float64), -1, axis=-1))


def assert_same_rotation(q: np.ndarray, ref: "Rotation", tol: float = TOL) -> None:
    """q (..., 4) unit quaternions represent the rotations `ref` (sign free)."""
    q = np.asarray(q, dtype=np.float64)
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0, atol=tol)
    np.testing.assert_allclose(np.abs(np.sum(q * to_wxyz(ref).reshape(q.shape), axis=-1)), 1.0, atol=tol)


def scipy_slerp(q0: "Rotation", q1: "Rotation", t: float) -> "Rotation":
    """Per-row SciPy slerp from q0[i] to q1[i] (the shortest arc) at t."""
    return Rotation.concatenate([Slerp([0.0, 1.0], Rotation.concatenate([q0[i], q1[i]]))([t])
                                 for i in range(len(q0))])


def random_rotations(n: int, seed: int) -> "Rotation":
    """Random rotations plus the hard cases: identity, half turns (w = 0) about axes and a diagonal."""
    half_turns = Rotation.from_rotvec(np.pi * np.array([(1, 0, 0), (0, 1, 0), (0, 0, 1),
                                                         (1 / np.sqrt(2), -1 / np.sqrt(2), 0)]))
    tiny = Rotation.from_rotvec([(1e-9, 0.0, 0.0), (0.0, -3e-7, 2e-7)])
    return Rotation.concatenate([Rotation.identity(), half_turns, tiny, Rotation.random(n, random_state=seed)])


# ----------------------------------------------------------------------------- NumPy (model_runtime.quat)

def test_qmul_is_scipy_composition():
    a, b = Rotation.random(64, random_state=1), Rotation.random(64, random_state=2)
    got = qmul(to_wxyz(a), to_wxyz(b))
    assert_same_rotation(got, a * b)            # a * b applies b first: matrix A @ B
    np.testing.assert_allclose(from_wxyz(got).as_matrix(), a.as_matrix() @ b.as_matrix(), atol=TOL)
    assert_same_rotation(qconj(to_wxyz(a)), a.inv())


def test_qmul_broadcasts_like_scipy():
    one = Rotation.random(random_state=3)
    many = Rotation.random(8, random_state=4)
    got = qmul(to_wxyz(one)[None], to_wxyz(many).reshape(2, 4, 4))
    assert_same_rotation(got.reshape(8, 4), one * many)


@pytest.mark.parametrize("t", [0.0, 0.25, 0.5, 0.9, 1.0])
def test_qslerp_matches_scipy_slerp(t):
    q0, q1 = Rotation.random(32, random_state=5), Rotation.random(32, random_state=6)
    w0, w1 = to_wxyz(q0), to_wxyz(q1)
    w1[::2] *= -1.0                       # the other sign of the same rotation must take the same short arc
    got = qslerp(w0, w1, t)
    assert_same_rotation(got, scipy_slerp(q0, q1, t), tol=1e-8)


def test_qslerp_of_nearly_equal_rotations():
    q0 = Rotation.random(4, random_state=7)
    q1 = Rotation.from_rotvec(np.full((4, 3), 1e-8)) * q0
    got = qslerp(to_wxyz(q0), to_wxyz(q1), 0.5)
    want = Rotation.from_rotvec(np.full((4, 3), 0.5e-8)) * q0
    assert_same_rotation(got, want)


def test_matrix_to_quat_np_matches_scipy():
    r = random_rotations(200, seed=8)
    got = matrix_to_quat_np(r.as_matrix())
    assert_same_rotation(got, r)
    assert (got[:, 0] >= 0.0).all()


def test_continuous_quaternions_keep_each_rotation():
    # a spinning and tumbling bone, 120 frames x 3 bones, each key with a random sign
    rng = np.random.default_rng(9)
    t = np.linspace(0.0, 6.0, 120)[:, None, None]
    axes = np.array([(0, 0, 1), (1, 1, 0), (0.3, -1, 0.5)], dtype=np.float64)
    axes /= np.linalg.norm(axes, axis=-1, keepdims=True)
    r = Rotation.from_rotvec((t * axes[None] * np.array([1.0, 2.5, 4.0])[None, :, None]).reshape(-1, 3))
    q = to_wxyz(r).reshape(120, 3, 4) * rng.choice([-1.0, 1.0], size=(120, 3, 1))
    got = continuous_quaternions(q)
    np.testing.assert_allclose(from_wxyz(got.reshape(-1, 4)).as_matrix(), r.as_matrix(), atol=TOL)
    assert (np.sum(got[1:] * got[:-1], axis=-1) > 0.0).all()     # no jump to the antipode between keys
    assert (got[0, :, 0] >= 0.0).all()


# ----------------------------------------------------------------------------- torch (model_runtime.skeleton)

def test_quat_to_matrix_matches_scipy():
    r = random_rotations(200, seed=10)
    q = torch.from_numpy(to_wxyz(r)) * torch.linspace(0.5, 3.0, len(r), dtype=torch.float64)[:, None]
    got = quat_to_matrix(q).numpy()                 # normalises its input
    np.testing.assert_allclose(got, r.as_matrix(), atol=TOL)


def test_matrix_to_quat_matches_scipy():
    r = random_rotations(200, seed=11)
    got = matrix_to_quat(torch.from_numpy(r.as_matrix())).numpy()
    assert_same_rotation(got, r)
    assert (got[:, 0] >= 0.0).all()


def test_axis_angle_to_matrix_matches_scipy():
    rng = np.random.default_rng(12)
    axes = rng.normal(size=(64, 3))
    axes /= np.linalg.norm(axes, axis=-1, keepdims=True)
    angles = np.concatenate(([0.0, 1e-10, 1e-6, np.pi, 4.0, 2 * np.pi - 1e-3], rng.uniform(0, np.pi, 58)))
    rv = axes * angles[:, None]
    got = axis_angle_to_matrix(torch.from_numpy(rv)).numpy()
    np.testing.assert_allclose(got, Rotation.from_rotvec(rv).as_matrix(), atol=TOL)


def test_matrix_to_axis_angle_matches_scipy():
    r = random_rotations(200, seed=13)
    got = matrix_to_axis_angle(torch.from_numpy(r.as_matrix())).numpy()
    want = r.as_rotvec()
    np.testing.assert_allclose(np.linalg.norm(got, axis=-1), np.linalg.norm(want, axis=-1), atol=1e-7)
    # at a half turn +axis and -axis are the same rotation: compare as rotations there
    np.testing.assert_allclose(Rotation.from_rotvec(got).as_matrix(), r.as_matrix(), atol=1e-7)
    not_half = np.linalg.norm(want, axis=-1) < np.pi - 1e-6
    np.testing.assert_allclose(got[not_half], want[not_half], atol=1e-7)


def test_yaw_matrix_matches_scipy():
    yaw = np.linspace(-4.0, 4.0, 17)
    got = yaw_matrix(torch.from_numpy(yaw)).numpy()
    np.testing.assert_allclose(got, Rotation.from_euler("z", yaw[:, None]).as_matrix(), atol=TOL)


def test_rot6d_holds_the_first_two_columns():
    r = random_rotations(100, seed=14)
    m = r.as_matrix()
    d6 = matrix_to_rot6d(torch.from_numpy(m)).numpy()
    np.testing.assert_allclose(d6, np.concatenate((m[:, :, 0], m[:, :, 1]), axis=-1), atol=0.0)


@pytest.mark.skipif(SCIPY_VERSION < (1, 11), reason="needs SciPy >= 1.11 (infinite weights in align_vectors)")
def test_rot6d_to_matrix_matches_scipy_alignment():
    """A noisy 6D vector gives the rotation whose x axis is exactly along a1 and whose y axis is as near a2
    as it can be: SciPy's align_vectors with the first vector pair weighted infinitely."""
    rng = np.random.default_rng(15)
    m = Rotation.random(50, random_state=16).as_matrix()
    d6 = np.concatenate((m[:, :, 0], m[:, :, 1]), axis=-1) * rng.uniform(0.5, 2.0, (50, 1)) \
        + rng.normal(scale=0.2, size=(50, 6))
    got = rot6d_to_matrix(torch.from_numpy(d6)).numpy()
    e1, e2 = np.eye(3)[0], np.eye(3)[1]
    for i in range(len(d6)):
        want, _ = Rotation.align_vectors([d6[i, :3], d6[i, 3:]], [e1, e2], weights=[np.inf, 1.0])
        np.testing.assert_allclose(got[i], want.as_matrix(), atol=1e-8)


@pytest.mark.parametrize("t", [0.0, 0.3, 1.0])
def test_torch_quat_slerp_matches_scipy_slerp(t):
    q0, q1 = Rotation.random(16, random_state=17), Rotation.random(16, random_state=18)
    w1 = to_wxyz(q1)
    w1[1::2] *= -1.0
    got = quat_slerp(torch.from_numpy(to_wxyz(q0)), torch.from_numpy(w1), t).numpy()
    assert_same_rotation(got, scipy_slerp(q0, q1, t), tol=1e-8)
