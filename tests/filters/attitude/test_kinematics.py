"""Kinematics: Ω(ω) of Deng et al. 2024, eq. 11 and its equivalent forms."""

import numpy as np

from filters.attitude import (
    axis_angle_to_quaternion,
    cross_matrix,
    omega_matrix,
    quaternion_multiply,
    quaternion_rate,
    random_quaternion,
    xi_matrix,
)


def test_omega_matrix_matches_deng2024_eq11():
    wx, wy, wz = 0.1, -0.2, 0.3
    expected = np.array([[0, wz, -wy, wx], [-wz, 0, wx, wy], [wy, -wx, 0, wz], [-wx, -wy, -wz, 0]])
    np.testing.assert_array_equal(omega_matrix([wx, wy, wz]), expected)


def test_rate_forms_agree():
    rng = np.random.default_rng(40)
    q = random_quaternion(20, rng)
    w = rng.normal(size=(20, 3))
    rate = quaternion_rate(q, w)
    np.testing.assert_allclose(rate, 0.5 * np.einsum("nij,nj->ni", omega_matrix(w), q), atol=1e-15)
    np.testing.assert_allclose(rate, 0.5 * np.einsum("nij,nj->ni", xi_matrix(q), w), atol=1e-15)
    # q̇ = ½ [ω, 0] ⊗ q with the composition convention A(p ⊗ q) = A(p) A(q).
    pure = np.concatenate([w, np.zeros((20, 1))], axis=1)
    np.testing.assert_allclose(rate, 0.5 * quaternion_multiply(pure, q), atol=1e-15)
    # The norm is preserved: q · q̇ = 0.
    np.testing.assert_allclose(np.sum(q * rate, axis=1), 0.0, atol=1e-15)


def test_constant_rate_rotation_is_the_exponential():
    """With constant ω along a fixed axis, q(t) = q(e, |ω| t) ⊗ q0."""
    q0 = random_quaternion(rng=41)
    w = np.array([0.0, 0.3, 0.4])
    t = 2.0
    exact = quaternion_multiply(axis_angle_to_quaternion(w, np.linalg.norm(w) * t), q0)
    h = 1e-6
    numeric = (
        quaternion_multiply(axis_angle_to_quaternion(w, np.linalg.norm(w) * (t + h)), q0)
        - quaternion_multiply(axis_angle_to_quaternion(w, np.linalg.norm(w) * (t - h)), q0)
    ) / (2 * h)
    np.testing.assert_allclose(numeric, quaternion_rate(exact, w), atol=1e-9)


def test_cross_matrix():
    rng = np.random.default_rng(42)
    a, b = rng.normal(size=(2, 5, 3))
    np.testing.assert_allclose(np.einsum("nij,nj->ni", cross_matrix(a), b), np.cross(a, b))
