"""Rotation and mean precession periods of torque-free motion: closed form vs integration."""

import math

import numpy as np
import pytest

from filters.attitude.torque_free_periods import euler_periods, euler_periods_numeric


def _random_body(rng):
    while True:
        moments = rng.uniform(1.0, 3.0, 3)
        if 2 * moments.max() < moments.sum():
            return np.diag(moments), rng.standard_normal(3) * 0.05


@pytest.mark.parametrize("seed", range(4))
def test_closed_form_matches_the_integrated_motion(seed):
    inertia, omega = _random_body(np.random.default_rng(seed))
    closed = euler_periods(inertia, omega)
    numeric = euler_periods_numeric(inertia, omega, samples_per_period=1000)
    assert closed.mode == numeric.mode in ("SAM", "LAM")
    assert closed.rotation_period_s == pytest.approx(numeric.rotation_period_s, rel=1e-7)
    assert closed.precession_period_s == pytest.approx(numeric.precession_period_s, rel=1e-7)


def test_both_modes_appear_and_a_rotated_body_frame_changes_nothing():
    rng = np.random.default_rng(5)
    inertia = np.diag([1.0, 2.0, 2.6])
    modes = set()
    for omega in ([0.02, 0.03, 0.06], [0.06, 0.03, 0.02]):
        periods = euler_periods(inertia, omega)
        modes.add(periods.mode)
        axes = np.linalg.qr(rng.standard_normal((3, 3)))[0]
        turned = euler_periods(axes @ inertia @ axes.T, axes @ np.asarray(omega))
        assert turned.rotation_period_s == pytest.approx(periods.rotation_period_s, rel=1e-9)
        assert turned.precession_period_s == pytest.approx(periods.precession_period_s, rel=1e-9)
    assert modes == {"SAM", "LAM"}


@pytest.mark.parametrize(
    ("moments", "omega", "mode"),
    [
        ((2.0, 2.0, 3.0), (0.02, 0.01, 0.05), "SAM"),  # oblate top
        ((1.0, 3.0, 3.0), (0.05, 0.01, 0.02), "LAM"),  # prolate top
    ],
)
def test_symmetric_top_textbook_periods(moments, omega, mode):
    """P_φ = 2π I_t/|L| and P_ψ = 2π/|Ω| with Ω = (I_a − I_t)/I_t · ω_a (Landau & Lifshitz
    §33), I_t the transverse and I_a the axial moment."""
    inertia, w = np.diag(moments), np.asarray(omega)
    axial = 2 if mode == "SAM" else 0
    transverse = moments[1]
    momentum = np.linalg.norm(inertia @ w)
    body_rate = (moments[axial] - transverse) / transverse * w[axial]
    for periods in (euler_periods(inertia, w), euler_periods_numeric(inertia, w)):
        assert periods.mode == mode
        assert periods.precession_period_s == pytest.approx(
            2 * math.pi * transverse / momentum, rel=1e-8
        )
        assert periods.rotation_period_s == pytest.approx(2 * math.pi / abs(body_rate), rel=1e-8)


def test_period_ratio_bounds_behind_the_reading_rule():
    """SAM: P_φ < P_ψ/2 always; LAM: P_φ < P_ψ mostly, but not always, and above P_ψ/2 at
    times (the rule of :func:`lightcurve.analysis.tumbling.euler_reading`)."""
    rng = np.random.default_rng(11)
    ratios = {"SAM": [], "LAM": []}
    for _ in range(3000):
        inertia, omega = _random_body(rng)
        periods = euler_periods(inertia, omega)
        ratios[periods.mode].append(periods.precession_period_s / periods.rotation_period_s)
    sam, lam = np.array(ratios["SAM"]), np.array(ratios["LAM"])
    assert len(sam) > 500 and len(lam) > 500
    assert sam.max() < 0.5
    assert 0.85 < np.mean(lam < 1.0) < 1.0
    assert np.mean(lam > 0.5) > 0.05


def test_principal_axis_rotation_and_bad_states():
    periods = euler_periods(np.diag([1.0, 2.0, 3.0]), [0.0, 0.0, 0.1])
    assert periods.mode == "PA"
    assert periods.rotation_period_s == pytest.approx(2 * math.pi / 0.1)
    with pytest.raises(ValueError, match="does not rotate"):
        euler_periods(np.diag([1.0, 2.0, 3.0]), [0.0, 0.0, 0.0])
    # L² = 2E·B exactly: ω along the separatrix (ω₂ = 0, ω₁ and ω₃ balanced).
    moments = np.array([1.0, 2.0, 3.0])
    w1 = 1.0
    w3 = math.sqrt(
        moments[0] * (moments[1] - moments[0]) / (moments[2] * (moments[2] - moments[1]))
    )
    with pytest.raises(ValueError, match="separatrix"):
        euler_periods(np.diag(moments), [w1 * 0.01, 0.0, w3 * 0.01])
