"""Spin-rate drift: per-night periods and the polynomial through them."""

import numpy as np
import pandas as pd
import pytest

from lightcurve.analysis.drift import (
    PAB_SYSTEMATIC,
    NightPeriod,
    fit_drift,
    night_periods,
    period_drift,
)
from lightcurve.io.observations import Observations, validate_table
from tests.lightcurve._spin_down import spin_down_nights


def _nights(slope_s_per_day, noise_s, rng, count=30):
    return [
        NightPeriod(
            f"night{d}.csv",
            "period",
            60000.0 + d,
            (360.0 + slope_s_per_day * d + rng.normal(0, noise_s)) / 3600,
            noise_s / 3600,
        )
        for d in range(count)
    ]


def test_linear_drift_sign_size_and_error():
    rng = np.random.default_rng(3)
    pulls = []
    for _ in range(20):
        fit = fit_drift(_nights(0.06, 0.05, rng))
        pulls.append((fit.period_derivative_s_per_day - 0.06) / fit.derivative_sigma_s_per_day)
        assert fit.period_derivative_s_per_day == pytest.approx(0.06, rel=0.2)
    assert 0.5 < np.std(pulls) < 1.6


def test_constant_period_reports_no_drift_and_quadratic_term():
    rng = np.random.default_rng(4)
    fit = fit_drift(_nights(0.0, 0.05, rng), quadratic=True)
    assert abs(fit.period_derivative_s_per_day) < 3 * fit.derivative_sigma_s_per_day
    assert fit.second_derivative_s_per_day2 is not None
    assert abs(fit.second_derivative_s_per_day2) < 3 * fit.second_derivative_sigma_s_per_day2


def test_bad_nights_are_errors_naming_the_file():
    rng = np.random.default_rng(5)
    with pytest.raises(ValueError, match="at least 3"):
        fit_drift(_nights(0.0, 0.05, rng, count=2), quadratic=True)
    nights = _nights(0.0, 0.05, rng, count=4)
    nights[2] = NightPeriod("night2.csv", "period", 60002.0, float("nan"), 1e-5)
    with pytest.raises(ValueError, match=r"night2\.csv"):
        fit_drift(nights)


def test_period_drift_over_files_recovers_a_spin_down():
    nights, (fit,) = period_drift(spin_down_nights(6), (0.12, 0.25))
    assert len(nights) == 6 and fit.series == "period"
    assert fit.period_derivative_s_per_day == pytest.approx(6.0, rel=0.05)


def _turning_observer_night(rate_rad_h: float, period_s: float = 600.0) -> Observations:
    """A 2-h night of a double-peaked rotator (pole: inertial z) while the observer turns
    about z at ``rate_rad_h`` and the Sun stays on x: the PAB turns at half that rate."""
    t = np.arange(0.0, 7200.0, 20.0)
    mag = 0.3 * np.cos(4 * np.pi * t / period_s) + 0.1 * np.cos(2 * np.pi * t / period_s)
    mag = mag + np.random.default_rng(8).normal(0, 0.01, len(t))
    angle = rate_rad_h * t / 3600.0 + 0.5
    table = pd.DataFrame(
        {
            "mjd": 61000.0 + t / 86400.0,
            "mag": mag,
            "mag_err": 0.01,
            "sun_x": 1.5e8,
            "sun_y": 0.0,
            "sun_z": 0.0,
            "obs_x": 4e4 * np.cos(angle),
            "obs_y": 4e4 * np.sin(angle),
            "obs_z": 0.0,
        }
    )
    return Observations(validate_table(table, "turning"), {}, "turning.csv")


def test_sidereal_nights_carry_the_pab_systematic():
    """With a pole, each night carries PAB_SYSTEMATIC · P² |Λ̇| / 2π; the drift fit weights
    the nights by the total."""
    rate = 0.3  # rad/h of the observer; the bisector turns at 0.15 rad/h
    (night,) = night_periods([_turning_observer_night(rate)], (0.12, 0.25), pole=(0.0, np.pi / 2))
    expected = PAB_SYSTEMATIC * night.period_h**2 * (rate / 2) / (2 * np.pi)
    assert night.systematic_h == pytest.approx(expected, rel=0.05)
    assert night.total_sigma_h == pytest.approx(np.hypot(night.sigma_h, expected), rel=0.05)
    (plain,) = night_periods([_turning_observer_night(rate)], (0.12, 0.25))
    assert plain.systematic_h == 0.0
    # A night with a large systematic weighs little: the line follows the other two.
    nights = [
        NightPeriod("a", "period", 0.0, 0.1, 1e-6),
        NightPeriod("b", "period", 1.0, 0.2, 1e-6, 1.0),
        NightPeriod("c", "period", 2.0, 0.1, 1e-6),
    ]
    assert abs(fit_drift(nights).period_derivative_s_per_day) < 1e-3


def _seasonal_nights(change_s: float, systematic_s: float, rng, count=30):
    """Constant 360-s nights whose periods follow a smooth seasonal error (a quarter sine
    wave rising by ``change_s`` over the nights) with a small fit scatter."""
    days = np.arange(count, dtype=float)
    error = change_s * np.sin(0.5 * np.pi * days / days[-1])
    return [
        NightPeriod(
            f"night{d}.csv",
            "period",
            60000.0 + d,
            (360.0 + e + rng.normal(0, 0.02)) / 3600,
            0.02 / 3600,
            systematic_s / 3600,
        )
        for d, e in zip(days, error, strict=True)
    ]


def test_common_systematic_covers_a_smooth_seasonal_error():
    """The nights' systematic S is common to them: it adds S k!/T^k to the k-th
    coefficient's σ in quadrature, so a smooth error rising by 1.5 S over the nights (a
    drift to the line, invisible in its χ²) stays within 2σ; counted as independent
    nightly errors it would not (σ ≈ √(σ_n² + S²) / (√N · std t))."""
    rng = np.random.default_rng(21)
    systematic = 0.06
    nights = _seasonal_nights(1.5 * systematic, systematic, rng)
    fit = fit_drift(nights)
    plain = fit_drift([NightPeriod(n.file, n.series, n.mjd, n.period_h, n.sigma_h) for n in nights])
    span = 29.0
    assert plain.reduced_chi2 < 1.5  # the scatter about the line does not reveal the error
    assert fit.period_derivative_s_per_day == pytest.approx(plain.period_derivative_s_per_day)
    independent = np.hypot(0.02, systematic) / (np.sqrt(30) * np.std(np.arange(30)))
    assert fit.derivative_sigma_s_per_day == pytest.approx(np.hypot(independent, systematic / span))
    assert abs(fit.period_derivative_s_per_day) < 2 * fit.derivative_sigma_s_per_day
    assert abs(fit.period_derivative_s_per_day) > 2 * independent
    quadratic = fit_drift(nights, quadratic=True)
    assert quadratic.second_derivative_sigma_s_per_day2 >= 2 * systematic / span**2
