"""Monocular EKF (Deng et al. 2024): Jacobians against autograd, filter algebra, scenarios."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from torch.func import jacfwd

from filters.attitude import (
    attitude_angle,
    error_state_matrix,
    euler_rate,
    inertia_from_normalized,
    normalized_from_inertia,
    propagate,
    quaternion_multiply,
    random_quaternion,
    tanh_from_inertia,
)
from filters.gaussian import joseph_update, kalman_gain
from filters.navigation.monocular import (
    FORMS,
    MonocularEKF,
    perturb_attitudes,
    reference_frame_truth,
    state_derivative,
)
from lightcurve.scenarios.monocular import load_monocular_scenario
from lightcurve.studies.monocular import convergence, run_study

SCENARIOS = Path(__file__).resolve().parents[3] / "data" / "scenarios"
J_A = np.array([[0.85, 0.13, 0.17], [0.13, 1.37, -0.11], [0.17, -0.11, 1.0]])

rates = st.lists(st.floats(-0.3, 0.3), min_size=3, max_size=3)


def _exact_error_rate(delta: torch.Tensor, omega_hat: torch.Tensor, p: torch.Tensor, form: str):
    """Nonlinear ``d/dt [δq_v, δω, δp]`` for ``δq = q ⊗ q̂⁻¹`` (Deng et al. 2024, eqs. 25–31)."""
    spec = FORMS[form]
    dq = torch.cat([delta[:3], torch.sqrt(1 - delta[:3] @ delta[:3])[None]])
    omega = omega_hat + delta[3:6]
    pure = lambda w: torch.cat([w, torch.zeros(1, dtype=w.dtype)])  # noqa: E731
    # q̇ = ½ [ω, 0] ⊗ q  ⇒  δq̇ = ½ [ω, 0] ⊗ δq − ½ δq ⊗ [ω̂, 0].
    dq_dot = 0.5 * quaternion_multiply(pure(omega), dq) - 0.5 * quaternion_multiply(
        dq, pure(omega_hat)
    )
    w_dot = euler_rate(omega, spec.tensor(p + delta[6:]))
    w_dot_hat = euler_rate(omega_hat, spec.tensor(p))
    return torch.cat([dq_dot[:3], w_dot - w_dot_hat, torch.zeros_like(p)])


@pytest.mark.parametrize("form", ["L", "k"])
@settings(max_examples=5, deadline=None)
@given(omega=rates, seed=st.integers(0, 2**31))
def test_error_state_matrix_matches_autograd(form, omega, seed):
    """``C`` (with ``M``, ``N``) equals the autograd Jacobian to 1e-9."""
    rng = np.random.default_rng(seed)
    if form == "L":
        # A random physical inertia, normalised (Lzz = 1).
        q = random_quaternion(rng=rng)
        from filters.attitude import attitude_matrix

        a = np.asarray(attitude_matrix(q))
        j = a.T @ np.diag(rng.uniform([1.0, 1.0, 1.0], [2.0, 2.0, 2.0])) @ a
        p = normalized_from_inertia(j)
    else:
        p = rng.normal(size=2)
    n = 6 + FORMS[form].size
    w_t, p_t = torch.tensor(omega, dtype=torch.float64), torch.tensor(p, dtype=torch.float64)
    auto = jacfwd(lambda d: _exact_error_rate(d, w_t, p_t, form))(
        torch.zeros(n, dtype=torch.float64)
    )
    c = error_state_matrix(np.asarray(omega), p, form)
    scale = max(1.0, float(np.abs(c).max()))
    assert np.max(np.abs(c - auto.numpy())) < 1e-9 * scale


def test_state_derivative_is_the_core_dynamics_in_numpy_and_torch():
    x = np.r_[random_quaternion(rng=1), 0.1, -0.2, 0.05, normalized_from_inertia(J_A)]
    f = state_derivative("L")
    from filters.attitude import state_derivative as core_derivative

    expected = core_derivative(x[:7], inertia_from_normalized(x[7:]))
    assert np.allclose(f(x)[:7], expected, atol=1e-15)
    assert np.all(f(x)[7:] == 0)
    assert np.allclose(f(torch.tensor(x)).numpy(), f(x), atol=1e-15)


def test_update_is_the_shared_joseph_update_and_batches_like_a_loop():
    rng = np.random.default_rng(5)
    a = rng.normal(size=(3, 11, 11))
    p = a @ np.swapaxes(a, -1, -2) * 1e-3 + 1e-4 * np.eye(11)
    x = np.concatenate(
        [random_quaternion(3, rng), np.tile([0.1, 0.0, 0.05, 0.8, 1.3, 0, 0, 0], (3, 1))], 1
    )
    z = perturb_attitudes(x[:, :4], 0.01, rng)
    r = 1e-4 * np.eye(3)
    batched = MonocularEKF(x, p, 1e-3 * np.eye(11), r)
    batched.update(z)
    h = np.hstack([np.eye(3), np.zeros((3, 8))])
    for i in range(3):
        single = MonocularEKF(x[i], p[i], 1e-3 * np.eye(11), r)
        nu = single.innovation(z[i])
        single.update(z[i])
        gain, _ = kalman_gain(p[i], h, r)
        assert np.allclose(single.P, joseph_update(p[i], gain, h, r), atol=1e-15)
        assert np.allclose(batched.P[i], single.P, atol=1e-15)
        assert np.allclose(batched.x[i], single.x, atol=1e-14)
        # The posterior attitude moved toward the measurement by the gain's share.
        after = np.asarray(attitude_angle(single.x[:4], z[i]))
        assert after < np.linalg.norm(2 * nu)


def test_missing_measurements_only_predict():
    x = np.r_[0, 0, 0, 1.0, 0.1, 0.0, 0.0, 0.9, 1.2, 0, 0, 0]
    ekf = MonocularEKF(np.stack([x, x]), 1e-2 * np.eye(11), 1e-6 * np.eye(11), 1e-4 * np.eye(3))
    z = np.array([[0, 0, 0, 1.0], [np.nan] * 4])
    p_before = ekf.P.copy()
    ekf.update(z)
    assert np.allclose(ekf.P[1], p_before[1]) and not np.allclose(ekf.P[0], p_before[0])


def test_reference_frame_truth_follows_the_filters_dynamics():
    """With q0 ≠ I the truth is re-expressed in the frame aligned with the first camera frame."""
    q0 = random_quaternion(rng=11)
    t = np.linspace(0, 30, 31)
    states = propagate(np.r_[q0, np.radians([5.0, 2.3, 3.5])], t, J_A)
    q, w, j = reference_frame_truth(J_A, q0, states)
    assert attitude_angle(q[0], [0, 0, 0, 1.0]) < 1e-12
    # ω' and J' obey Euler's equations and q' the kinematics: compare with a propagation.
    again = propagate(np.r_[q[0], w[0]], t, j)
    assert np.max(np.asarray(attitude_angle(again[:, :4], q))) < 1e-8
    assert np.max(np.abs(again[:, 4:] - w)) < 1e-10


def _scenario(name: str, **changes):
    sc = load_monocular_scenario(SCENARIOS / name)
    if changes:
        sc = dataclasses.replace(sc, truth=dataclasses.replace(sc.truth, **changes))
    return sc


def test_scenario_a_converges_with_the_papers_setup():
    """Nutating body, reduced: 4 seeded runs of 1600 s (the benchmark runs 50 of 2000 s)."""
    sc = _scenario("nutation.toml", duration=1600.0)
    assert np.allclose(np.diag(sc.q), 1e-3) and np.allclose(np.diag(sc.r), 1e-3)
    study = run_study(sc, runs=4, seed=7)
    conv = convergence(study)
    err = conv["errors"]
    assert np.all(conv["success"]), (err["attitude_deg"][-1], err["inertia"][-1])
    assert np.all(err["attitude_deg"][-1] < 0.5)
    assert np.all(err["rate_fraction"][-1] < 0.02)
    assert np.all(np.abs(err["inertia"][-1]) < 0.02)
    # Half-way the inertia has not converged yet: the run length matters.
    assert np.max(np.abs(err["inertia"][400])) > 0.05


def test_scenario_b_inertia_does_not_converge():
    """Pure spin (filter side): Lxx, Lyy, Lxz keep their prior and their σ grows."""
    sc = _scenario("pure_spin.toml", duration=400.0)
    study = run_study(sc, runs=1, seed=3)
    l_true = normalized_from_inertia(sc.truth.inertia)
    sig = study.history.sigmas[:, 0, 6:]
    l_hat = study.history.states[-1, 0, 7:]
    assert abs(l_hat[1] - l_true[1]) > 0.5  # Lyy stays near its initial 0.7 (truth 1.37)
    for i in (0, 1, 3):  # unobservable: σ grows like √(Q t)
        assert sig[-1, i] > 1.5 * sig[100, i]
        assert sig[-1, i] == pytest.approx(math.sqrt(0.1 + 1e-3 * 400), rel=0.05)
    # The observable part (attitude and rates) still converges.
    assert convergence(study)["errors"]["attitude_deg"][-1, 0] < 0.5


def test_tanh_form_converges_for_a_principal_axis_body():
    """The k-form variant on a nutating body whose principal axes are the first camera frame."""
    sc = _scenario("nutation.toml", duration=1500.0, inertia=np.diag([0.85, 1.37, 1.0]))
    k_true = tanh_from_inertia(np.diag([0.85, 1.37, 1.0]))
    n = 8
    sc = dataclasses.replace(
        sc,
        form=FORMS["k"],
        x0=np.r_[sc.x0[:7], 0.0, 0.0],
        p0=np.diag([0.01] * 6 + [1.0, 1.0]),
        q=1e-3 * np.eye(n),
        r=1e-3 * np.eye(3),
    )
    assert sc.p0.shape == (n, n)
    study = run_study(sc, runs=2, seed=1)
    k_hat = study.history.states[-1, :, 7:]
    assert np.max(np.abs(k_hat - k_true)) < 0.02
    assert np.max(np.abs(study.history.states[300, :, 7:] - k_true)) > 0.05
    assert np.all(convergence(study)["errors"]["attitude_deg"][-1] < 0.5)


def test_update_accepts_a_per_update_noise():
    x = np.r_[0.0, 0.0, 0.0, 1.0, 0.1, 0.0, 0.05, normalized_from_inertia(J_A)]
    p = 1e-3 * np.eye(11)
    z = np.array([0.01, 0.0, 0.0, np.sqrt(1 - 1e-4)])
    default = MonocularEKF(x, p, 1e-3 * np.eye(11), 1e-4 * np.eye(3))
    explicit = MonocularEKF(x, p, 1e-3 * np.eye(11), np.eye(3))
    default.update(z)
    explicit.update(z, r=1e-4 * np.eye(3))
    np.testing.assert_allclose(explicit.P, default.P, atol=1e-15)
    np.testing.assert_allclose(explicit.x, default.x, atol=1e-15)
