"""Clohessy–Wiltshire dynamics against matrix exponentials, quadrature and closed orbits."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import quad_vec, solve_ivp
from scipy.linalg import expm

from filters.navigation.hill import (
    cw_input_matrix,
    cw_matrix,
    cw_process_noise,
    cw_transition,
    mean_motion,
)

N_LEO = mean_motion(6878.137e3)  # 500 km circular orbit

motions = st.floats(min_value=1e-5, max_value=1e-2)
steps = st.floats(min_value=-5000.0, max_value=5000.0)


def test_mean_motion_of_leo_orbit():
    period = 2 * math.pi / N_LEO
    assert period == pytest.approx(5677.0, abs=1.0)  # 500 km altitude: 94.6 min


@settings(max_examples=40, deadline=None)
@given(motions, steps)
def test_transition_is_the_matrix_exponential(n, dt):
    np.testing.assert_allclose(cw_transition(n, dt), expm(cw_matrix(n) * dt), atol=1e-9, rtol=1e-9)


@settings(max_examples=40, deadline=None)
@given(motions, steps, steps)
def test_transition_composes(n, t1, t2):
    np.testing.assert_allclose(
        cw_transition(n, t1) @ cw_transition(n, t2), cw_transition(n, t1 + t2), atol=1e-7
    )


def test_transition_broadcasts_over_steps():
    dts = np.array([[0.16, 1.0], [10.0, -3.0]])
    phi = cw_transition(N_LEO, dts)
    assert phi.shape == (2, 2, 6, 6)
    np.testing.assert_allclose(phi[1, 0], cw_transition(N_LEO, 10.0))


@pytest.mark.parametrize("dt", [0.16, 1.0, 600.0, 5000.0])
def test_input_matrix_against_augmented_exponential(dt):
    # exp([[A, G], [0, 0]] Δt) has Γ = ∫ Φ G in its upper-right block (Van Loan).
    block = np.zeros((9, 9))
    block[:6, :6] = cw_matrix(N_LEO)
    block[3:6, 6:] = np.eye(3)
    expected = expm(block * dt)[:6, 6:]
    np.testing.assert_allclose(cw_input_matrix(N_LEO, dt), expected, atol=1e-12, rtol=1e-9)


def test_input_matrix_against_numerical_integration():
    rng = np.random.default_rng(3)
    s0 = rng.normal(size=6) * [10, 10, 10, 0.01, 0.01, 0.01]
    accel = rng.normal(size=3) * 1e-4
    dt = 900.0
    a = cw_matrix(N_LEO)
    sol = solve_ivp(lambda t, s: a @ s + np.r_[0, 0, 0, accel], (0, dt), s0, rtol=1e-12, atol=1e-12)
    predicted = cw_transition(N_LEO, dt) @ s0 + cw_input_matrix(N_LEO, dt) @ accel
    np.testing.assert_allclose(predicted, sol.y[:, -1], rtol=1e-8, atol=1e-9)


def test_closed_relative_orbit_is_periodic():
    # ẏ0 = −2 n x0 removes the along-track drift: a 2:1 ellipse repeating every orbit.
    amp = 2.5
    s0 = np.array([0.0, 10.0, 0.0, -N_LEO * amp, 0.0, N_LEO * 1.0])
    period = 2 * math.pi / N_LEO
    half = cw_transition(N_LEO, period / 2) @ s0
    assert half[1] == pytest.approx(10.0 + 4 * amp, abs=1e-9)  # depth 10 m → 20 m
    np.testing.assert_allclose(cw_transition(N_LEO, period) @ s0, s0, atol=1e-9)


def test_process_noise_against_quadrature():
    psd, dt = 2.5e-9, 30.0
    g = np.zeros((6, 3))
    g[3:] = np.eye(3)
    expected, _ = quad_vec(
        lambda s: cw_transition(N_LEO, s) @ g @ g.T @ cw_transition(N_LEO, s).T * psd, 0, dt
    )
    q = cw_process_noise(N_LEO, dt, psd)
    np.testing.assert_allclose(q, expected, rtol=1e-8, atol=1e-20)
    # Short-step limit of a double integrator: Var(position) = q Δt³ / 3.
    assert q[0, 0] == pytest.approx(psd * dt**3 / 3, rel=1e-3)


@pytest.mark.parametrize("bad", [0.0, -1e-3, float("nan")])
def test_bad_mean_motion_is_rejected(bad):
    with pytest.raises(ValueError, match="mean motion"):
        cw_transition(bad, 1.0)


def test_bad_inputs_are_rejected():
    with pytest.raises(ValueError, match="orbit radius"):
        mean_motion(-1.0)
    with pytest.raises(ValueError, match="noise density"):
        cw_process_noise(N_LEO, 1.0, -1.0)
