"""Closed-form torque-free attitude about the angular momentum, against the integrator."""

import numpy as np
import pytest

from filters.attitude.propagation import propagate
from filters.attitude.quaternion import attitude_angle, quaternion_from_matrix
from filters.attitude.torque_free_motion import (
    attitude_about_momentum,
    body_rates,
    period_ratio,
    scaled_motion,
)
from filters.attitude.torque_free_periods import euler_periods


@pytest.mark.parametrize(
    ("mode", "moments", "d"),
    [("SAM", (0.5, 0.8, 1.0), 0.9), ("LAM", (0.4, 0.8, 1.0), 0.6), ("LAM", (0.3, 0.9, 1.0), 0.5)],
)
def test_closed_form_attitude_follows_the_integrated_motion(mode, moments, d):
    motion = scaled_motion(np.array(moments), d, mode)
    # The motion's axes (x, y, z) carry the moments (opposite, intermediate, reference).
    axis_moments = np.array(moments)[[2, 1, 0]] if mode == "LAM" else np.array(moments)
    tau = np.linspace(0.0, 3.0, 301)
    closed = attitude_about_momentum(motion, tau)
    state = np.concatenate([quaternion_from_matrix(closed[0]), body_rates(motion, tau[:1])[0]])
    integrated = propagate(state, tau * motion.rotation_period, np.diag(axis_moments))
    error = attitude_angle(integrated[:, :4], quaternion_from_matrix(closed))
    assert np.max(error) < 5e-4  # rad; the precession table is sampled 512 times a period
    # The angular momentum lies along the frame's z axis, with |L| = 1.
    momentum = axis_moments * body_rates(motion, tau)
    assert np.allclose(np.einsum("nji,nj->ni", closed, momentum), [0.0, 0.0, 1.0], atol=1e-9)


@pytest.mark.parametrize("mode", ["SAM", "LAM"])
def test_period_ratio_matches_the_elliptic_periods(mode):
    moments, d = np.array([0.45, 0.7, 1.0]), 0.85 if mode == "SAM" else 0.55
    motion = scaled_motion(moments, d, mode)
    axis_moments = moments[[2, 1, 0]] if mode == "LAM" else moments
    periods = euler_periods(np.diag(axis_moments), body_rates(motion, np.array([0.2]))[0])
    assert periods.mode == mode
    assert periods.rotation_period_s == pytest.approx(motion.rotation_period, rel=1e-9)
    expected = periods.precession_period_s / periods.rotation_period_s
    assert float(period_ratio(moments, np.array(d), mode)) == pytest.approx(expected, rel=1e-9)
    assert motion.ratio == pytest.approx(expected, rel=1e-5)


def test_unknown_mode_is_refused():
    with pytest.raises(ValueError, match="unknown mode"):
        period_ratio(np.array([0.5, 0.8, 1.0]), np.array(0.9), "PA")
