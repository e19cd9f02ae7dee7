"""Double differences, their correlated covariance and the float normal equations, against an
independent derivation from undifferenced observations."""

from __future__ import annotations

import numpy as np
import pytest

from filters.gnss.differencing import (
    common_view,
    double_difference_covariance,
    double_difference_operator,
    double_differences,
    reference_satellite,
    single_differences,
)
from filters.gnss.relative import AmbiguityNormals, epoch_normal_equations

LAMBDA = 0.190293672798365


def undifferenced_dd_operator(m: int, reference: int) -> np.ndarray:
    """DD operator acting on undifferenced observations ordered (satellite, receiver) with
    receivers (base, rover): the Kronecker product of the between-satellite difference and
    the between-receiver difference ``[−1, 1]``."""
    between_satellites = np.zeros((m - 1, m))
    rows = [s for s in range(m) if s != reference]
    for i, s in enumerate(rows):
        between_satellites[i, s], between_satellites[i, reference] = 1.0, -1.0
    return np.kron(between_satellites, np.array([[-1.0, 1.0]]))


def test_double_difference_covariance_is_the_propagated_undifferenced_one():
    rng = np.random.default_rng(0)
    m, ref = 7, 3
    var = rng.uniform(0.2, 2.0, size=(m, 2)) ** 2  # (satellite, receiver): base, rover
    d = undifferenced_dd_operator(m, ref)
    expected = d @ np.diag(var.ravel()) @ d.T
    got = double_difference_covariance(var[:, 1], var[:, 0], ref)
    np.testing.assert_allclose(got, expected, rtol=1e-14, atol=0)
    # The operator on single differences and the values of the differences themselves.
    values = rng.normal(size=(m, 2))
    sd = single_differences(values[:, 1], values[:, 0])
    np.testing.assert_allclose(double_differences(sd, ref), d @ values.ravel(), rtol=1e-14)
    np.testing.assert_allclose(double_difference_operator(m, ref) @ sd, d @ values.ravel())


def two_epoch_problem(seed: int = 4):
    rng = np.random.default_rng(seed)
    m, ref = 6, 2
    designs = []
    for _ in range(2):
        u = rng.normal(size=(m, 3))
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        designs.append(double_differences(-u.T, ref).T)
    sig_p = rng.uniform(0.3, 0.6, size=(2, m, 2))
    sig_f = rng.uniform(0.002, 0.004, size=(2, m, 2))
    a_true = rng.integers(-50, 50, size=m - 1).astype(float)
    b_true = rng.normal(scale=5.0, size=(2, 3))
    ys = []
    for k in range(2):
        y_code = designs[k] @ b_true[k] + rng.normal(scale=0.5, size=m - 1)
        y_phase = designs[k] @ b_true[k] + LAMBDA * a_true + rng.normal(scale=0.005, size=m - 1)
        ys.append((y_code, y_phase))
    return m, ref, designs, sig_p, sig_f, ys


def test_float_normal_equations_match_an_independent_two_epoch_batch():
    m, ref, designs, sig_p, sig_f, ys = two_epoch_problem()
    n = m - 1
    d = undifferenced_dd_operator(m, ref)
    # Independent derivation: stack both epochs' code and phase DDs, parameters
    # [b₁, b₂, a], covariance propagated from the undifferenced variances.
    blocks, rows, obs = [], [], []
    for k in range(2):
        for sig, is_phase in ((sig_p[k], False), (sig_f[k], True)):
            blocks.append(d @ np.diag(sig.ravel() ** 2) @ d.T)
            row = np.zeros((n, 6 + n))
            row[:, 3 * k : 3 * k + 3] = designs[k]
            if is_phase:
                row[:, 6:] = LAMBDA * np.eye(n)
            rows.append(row)
            obs.append(ys[k][1] if is_phase else ys[k][0])
    x = np.vstack(rows)
    q = np.zeros((4 * n, 4 * n))
    for i, blk in enumerate(blocks):
        q[i * n : (i + 1) * n, i * n : (i + 1) * n] = blk
    w = np.linalg.inv(q)
    normal, rhs = x.T @ w @ x, x.T @ w @ np.concatenate(obs)
    # Reduce the two baselines out (Schur complement) and solve the full system.
    n_bb, n_ba, n_aa = normal[:6, :6], normal[:6, 6:], normal[6:, 6:]
    reduced = n_aa - n_ba.T @ np.linalg.solve(n_bb, n_ba)
    reduced_rhs = rhs[6:] - n_ba.T @ np.linalg.solve(n_bb, rhs[:6])
    full_solution = np.linalg.solve(normal, rhs)

    # The module: epoch by epoch, reduced, accumulated by PRN.
    prns = [11, 12, 14, 15, 17]
    amb = AmbiguityNormals(reference=13)
    amb.add(prns)
    epochs = []
    for k in range(2):
        ne = epoch_normal_equations(
            designs[k],
            ys[k][0],
            ys[k][1],
            double_difference_covariance(sig_p[k, :, 1] ** 2, sig_p[k, :, 0] ** 2, ref),
            double_difference_covariance(sig_f[k, :, 1] ** 2, sig_f[k, :, 0] ** 2, ref),
            LAMBDA,
        )
        epochs.append(ne)
        amb.accumulate(ne["reduced_normal"], ne["reduced_rhs"], prns)
        # Each epoch's full normal block equals the independent one's epoch block.
        np.testing.assert_allclose(ne["N_bb"], n_bb[3 * k : 3 * k + 3, 3 * k : 3 * k + 3],
                                   rtol=1e-12, atol=1e-12 * np.abs(n_bb).max())  # fmt: skip
    scale = np.abs(reduced).max()
    np.testing.assert_allclose(amb.normal, reduced, rtol=1e-12, atol=1e-12 * scale)
    np.testing.assert_allclose(
        amb.rhs, reduced_rhs, rtol=1e-12, atol=1e-12 * np.abs(reduced_rhs).max()
    )
    a_hat, q_hat = amb.float_solution(np.arange(n), conditional=False)
    np.testing.assert_allclose(a_hat, full_solution[6:], rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(q_hat, np.linalg.inv(normal)[6:, 6:], rtol=1e-10, atol=1e-14)
    # Back-substituted baselines equal the batch ones.
    for k, ne in enumerate(epochs):
        b = np.linalg.solve(ne["N_bb"], ne["n_b"] - ne["N_ba"] @ a_hat)
        np.testing.assert_allclose(b, full_solution[3 * k : 3 * k + 3], rtol=1e-10, atol=1e-10)


def test_reference_change_and_marginalisation_preserve_the_solution():
    _, ref, designs, sig_p, sig_f, ys = two_epoch_problem(seed=9)
    prns = [21, 22, 24, 25, 26]
    amb = AmbiguityNormals(reference=23)
    amb.add(prns)
    for k in range(2):
        ne = epoch_normal_equations(
            designs[k], ys[k][0], ys[k][1],
            double_difference_covariance(sig_p[k, :, 1] ** 2, sig_p[k, :, 0] ** 2, ref),
            double_difference_covariance(sig_f[k, :, 1] ** 2, sig_f[k, :, 0] ** 2, ref),
            LAMBDA,
        )  # fmt: skip
        amb.accumulate(ne["reduced_normal"], ne["reduced_rhs"], prns)
    a_hat, q_hat = amb.float_solution(np.arange(5), conditional=False)
    old = dict(zip(amb.prns, a_hat, strict=True))
    amb.change_reference(25)
    new_hat, new_q = amb.float_solution(np.arange(5), conditional=False)
    new = dict(zip(amb.prns, new_hat, strict=True))
    assert amb.reference == 25 and 23 in amb.prns and 25 not in amb.prns
    for p in (21, 22, 24, 26):
        assert new[p] == pytest.approx(old[p] - old[25], abs=1e-9)
    assert new[23] == pytest.approx(-old[25], abs=1e-9)
    t = np.eye(5)
    j = prns.index(25)
    t[:, j] -= 1.0
    t[j, j] = -1.0
    np.testing.assert_allclose(new_q, t @ q_hat @ t.T, rtol=1e-9, atol=1e-12)
    # Marginalising a parameter keeps the others' float solution and covariance.
    before_hat, before_q = new_hat, new_q
    amb.drop([22])
    kept = [i for i, p in enumerate([21, 22, 24, 23, 26]) if p != 22]
    after_hat, after_q = amb.float_solution(np.arange(4), conditional=False)
    np.testing.assert_allclose(after_hat, before_hat[kept], atol=1e-9)
    np.testing.assert_allclose(after_q, before_q[np.ix_(kept, kept)], rtol=1e-9, atol=1e-12)


def test_common_view_and_reference_choice():
    base = np.array([True, True, False, True, True])
    rover = np.array([True, False, True, True, True])
    np.testing.assert_array_equal(common_view(base, rover), [True, False, False, True, True])
    el = np.radians([30.0, 70.0, 50.0])
    assert reference_satellite(el) == 1
    assert reference_satellite(el, current=2) == 2  # kept while allowed
    assert reference_satellite(el, current=1, allowed=[True, False, True]) == 2
    with pytest.raises(ValueError):
        reference_satellite(el, allowed=[False] * 3)
    with pytest.raises(ValueError):
        double_difference_operator(3, 5)
