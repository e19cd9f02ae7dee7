"""Quaternion algebra: conventions, identities (hypothesis) and conversions."""

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.spatial.transform import Rotation

from filters.attitude import (
    attitude_angle,
    attitude_matrix,
    axis_angle_to_quaternion,
    euler321_to_quaternion,
    grp_to_quaternion,
    mrp_to_quaternion,
    quaternion_conjugate,
    quaternion_from_matrix,
    quaternion_inverse,
    quaternion_mean,
    quaternion_multiply,
    quaternion_normalize,
    quaternion_to_euler321,
    quaternion_to_grp,
    quaternion_to_mrp,
    quaternion_to_rotation_vector,
    random_quaternion,
    rotate,
    rotation_vector_to_quaternion,
)

finite = st.floats(-1.0, 1.0, allow_nan=False)
quaternions = (
    arrays(np.float64, 4, elements=finite)
    .filter(lambda q: np.linalg.norm(q) > 1e-3)
    .map(lambda q: q / np.linalg.norm(q))
)


def same_attitude(p, q, atol=1e-12):
    """q and −q are the same attitude."""
    p, q = np.asarray(p).reshape(4), np.asarray(q).reshape(4)
    return min(np.abs(p - q).max(), np.abs(p + q).max()) <= atol


def test_attitude_matrix_is_scipy_transpose():
    """A(q) = Rotation.from_quat(q).as_matrix().T for 10⁴ random q (docs/conventions.md)."""
    q = random_quaternion(10_000, rng=1)
    expected = np.swapaxes(Rotation.from_quat(q).as_matrix(), -1, -2)
    np.testing.assert_allclose(attitude_matrix(q), expected, atol=1e-14)


def test_attitude_matrix_maps_inertial_to_body():
    """A rotation of the body by +90° about z sees the inertial x axis along body −y."""
    q = axis_angle_to_quaternion([0.0, 0.0, 1.0], np.pi / 2)
    np.testing.assert_allclose(rotate(q, [1.0, 0.0, 0.0]), [0.0, -1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(attitude_matrix(q) @ [1.0, 0.0, 0.0], [0.0, -1.0, 0.0], atol=1e-15)


def test_deng2024_eq10_form():
    """Deng et al. 2024, eq. 10 writes A = (2 q4² − 1) I + 2 q_v q_vᵀ − 2 q4 [q_v×] for unit q."""
    q = random_quaternion(50, rng=2)
    qv, q4 = q[:, :3], q[:, 3]
    skew = np.zeros((50, 3, 3))
    skew[:, 0, 1], skew[:, 0, 2], skew[:, 1, 2] = -qv[:, 2], qv[:, 1], -qv[:, 0]
    skew -= np.swapaxes(skew, 1, 2)
    expected = (
        (2 * q4**2 - 1)[:, None, None] * np.eye(3)
        + 2 * qv[:, :, None] * qv[:, None, :]
        - 2 * q4[:, None, None] * skew
    )
    np.testing.assert_allclose(attitude_matrix(q), expected, atol=1e-14)


@settings(max_examples=200, deadline=None)
@given(quaternions, quaternions, quaternions)
def test_product_associative_and_composes_matrices(p, q, r):
    np.testing.assert_allclose(
        quaternion_multiply(quaternion_multiply(p, q), r),
        quaternion_multiply(p, quaternion_multiply(q, r)),
        atol=1e-14,
    )
    np.testing.assert_allclose(
        attitude_matrix(quaternion_multiply(p, q)),
        attitude_matrix(p) @ attitude_matrix(q),
        atol=1e-14,
    )


@settings(max_examples=200, deadline=None)
@given(quaternions, arrays(np.float64, 3, elements=st.floats(-10, 10)))
def test_inverse_and_rotation(q, v):
    identity = quaternion_multiply(q, quaternion_inverse(q))
    np.testing.assert_allclose(identity, [0, 0, 0, 1], atol=1e-14)
    np.testing.assert_allclose(quaternion_conjugate(q), quaternion_inverse(q), atol=1e-14)
    np.testing.assert_allclose(rotate(q, v), attitude_matrix(q) @ v, atol=1e-12)
    np.testing.assert_allclose(attitude_matrix(q) @ attitude_matrix(q).T, np.eye(3), atol=1e-14)


@settings(max_examples=300, deadline=None)
@given(quaternions)
def test_round_trips(q):
    assert same_attitude(quaternion_from_matrix(attitude_matrix(q)), q)
    assert same_attitude(rotation_vector_to_quaternion(quaternion_to_rotation_vector(q)), q)
    assert same_attitude(grp_to_quaternion(quaternion_to_grp(q)), q)
    assert same_attitude(grp_to_quaternion(quaternion_to_grp(q, a=0.5, f=3.0), 0.5, 3.0), q)
    assert same_attitude(mrp_to_quaternion(quaternion_to_mrp(q)), q)
    assert np.linalg.norm(quaternion_to_mrp(q)) <= 1 + 1e-12
    assert same_attitude(euler321_to_quaternion(quaternion_to_euler321(q)), q, atol=1e-7)


def test_euler321_at_gimbal_lock():
    """At pitch ±90° only ψ ∓ φ is defined: the attitude is kept and roll is zero."""
    for pitch in (np.pi / 2, -np.pi / 2):
        q = euler321_to_quaternion([0.3, pitch, -0.4])
        angles = quaternion_to_euler321(q)
        assert angles[2] == 0.0
        assert angles[1] == pytest.approx(pitch, abs=1e-7)
        assert same_attitude(euler321_to_quaternion(angles), q, atol=1e-7)


def test_from_matrix_near_pi_rotations():
    """The four-candidate method is exact for 180° rotations where q4 = 0."""
    axes = np.eye(3)
    for axis in axes:
        q = axis_angle_to_quaternion(axis, np.pi)
        assert same_attitude(quaternion_from_matrix(attitude_matrix(q)), q)


def test_small_angle_series_are_continuous():
    rv = np.array([[1e-9, -2e-9, 3e-9], [1e-5, 0, 0], [2e-4, 1e-4, 0]])
    q = rotation_vector_to_quaternion(rv)
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0, atol=1e-15)
    np.testing.assert_allclose(quaternion_to_rotation_vector(q), rv, rtol=1e-12, atol=1e-20)


def test_grp_scale_is_angle_for_small_rotations():
    """With the USQUE choice f = 2(a + 1), |p| ≈ θ for small θ (Crassidis & Markley 2003)."""
    q = axis_angle_to_quaternion([0.0, 1.0, 0.0], 1e-3)
    assert np.linalg.norm(quaternion_to_grp(q)) == pytest.approx(1e-3, rel=1e-6)


def test_euler321_matches_scipy_intrinsic_zyx():
    angles = np.random.default_rng(3).uniform([-np.pi, -1.5, -np.pi], [np.pi, 1.5, np.pi], (100, 3))
    expected = np.swapaxes(Rotation.from_euler("ZYX", angles).as_matrix(), -1, -2)
    np.testing.assert_allclose(
        attitude_matrix(euler321_to_quaternion(angles)), expected, atol=1e-14
    )
    np.testing.assert_allclose(
        quaternion_to_euler321(euler321_to_quaternion(angles)), angles, atol=1e-12
    )


def test_attitude_angle():
    q = random_quaternion(100, rng=4)
    angle = np.random.default_rng(5).uniform(0, np.pi, 100)
    axis = np.random.default_rng(6).standard_normal((100, 3))
    p = quaternion_multiply(axis_angle_to_quaternion(axis, angle), q)
    np.testing.assert_allclose(attitude_angle(p, q), angle, atol=1e-7)
    np.testing.assert_allclose(attitude_angle(-p, q), angle, atol=1e-7)


def test_random_quaternions_are_uniform():
    """Uniform on SO(3): E[q_i²] = 1/4 and the rotation-angle density is (1 − cos θ)/π."""
    q = random_quaternion(200_000, rng=7)
    np.testing.assert_allclose(np.mean(q**2, axis=0), 0.25, atol=3e-3)
    theta = attitude_angle(q, np.array([0.0, 0.0, 0.0, 1.0]))
    # P(θ ≤ π/2) = (θ − sin θ)/π at θ = π/2.
    assert np.mean(theta <= np.pi / 2) == pytest.approx((np.pi / 2 - 1) / np.pi, abs=3e-3)
    assert random_quaternion((2, 3), rng=1).shape == (2, 3, 4)
    np.testing.assert_array_equal(random_quaternion(5, rng=9), random_quaternion(5, rng=9))


def test_quaternion_mean_ignores_signs_and_weights_work():
    rng = np.random.default_rng(8)
    centre = random_quaternion(rng=rng)
    small = rng.normal(scale=0.01, size=(500, 3))
    samples = quaternion_multiply(rotation_vector_to_quaternion(small), centre)
    flipped = samples * np.where(rng.random(500) < 0.5, -1.0, 1.0)[:, None]
    mean = quaternion_mean(flipped)
    assert attitude_angle(mean, centre) < 3e-3
    other = quaternion_multiply(axis_angle_to_quaternion([1, 0, 0], 1.0), centre)
    weighted = quaternion_mean(np.stack([centre, other]), np.array([1.0, 0.0]))
    assert attitude_angle(weighted, centre) < 1e-12


def test_torch_matches_numpy_and_is_differentiable():
    q = random_quaternion(64, rng=10)
    p = random_quaternion(64, rng=11)
    qt = torch.tensor(q, requires_grad=True)
    out = quaternion_multiply(torch.tensor(p), qt)
    assert isinstance(out, torch.Tensor)
    np.testing.assert_allclose(out.detach().numpy(), quaternion_multiply(p, q), atol=1e-15)
    np.testing.assert_allclose(attitude_matrix(qt).detach().numpy(), attitude_matrix(q), atol=1e-15)
    rv = quaternion_to_rotation_vector(qt)
    rv.sum().backward()
    assert torch.all(torch.isfinite(qt.grad))
    rv0 = torch.zeros(3, dtype=torch.float64, requires_grad=True)
    rotation_vector_to_quaternion(rv0).sum().backward()
    np.testing.assert_allclose(rv0.grad.numpy(), 0.5)


def test_normalize_rejects_zero_quaternion():
    with pytest.raises(ValueError, match="zero or non-finite"):
        quaternion_normalize(np.zeros(4))


def test_single_matrix_gives_single_quaternion():
    q = random_quaternion(rng=35)
    assert quaternion_from_matrix(attitude_matrix(q)).shape == (4,)
