"""Shared Kalman building blocks."""

import numpy as np
import pytest

from filters.gaussian import (
    chi2_band,
    discrete_process_noise,
    joseph_update,
    kalman_gain,
    mahalanobis_squared,
)


def test_gain_and_joseph_update_match_textbook():
    p = np.array([[4.0, 1.0], [1.0, 2.0]])
    h = np.array([[1.0, 0.0]])
    r = np.array([[1.0]])
    gain, s = kalman_gain(p, h, r)
    np.testing.assert_allclose(s, [[5.0]])
    np.testing.assert_allclose(gain, [[0.8], [0.2]])
    updated = joseph_update(p, gain, h, r)
    np.testing.assert_allclose(updated, (np.eye(2) - gain @ h) @ p, atol=1e-14)


def test_joseph_stays_positive_with_suboptimal_gain():
    p = np.diag([1e-8, 1.0])
    h = np.array([[1.0, 1.0]])
    r = np.array([[1e-10]])
    gain = np.array([[0.5], [0.5]])
    assert np.all(np.linalg.eigvalsh(joseph_update(p, gain, h, r)) > 0)


def test_van_loan_matches_closed_form_for_double_integrator():
    a = np.array([[0.0, 1.0], [0.0, 0.0]])
    q = np.diag([0.0, 2.0])
    phi, qd = discrete_process_noise(a, q, 3.0)
    np.testing.assert_allclose(phi, [[1, 3], [0, 1]], atol=1e-14)
    np.testing.assert_allclose(qd, 2.0 * np.array([[9.0, 4.5], [4.5, 3.0]]), atol=1e-12)


def test_nees_of_gaussian_samples_is_inside_the_band():
    rng = np.random.default_rng(50)
    cov = np.array([[2.0, 0.3, 0.0], [0.3, 1.0, 0.1], [0.0, 0.1, 0.5]])
    samples = rng.multivariate_normal(np.zeros(3), cov, size=400)
    nees = mahalanobis_squared(samples, cov)
    lower, upper = chi2_band(3, runs=400)
    assert lower < nees.mean() < upper
    assert chi2_band(2, 1) == pytest.approx((0.0506356, 7.3777589), rel=1e-6)


def test_batched_forms_equal_single_ones():
    rng = np.random.default_rng(51)
    a = rng.normal(size=(5, 4, 4))
    p = a @ np.swapaxes(a, 1, 2) + np.eye(4)
    h = rng.normal(size=(5, 2, 4))
    r = np.tile(np.diag([0.3, 0.5]), (5, 1, 1))
    gains, s = kalman_gain(p, h, r)
    updated = joseph_update(p, gains, h, r)
    for i in range(5):
        g, si = kalman_gain(p[i], h[i], r[i])
        np.testing.assert_allclose(gains[i], g, atol=1e-12)
        np.testing.assert_allclose(s[i], si, atol=1e-12)
        np.testing.assert_allclose(updated[i], joseph_update(p[i], g, h[i], r[i]), atol=1e-12)


def test_van_loan_batches():
    a = np.stack([np.array([[0.0, 1.0], [0.0, 0.0]]), np.array([[0.0, 1.0], [-1.0, -0.1]])])
    q = np.diag([0.0, 2.0])
    phi, qd = discrete_process_noise(a, q, 0.5)
    for i in range(2):
        p1, q1 = discrete_process_noise(a[i], q, 0.5)
        np.testing.assert_allclose(phi[i], p1, atol=1e-14)
        np.testing.assert_allclose(qd[i], q1, atol=1e-14)
