"""Spin-rate drift: per-night periods and the polynomial through them."""

import numpy as np
import pytest

from lightcurve.analysis.drift import NightPeriod, fit_drift, period_drift
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
