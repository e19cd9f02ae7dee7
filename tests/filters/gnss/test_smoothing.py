"""Carrier smoothing of code (Hatch filter): the closed-form 1/n variance, the exponential
regime, restarts on slips and on loss of lock."""

from __future__ import annotations

import numpy as np
import pytest

from filters.gnss.smoothing import CarrierSmoothing

CHANNELS = 4000  # independent channels: sample variances within √(2/4000) ≈ 2.2 % (1σ)


def run_channels(window, epochs, code_sigma, phase_sigma, seed):
    """Moving ranges, constant carrier biases; returns errors and predicted variances."""
    rng = np.random.default_rng(seed)
    prn = np.arange(CHANNELS)
    start = rng.uniform(2.0e7, 2.6e7, CHANNELS)
    rate = rng.uniform(-800.0, 800.0, CHANNELS)  # m/s: the carrier carries the range along
    bias = rng.uniform(-1e3, 1e3, CHANNELS)
    smoothing = CarrierSmoothing(window)
    errors, variances = [], []
    for k in range(epochs):
        rho = start + rate * k
        code = rho + code_sigma * rng.standard_normal(CHANNELS)
        phase = rho + bias + phase_sigma * rng.standard_normal(CHANNELS)
        smoothed, variance, count = smoothing.update(
            float(k),
            prn,
            code,
            phase,
            np.ones(CHANNELS, bool),
            code_variance=code_sigma**2,
            phase_variance=phase_sigma**2,
        )
        errors.append(smoothed - rho)
        variances.append(variance)
    return np.array(errors), np.array(variances), count


@pytest.mark.parametrize("n", [1, 4, 25, 60])
def test_noiseless_carrier_smooths_white_code_noise_as_one_over_n(n):
    sigma = 0.7
    errors, variances, count = run_channels(100.0, n, sigma, 0.0, seed=11 + n)
    assert np.all(count == n)
    np.testing.assert_allclose(variances[-1], sigma**2 / n, rtol=1e-12)
    ratio = errors[-1].var() / (sigma**2 / n)
    assert abs(ratio - 1.0) < 0.1  # 4.5σ of the sample variance
    assert abs(errors[-1].mean()) < 4.0 * sigma / np.sqrt(n * CHANNELS)  # unbiased


def test_carrier_noise_adds_to_the_smoothed_variance_as_modelled():
    code_sigma, phase_sigma, n = 0.5, 0.1, 30
    errors, variances, _ = run_channels(100.0, n, code_sigma, phase_sigma, seed=3)
    expected = code_sigma**2 / n + phase_sigma**2 * (1.0 - 1.0 / n)
    np.testing.assert_allclose(variances[-1], expected, rtol=1e-12)
    assert abs(errors[-1].var() / expected - 1.0) < 0.1


def test_exponential_regime_levels_off_after_the_window():
    sigma, length = 0.5, 10  # 10 s window at 1 Hz
    errors, variances, _ = run_channels(float(length), 120, sigma, 0.0, seed=5)
    steady = sigma**2 / (2 * length - 1)  # α σ² / (2 − α), α = 1/N
    np.testing.assert_allclose(variances[-1], steady, rtol=1e-6)
    assert variances[length - 1, 0] == pytest.approx(sigma**2 / length)
    assert abs(errors[-1].var() / steady - 1.0) < 0.1


def test_zero_window_returns_the_raw_code():
    smoothing = CarrierSmoothing(0.0)
    rng = np.random.default_rng(1)
    for k in range(5):
        code, phase = rng.normal(size=3), rng.normal(size=3)
        out, variance, count = smoothing.update(
            k, [3, 5, 9], code, phase, [True] * 3, code_variance=0.5, phase_variance=1e-5
        )
        np.testing.assert_allclose(out, code, rtol=0, atol=1e-12)
        np.testing.assert_array_equal(count, [k + 1] * 3)  # continuous, but not averaged
        np.testing.assert_array_equal(variance, [0.5] * 3)


def test_a_slip_or_a_gap_restarts_only_that_channel():
    rng = np.random.default_rng(8)
    smoothing = CarrierSmoothing(100.0)
    prn = np.array([2, 7, 11])
    rho, bias = np.array([2.1e7, 2.2e7, 2.3e7]), np.array([5.0, -3.0, 40.0])
    jump = 7 * 0.1903  # a 7-cycle slip on PRN 7 at epoch 20 (m)
    for k in range(30):
        code = rho + 0.5 * rng.standard_normal(3)
        phase = rho + bias + np.where((prn == 7) & (k >= 20), jump, 0.0)
        continuous = np.array([True, k != 20, True])  # the slip detector flags PRN 7
        out, variance, count = smoothing.update(
            k, prn, code, phase, continuous, code_variance=0.25, phase_variance=0.0
        )
        if k == 20:
            assert count.tolist() == [21, 1, 21]
            assert out[1] == pytest.approx(code[1], abs=1e-6) and variance[1] == 0.25  # raw code
    assert count.tolist() == [30, 10, 30]
    assert abs(out[1] - rho[1]) < 4 * 0.5 / np.sqrt(10)  # the slip does not leak in
    # A satellite missing for an epoch restarts when it returns; the others carry on.
    smoothing.update(
        30,
        prn[[0, 2]],
        rho[[0, 2]],
        (rho + bias)[[0, 2]],
        [True, True],
        code_variance=0.25,
        phase_variance=0,
    )
    _, _, count = smoothing.update(
        31, prn, rho, rho + bias, [True] * 3, code_variance=0.25, phase_variance=0.0
    )
    assert count.tolist() == [32, 1, 32]


def test_an_unflagged_slip_biases_the_smoothed_code():
    # Why the restart matters: without it the slip enters with weight (1 − 1/n).
    smoothing = CarrierSmoothing(100.0)
    jump = 3 * 0.1903
    for k in range(11):
        phase = 100.0 + (jump if k == 10 else 0.0)
        out, _, _ = smoothing.update(
            k, [4], [0.0], [phase], [True], code_variance=0.25, phase_variance=0.0
        )
    assert out[0] == pytest.approx(jump * (1 - 1 / 11))


def test_bad_input():
    with pytest.raises(ValueError, match="window"):
        CarrierSmoothing(-1.0)
    smoothing = CarrierSmoothing(10.0)
    smoothing.update(5.0, [1], [0.0], [0.0], [True], code_variance=1.0, phase_variance=0.0)
    with pytest.raises(ValueError, match="epochs must increase"):
        smoothing.update(5.0, [1], [0.0], [0.0], [True], code_variance=1.0, phase_variance=0.0)
