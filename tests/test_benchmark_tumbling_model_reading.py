"""The torque-free reading study's core on a small integrated tumbler (so it cannot rot)."""

import numpy as np
import pytest

from benchmarks.tumbling_model_reading import FluxFit, model_columns
from benchmarks.tumbling_periods import rates_in_mode
from filters.attitude import attitude_matrix, random_quaternion
from filters.attitude.propagation import torque_free_trajectory
from filters.attitude.torque_free_motion import scaled_motion
from filters.attitude.torque_free_periods import euler_periods, principal_state
from lightcurve.analysis.period import StackedLightCurves
from lightcurve.analysis.tumbling_reading import motions_with_ratio, reading_hypotheses


def _random_rotations(rng, n):
    return attitude_matrix(random_quaternion((n,), rng))


@pytest.mark.parametrize(("degree", "functions"), [(2, 9 + 25), (3, 9 + 25 + 49)])
def test_columns_absorb_constant_rotations_on_either_side(degree, functions):
    rng = np.random.default_rng(0)
    attitude = _random_rotations(rng, 400)
    left, right = _random_rotations(rng, 2)
    columns = model_columns(attitude, degree)
    turned = model_columns(left @ attitude @ right, degree)
    assert np.linalg.matrix_rank(columns) == functions
    assert np.linalg.matrix_rank(np.concatenate([columns, turned], axis=1)) == functions


def test_true_motion_fits_an_integrated_tumbler_to_the_noise():
    """A brightness quadratic in the body-frame Sun and observer directions of an integrated
    short-axis tumbler (within the model's degree): the closed-form motion at the true
    moments and energy fits it to the noise, and the true reading has the least χ² of the
    readings of the true pair."""
    rng = np.random.default_rng(3)
    axes = np.linalg.qr(rng.standard_normal((3, 3)))[0]
    inertia = axes @ np.diag([1.2, 1.9, 2.4]) @ axes.T
    omega = rates_in_mode(rng, inertia, "SAM")
    truth = euler_periods(inertia, omega)
    times = np.sort(rng.uniform(0.0, 5 * truth.rotation_period_s, 400))
    q, _ = torque_free_trajectory(random_quaternion((), rng), omega, times, inertia, 0.5)
    sun, observer = np.array([1.0, 0.0, 0.0]), np.array([0.6, 0.8, 0.0])
    form = rng.standard_normal((3, 3))
    body_sun, body_observer = attitude_matrix(q) @ sun, attitude_matrix(q) @ observer
    flux = 2.0 + 0.3 * np.einsum("ni,ij,nj->n", body_sun, form + form.T, body_observer)
    sigma = np.full(len(times), 0.005)
    magnitudes = -2.5 * np.log10(flux) + rng.normal(0.0, sigma)
    data = StackedLightCurves(
        mjd=times / 86400.0,
        times=times,
        magnitudes=magnitudes,
        sigma=sigma,
        curve=np.zeros(len(times), int),
        sun=np.tile(sun, (len(times), 1)),
        observer=np.tile(observer, (len(times), 1)),
    )
    fit = FluxFit(data, np.arange(len(times)))
    moments, rates = principal_state(inertia, omega)
    d = np.sum((moments * rates) ** 2) / np.sum(moments * rates**2) / moments[2]
    motion = scaled_motion(moments / moments[2], d, "SAM")
    chi2 = fit.best_origin(motion, 1.0 / truth.rotation_period_s, 64)
    assert chi2 < 1.5 * len(times)
    pair = np.array([1.0 / truth.precession_period_s, 1.0 / truth.rotation_period_s])
    least = {
        reading[:3]: min(
            (
                fit.best_origin(m, reading[1], 10)
                for m in motions_with_ratio(reading[1] / reading[0], reading[2], grid=4)
            ),
            default=np.inf,
        )
        for reading in reading_hypotheses(pair)
    }
    best = min(least, key=least.get)
    assert np.allclose(best[:2], pair, rtol=1e-9) and best[2] == "SAM"
