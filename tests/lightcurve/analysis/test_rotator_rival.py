"""The one-period rival's side of the tumbling verdict: the search penalty and the rule for
a pair that a changing one-period light curve explains."""

import math

import numpy as np
import pytest

from benchmarks.tumbling_periods import run_case
from lightcurve.analysis.rotator_rival import (
    GEOMETRY_CHANGE_DEG,
    geometry_change_deg,
    geometry_explains_pair,
    search_penalty,
)


def _turning_geometry(phase_change_deg: float, n: int = 50) -> tuple[np.ndarray, np.ndarray]:
    """Sun on x; the observer turns in the x-y plane from 20° to 20° + the change."""
    angle = np.radians(20.0 + np.linspace(0.0, phase_change_deg, n))
    sun = np.tile([1.5e8, 0.0, 0.0], (n, 1))
    observer = 4e4 * np.column_stack([np.cos(angle), np.sin(angle), np.zeros(n)])
    return sun, observer


def _carried_geometry(turn_deg: float, n: int = 50) -> tuple[np.ndarray, np.ndarray]:
    """Sun and observer 40° apart, both turning about z by ``turn_deg``: a constant phase
    angle, the bisector turning by ``turn_deg``."""
    angle = np.radians(np.linspace(0.0, turn_deg, n))
    sun = 1.5e8 * np.column_stack([np.cos(angle), np.sin(angle), np.zeros(n)])
    observer = 4e4 * np.column_stack([np.cos(angle + 0.7), np.sin(angle + 0.7), np.zeros(n)])
    return sun, observer


def test_geometry_change_is_the_phase_angle_range_or_the_bisector_turn():
    assert geometry_change_deg(*_turning_geometry(60.0)) == pytest.approx(60.0)
    assert geometry_change_deg(*_carried_geometry(45.0)) == pytest.approx(45.0)
    assert geometry_change_deg(*_carried_geometry(0.0)) == pytest.approx(0.0, abs=1e-6)


def test_a_near_harmonic_pair_is_explained_only_where_the_geometry_changes():
    span = 600.0
    f2 = 1 / 180.0
    near = (3 * f2 + 0.6 / span, f2)  # 0.6 cycles per span from 3:1
    far = (3.5 * f2, f2)  # 1.67 cycles from 3:1 and 4:1, farther from the other ratios
    fast, slow = _turning_geometry(100.0), _turning_geometry(GEOMETRY_CHANGE_DEG / 3)
    assert geometry_explains_pair(near, span, *fast, resolution_cycles=1.5)
    assert not geometry_explains_pair(near, span, *slow, resolution_cycles=1.5)
    assert not geometry_explains_pair(far, span, *fast, resolution_cycles=1.5)
    # 2:3 and 4:1 count as well, the order of the two frequencies does not matter, and a
    # turning bisector at a constant phase angle moves the geometry too.
    assert geometry_explains_pair((f2, 1.5 * f2 + 0.2 / span), span, *fast, resolution_cycles=1.5)
    assert geometry_explains_pair((f2, 4 * f2 - 0.5 / span), span, *fast, resolution_cycles=1.5)
    turning = _carried_geometry(2 * GEOMETRY_CHANGE_DEG)
    assert geometry_explains_pair(near, span, *turning, resolution_cycles=1.5)


def test_search_penalty_holds_the_false_alarm_rate_of_white_noise():
    """White noise, M independent Fourier frequencies: the largest Δχ² of one sinusoid
    exceeds ``2 ln(1/p) + 2 ln M`` in about a fraction p of the series (false-alarm
    probability ``1 − (1 − p/M)^M ≈ p``), and the unpenalised ``2 ln(1/p)`` in most."""
    rng = np.random.default_rng(11)
    n, trials, series = 512, 200, 400
    noise = rng.standard_normal((series, n))
    power = np.abs(np.fft.rfft(noise, axis=1)[:, 1 : trials + 1]) ** 2
    delta_chi2 = 2.0 * power / n  # χ²₂ per frequency for unit σ
    largest = delta_chi2.max(axis=1)
    base = 2 * math.log(1 / 0.05)
    assert search_penalty(trials) == pytest.approx(2 * math.log(trials))
    assert search_penalty(0.5) == 0.0
    assert np.mean(largest > base + search_penalty(trials)) == pytest.approx(0.05, abs=0.03)
    assert np.mean(largest > base) > 0.9


def test_low_orbit_pass_of_a_principal_axis_rotator_is_not_tumbling():
    """A principal-axis rotator on an 11-min low-orbit pass (the geometry turns by 66°):
    its two-period fit lands 0.7 cycles from 3:4 and beats the one-period rival
    (ΔBIC ≈ 110), but the changing geometry explains the pair."""
    record = run_case(1000, 20, mode="PA-max")
    assert record["scenario"] == "leo" and record["delta_bic"] > 20
    assert not record["tumbling"]
