"""The shared quaternion code against scipy's independent implementation."""

import itertools

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

from modb_kernel import kinematics, quaternion, resample

ORDERS = ["".join(p) for p in itertools.permutations("XYZ")]


def scipy_quat(r: Rotation) -> np.ndarray:
    x, y, z, w = r.as_quat().T  # scipy is scalar-last
    return quaternion.canonical(np.stack([w, x, y, z], axis=-1))


@pytest.mark.parametrize("order", ORDERS)
def test_from_euler_matches_scipy_intrinsic(order):
    rng = np.random.default_rng(1)
    angles = rng.uniform(-np.pi, np.pi, size=(500, 3))
    ours = quaternion.from_euler(angles, order)
    theirs = scipy_quat(Rotation.from_euler(order, angles))  # upper case = intrinsic in scipy
    assert np.allclose(ours, theirs, atol=1e-12)


@pytest.mark.parametrize("order", ORDERS + ["Z", "XY", "YX"])
def test_to_euler_inverts_from_euler(order):
    rng = np.random.default_rng(2)
    angles = rng.uniform(-np.pi, np.pi, size=(500, len(order)))
    if len(order) == 3:
        angles[:, 1] = rng.uniform(-1.5, 1.5, size=500)  # away from gimbal lock
    q = quaternion.from_euler(angles, order)
    back = quaternion.from_euler(quaternion.to_euler(q, order), order)
    assert np.allclose(back, q, atol=1e-9)


def test_rotate_and_multiply_match_scipy():
    rng = np.random.default_rng(3)
    a, b = Rotation.random(200, random_state=4), Rotation.random(200, random_state=5)
    v = rng.normal(size=(200, 3))
    assert np.allclose(quaternion.rotate(scipy_quat(a), v), a.apply(v), atol=1e-12)
    product = quaternion.canonical(quaternion.multiply(scipy_quat(a), scipy_quat(b)))
    assert np.allclose(product, scipy_quat(a * b), atol=1e-12)
    assert np.allclose(quaternion.to_matrix(scipy_quat(a)), a.as_matrix(), atol=1e-12)


def test_canonical_sign_and_angle_between():
    q = quaternion.canonical([[-0.5, 0.5, 0.5, 0.5]])
    assert q[0, 0] == 0.5
    a = Rotation.random(100, random_state=6)
    b = Rotation.random(100, random_state=7)
    expected = (a.inv() * b).magnitude()
    assert np.allclose(quaternion.angle_between(scipy_quat(a), scipy_quat(b)), expected, atol=1e-9)
    # q and -q are the same rotation; tiny angles stay accurate.
    qa = scipy_quat(a)
    assert np.allclose(quaternion.angle_between(qa, -qa), 0.0)
    tiny = scipy_quat(a * Rotation.from_rotvec([1e-7, 0, 0]))
    assert np.allclose(quaternion.angle_between(qa, tiny), 1e-7, rtol=1e-3)


def test_rotation_vectors_and_powers_match_scipy():
    r = Rotation.random(300, random_state=8)
    q = scipy_quat(r)
    assert np.allclose(quaternion.to_rotation_vector(q), r.as_rotvec(), atol=1e-12)
    assert np.allclose(quaternion.to_rotation_vector(-q), r.as_rotvec(), atol=1e-12)
    assert np.allclose(quaternion.from_rotation_vector(r.as_rotvec()), q, atol=1e-12)
    # q^t is the slerp from the identity: scipy's rotation vector scaled by t.
    expected = scipy_quat(Rotation.from_rotvec(0.3 * r.as_rotvec()))
    assert np.allclose(quaternion.canonical(quaternion.power(q, 0.3)), expected, atol=1e-12)
    assert np.allclose(quaternion.to_rotation_vector(np.array([1.0, 0, 0, 0])), 0.0)


def test_forward_kinematics_two_bone_chain():
    # Root at (0,1,0) turned 90 degrees about Y; child one metre along +X in the root frame.
    rot_y = quaternion.from_euler([[np.pi / 2]], "Y")[0]
    rotations = np.array([[rot_y, [1, 0, 0, 0]]])
    p = kinematics.world_positions([-1, 0], [[0, 0, 0], [1, 0, 0]], rotations, [[[0, 1, 0]]], [0])
    assert np.allclose(p[0], [[0, 1, 0], [0, 1, -1]])


@pytest.mark.parametrize("order", ORDERS)
@pytest.mark.parametrize("middle", [90.0, -90.0, 89.9999999, -89.99999999])
def test_to_euler_at_gimbal_lock(order, middle):
    rng = np.random.default_rng(9)
    angles = np.radians(
        np.column_stack(
            [rng.uniform(-180, 180, 50), np.full(50, middle), rng.uniform(-180, 180, 50)]
        )
    )
    q = quaternion.from_euler(angles, order)
    back = quaternion.from_euler(quaternion.to_euler(q, order), order)
    assert np.allclose(quaternion.angle_between(back, q), 0.0, atol=1e-6)


def test_resampling_matches_scipy_slerp_and_numpy_interp():
    rng = np.random.default_rng(5)
    q = Rotation.random(60 * 4, random_state=6).as_quat().reshape(60, 4, 4)[..., [3, 0, 1, 2]]
    q[q[..., 0] < 0] *= -1
    t = rng.normal(size=(60, 2, 3))
    frames = np.concatenate([np.linspace(0, 59, 211), [0, 59, 30.5]])
    rotations, translations = resample.sampled(q, t, frames)
    for j in range(4):
        want = Slerp(np.arange(60), Rotation.from_quat(q[:, j][:, [1, 2, 3, 0]]))(frames)
        assert np.allclose(Rotation.from_quat(rotations[:, j][:, [1, 2, 3, 0]]).as_matrix(),
                           want.as_matrix(), atol=1e-12)  # fmt: skip
    for k, c in itertools.product(range(2), range(3)):
        assert np.allclose(translations[:, k, c], np.interp(frames, np.arange(60), t[:, k, c]))
    assert np.all(rotations[..., 0] >= 0)
    assert np.allclose(resample.fps_frames(9, 120.0, 30.0), [0, 4, 8])
