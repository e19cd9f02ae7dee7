"""LAMBDA: decorrelation, integer search, ratio test and success rate against brute force."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import norm

from filters.gnss.lambda_ import (
    bootstrapped_success_rate,
    decorrelate,
    integer_search,
    lambda_method,
    ldl,
)


def enumerate_ellipsoid(a: np.ndarray, q: np.ndarray, radius: float) -> tuple[np.ndarray, ...]:
    """Every integer vector ``z`` with ``(a − z)ᵀ Q⁻¹ (a − z) ≤ radius``, by exhaustive
    enumeration in the natural coordinate order (no decorrelation, no shrinking): with
    ``Q⁻¹ = Uᵀ U`` (``U`` upper triangular) the last coordinate is bounded alone, then each
    earlier one given the later ones. Returns the points and their squared norms."""
    n = len(a)
    u = np.linalg.cholesky(np.linalg.inv(q)).T
    points = np.zeros((1, 0))
    partial = np.zeros(1)
    for k in range(n - 1, -1, -1):
        later = points  # columns k+1 … n-1
        centre = a[k] + (later - a[k + 1 :]) @ u[k, k + 1 :] / u[k, k] * -1.0
        half = np.sqrt(np.maximum(radius - partial, 0.0)) / abs(u[k, k])
        lo, hi = np.ceil(centre - half).astype(int), np.floor(centre + half).astype(int)
        counts = np.maximum(hi - lo + 1, 0)
        parent = np.repeat(np.arange(len(points)), counts)
        offsets = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
        zk = lo[parent] + offsets
        partial = partial[parent] + (u[k, k] * (centre[parent] - zk)) ** 2
        points = np.column_stack([zk, later[parent]])
        keep = partial <= radius
        points, partial = points[keep], partial[keep]
    return points, partial


def random_problem(rng: np.random.Generator, n: int, badly: bool) -> tuple[np.ndarray, ...]:
    """Float ambiguities and a covariance: eigenvalues log-uniform over [0.05, 2] cycles²
    (well conditioned) or over [1e-4, 20] cycles² (badly conditioned, GNSS-like)."""
    basis, _ = np.linalg.qr(rng.standard_normal((n, n)))
    low, high = (1e-4, 20.0) if badly else (0.05, 2.0)
    eig = np.exp(rng.uniform(np.log(low), np.log(high), n))
    eig[:2] = low, high  # span the whole range
    q = basis @ np.diag(eig) @ basis.T
    return rng.normal(scale=50.0, size=n), 0.5 * (q + q.T)


def test_lambda_matches_brute_force_ils_on_2000_problems():
    rng = np.random.default_rng(20251995)
    condition_reduced = 0
    for trial in range(2000):
        n, badly = 2 + trial % 7, trial % 2 == 1
        a, q = random_problem(rng, n, badly)
        est = lambda_method(a, q)
        # Enumerate with a margin for round-off (1e-6 relative), rank by accurate norms.
        points, _ = enumerate_ellipsoid(a, q, est.squared_norms[1] * (1 + 1e-6) + 1e-9)
        d = points - a
        norms = np.einsum("ij,ji->i", d, np.linalg.solve(q, d.T))
        order = np.argsort(norms)[:2]
        assert len(points) >= 2
        np.testing.assert_array_equal(est.candidates, points[order], err_msg=f"trial {trial}")
        np.testing.assert_allclose(est.squared_norms, norms[order], rtol=1e-7, atol=1e-9)
        z = est.z_transform
        np.testing.assert_array_equal(z, np.rint(z))
        assert abs(round(np.linalg.det(z))) == 1
        cond, cond_z = np.linalg.cond(q), np.linalg.cond(z.T @ q @ z)
        assert cond_z <= cond * (1 + 1e-9)
        condition_reduced += cond_z < 0.5 * cond
    assert condition_reduced > 800  # every badly conditioned problem gains at least 2×


def test_enumeration_agrees_with_a_plain_box_search():
    rng = np.random.default_rng(3)
    for n in (2, 3, 4):
        a, q = random_problem(rng, n, badly=True)
        radius = 3.0
        points, _ = enumerate_ellipsoid(a, q, radius)
        half = np.sqrt(radius * np.diag(q))
        axes = [np.arange(np.ceil(a[i] - half[i]), np.floor(a[i] + half[i]) + 1) for i in range(n)]
        box = np.array(np.meshgrid(*axes, indexing="ij")).reshape(n, -1).T
        d = box - a
        box_norms = np.einsum("ij,jk,ik->i", d, np.linalg.inv(q), d)
        inside = box[box_norms <= radius]
        assert {tuple(p) for p in inside} == {tuple(p) for p in points.astype(float)}


def test_ldl_and_the_decorrelated_factors():
    rng = np.random.default_rng(1)
    _, q = random_problem(rng, 6, badly=True)
    lo, d = ldl(q)
    np.testing.assert_allclose(lo.T @ np.diag(d) @ lo, q, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(np.diag(lo), 1.0)
    assert np.allclose(np.triu(lo, 1), 0.0)
    z, lz, dz = decorrelate(q)
    np.testing.assert_allclose(lz.T @ np.diag(dz) @ lz, z.T @ q @ z, rtol=1e-9, atol=1e-10)
    assert np.all(np.abs(np.tril(lz, -1)) <= 0.5 + 1e-12)  # integer Gauss transforms applied
    # Volume is invariant: det Q = ∏ D before and after.
    assert np.prod(d) == pytest.approx(np.prod(dz), rel=1e-9)
    with pytest.raises(np.linalg.LinAlgError):
        ldl(-np.eye(3))


def test_search_returns_several_candidates_in_order():
    rng = np.random.default_rng(5)
    a, q = random_problem(rng, 5, badly=False)
    z, lo, d = decorrelate(q)
    found, norms = integer_search(z.T @ a, lo, d, candidates=6)
    assert np.all(np.diff(norms) >= 0)
    _, all_norms = enumerate_ellipsoid(z.T @ a, z.T @ q @ z, norms[-1] * (1 + 1e-9))
    np.testing.assert_allclose(np.sort(all_norms)[:6], norms, rtol=1e-9)
    assert len({tuple(f) for f in found}) == 6


def test_an_integer_float_solution_is_its_own_fix():
    q = np.array([[0.5, 0.3], [0.3, 0.4]])
    est = lambda_method([3.0, -7.0], q)
    np.testing.assert_array_equal(est.best, [3, -7])
    assert est.squared_norms[0] == 0 and est.ratio == np.inf
    assert est.accepted(3.0)


def test_bootstrapped_success_rate_bounds_the_monte_carlo_ils_success():
    rng = np.random.default_rng(11)
    for n, badly in ((3, False), (4, True)):
        _, q = random_problem(rng, n, badly)
        q = q * 0.02  # a problem with an intermediate success rate
        est = lambda_method(np.zeros(n), q)
        bound = est.success_rate
        draws = rng.multivariate_normal(np.zeros(n), q, size=1500)
        successes = sum(np.all(lambda_method(x, q).best == 0) for x in draws)
        rate = successes / len(draws)
        sigma = np.sqrt(bound * (1 - bound) / len(draws))
        assert rate >= bound - 4 * sigma - 1e-3
    # One dimension: exact, 2Φ(1/(2σ)) − 1.
    assert bootstrapped_success_rate([0.09]) == pytest.approx(2 * norm.cdf(1 / 0.6) - 1)


def test_ratio_and_success_rate_acceptance():
    q = np.diag([0.01, 0.01])
    est = lambda_method([0.1, -0.05], q)
    assert est.ratio > 3 and est.success_rate > 0.99999
    assert est.accepted(3.0, 0.999)
    ambiguous = lambda_method([0.5, 0.0], np.diag([0.3, 0.3]))
    assert ambiguous.ratio < 1.01 and not ambiguous.accepted(1.5)
    with pytest.raises(ValueError, match="covariance"):
        lambda_method([0.0, 1.0], np.eye(3))
