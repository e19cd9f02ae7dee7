"""Spin states in the DAMIT convention ↔ attitude quaternions (lightcurve.analysis.spin)."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from filters.attitude import attitude_angle, attitude_matrix, quaternion_from_matrix
from lightcurve.analysis.spin import SpinState, pole_distance, pole_vector, spin_from_attitude
from lightcurve.photometry.simulate import truth_states

angles = st.floats(0.0, 2 * math.pi)
latitudes = st.floats(-1.5, 1.5)
periods = st.floats(0.5, 50.0)


def _damit_matrix(lam, beta, phi):
    """``R_z(φ) R_y(90° − β) R_z(λ)`` written out from Ďurech et al. 2010, eq. 1."""

    def rz(a):
        return np.array([[np.cos(a), np.sin(a), 0], [-np.sin(a), np.cos(a), 0], [0, 0, 1]])

    def ry(a):
        return np.array([[np.cos(a), 0, -np.sin(a)], [0, 1, 0], [np.sin(a), 0, np.cos(a)]])

    return rz(phi) @ ry(np.pi / 2 - beta) @ rz(lam)


@settings(max_examples=50, deadline=None)
@given(angles, latitudes, periods, angles, st.floats(0.0, 400.0))
def test_attitude_is_the_damit_rotation(lam, beta, period_h, phi0, days):
    spin = SpinState(lam, beta, period_h * 3600.0, phi0, 50000.0)
    q = spin.attitude([50000.0 + days])[0]
    phi = phi0 + 2 * math.pi * days * 86400.0 / spin.period_s
    np.testing.assert_allclose(attitude_matrix(q), _damit_matrix(lam, beta, phi), atol=1e-8)
    # The same matrix from scipy's intrinsic ZYZ Euler angles (active → transposed).
    scipy_matrix = Rotation.from_euler("ZYZ", [lam, math.pi / 2 - beta, phi]).as_matrix().T
    np.testing.assert_allclose(attitude_matrix(q), scipy_matrix, atol=1e-8)
    # The body z axis is the pole.
    np.testing.assert_allclose(attitude_matrix(q)[2], spin.pole, atol=1e-12)


@settings(max_examples=50, deadline=None)
@given(angles, latitudes, periods, angles)
def test_spin_from_attitude_round_trip(lam, beta, period_h, phi0):
    spin = SpinState(lam, beta, period_h * 3600.0, phi0, 51000.0)
    q0, omega0 = spin.initial_state(51000.0)
    back = spin_from_attitude(q0, omega0, 51000.0)
    assert back.period_s == pytest.approx(spin.period_s, rel=1e-12)
    assert math.degrees(pole_distance(back.lambda_rad, back.beta_rad, lam, beta)) < 1e-6
    later = [51000.0, 51000.37]
    assert np.all(attitude_angle(back.attitude(later), spin.attitude(later)) < 1e-8)


def test_negative_spin_rate_flips_the_pole():
    spin = SpinState.from_degrees(40.0, 30.0, 6.0, 10.0, 0.0)
    q0, omega0 = spin.initial_state(0.0)
    # The same motion expressed in a body frame turned 180° about x: ω along −z.
    flipped = Rotation.from_euler("x", 180, degrees=True).as_matrix().T @ attitude_matrix(q0)

    q_flipped = quaternion_from_matrix(flipped[None])[0]
    back = spin_from_attitude(q_flipped, -omega0, 0.0)
    assert math.degrees(pole_distance(back.lambda_rad, back.beta_rad, *np.radians([40, 30]))) < 1e-6
    with pytest.raises(ValueError, match="not along the body z axis"):
        spin_from_attitude(q0, [1e-3, 0.0, 1e-3], 0.0)


def test_torque_free_axisymmetric_motion_is_the_uniform_spin():
    """simulate's DOP853 truth from (q0, ω0), inertia diag(1, 1, 2), follows the spin state."""
    spin = SpinState.from_degrees(128.5, -89.66, 12.132, 0.0, 55000.0)
    times = np.linspace(0.0, 8 * 3600.0, 9)
    q0, omega0 = spin.initial_state(55000.0)
    states = truth_states(times, q0, omega0, np.diag([1.0, 1.0, 2.0]))
    expected = spin.attitude(55000.0 + times / 86400.0)
    assert np.max(attitude_angle(states[:, :4], expected)) < 1e-8


def test_pole_distance_on_the_sphere():
    # Near the ecliptic pole a 180° longitude difference is a small angle.
    d = pole_distance(math.radians(10), math.radians(-89), math.radians(190), math.radians(-89))
    assert math.degrees(d) == pytest.approx(2.0, abs=1e-9)
    assert math.degrees(pole_distance(0.0, 0.0, math.pi, 0.0)) == pytest.approx(180.0)
    np.testing.assert_allclose(np.linalg.norm(pole_vector([0.1, 2.0], [0.3, -1.2]), axis=1), 1.0)


def test_spin_state_validation():
    with pytest.raises(ValueError, match="period"):
        SpinState(0.0, 0.0, -1.0)
    with pytest.raises(ValueError, match="latitude"):
        SpinState.from_degrees(0.0, 95.0, 5.0)
