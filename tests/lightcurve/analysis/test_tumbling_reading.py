"""Reading a tumbler's pair by a convex facet model under torque-free motion."""

import numpy as np
import pytest

from benchmarks.tumbling_periods import simulate_run
from filters.attitude import attitude_matrix
from filters.attitude.torque_free_periods import euler_periods
from lightcurve.analysis.egi.profile import EGIProfile
from lightcurve.analysis.tumbling_reading import (
    CONVEX_LAW,
    MAX_MOMENT_RATIO,
    SCREEN_EPOCHS,
    SCREEN_NORMALS,
    ConvexDecision,
    ReadingFit,
    decide_reading,
    motions_with_ratio,
    reading_hypotheses,
)


def test_readings_are_bases_of_the_pair_within_the_period_ratio_bounds():
    pair = np.array([1 / 98.4, 1 / 82.5])
    readings = reading_hypotheses(pair)
    assert len({(round(r.f_phi, 12), round(r.f_psi, 12), r.mode) for r in readings}) == len(
        readings
    )
    for reading in readings:
        assert np.allclose(reading.basis @ pair, [reading.f_phi, reading.f_psi], rtol=1e-12)
        assert abs(round(np.linalg.det(reading.basis))) == 1
        bound = 0.5 if reading.mode == "SAM" else MAX_MOMENT_RATIO - 1.0
        assert 0 < reading.f_psi < bound * reading.f_phi
    # The long-axis reading (f_φ, f_φ + f_ψ) → (f_φ, f_ψ) and its short-axis twin are there.
    f_phi, f_psi = 1 / 98.4, 1 / 82.5 - 1 / 98.4
    assert any(
        np.allclose([r.f_phi, r.f_psi], [f_phi, f_psi]) and r.mode == "LAM" for r in readings
    )
    assert any(np.allclose([r.f_phi, r.f_psi], [2 * f_phi + f_psi, f_phi]) for r in readings)


@pytest.mark.parametrize("mode", ["SAM", "LAM"])
def test_motions_have_the_asked_period_ratio(mode):
    ratio = 0.3 if mode == "SAM" else 0.8
    motions = motions_with_ratio(ratio, mode, grid=4)
    assert motions
    assert all(m.mode == mode and abs(m.ratio / ratio - 1) < 1e-5 for m in motions)


@pytest.mark.parametrize(("run", "mode"), [(1, "LAM"), (10, "SAM")])
def test_true_reading_wins_on_a_simulated_tumbler(run, mode):
    """Geostationary arcs of the tumbler benchmark (seed 1): an egg, which no facet model on
    the grid reproduces, Lambertian where the fit assumes the convex-inversion law."""
    sim, inertia, omega, _, _ = simulate_run(1, run)
    truth = euler_periods(inertia, omega)
    assert truth.mode == mode
    pair = np.array([1 / truth.precession_period_s, 1 / truth.rotation_period_s])
    decision = decide_reading(sim, pair)
    best = decision.best
    assert np.allclose([best.reading.f_phi, best.reading.f_psi], pair, rtol=1e-9)
    assert best.reading.mode == mode and not decision.ambiguous
    # Within twice the χ² of the simulator's own attitudes (the law's and the grid's floor).
    profile = EGIProfile(sim, CONVEX_LAW, normals=SCREEN_NORMALS, epochs=SCREEN_EPOCHS)
    step = int(np.ceil(len(sim) / SCREEN_EPOCHS))
    assert best.chi2 < 2.0 * profile.chi2(attitude_matrix(sim.truth[::step, :4]))


def test_decision_periods_carry_the_basis_errors():
    periods_h, sigmas_h = np.array([98.4, 82.5]) / 3600, np.array([0.01, 0.02]) / 3600
    pair = 1 / (periods_h * 3600)
    f_phi, f_psi = pair[0], pair[1] - pair[0]
    lam = next(
        r
        for r in reading_hypotheses(pair)
        if r.mode == "LAM" and np.allclose([r.f_phi, r.f_psi], [f_phi, f_psi])
    )
    fit = ReadingFit(lam, 100.0, None, 0.0, np.eye(3))
    decision = ConvexDecision([fit], 20.0, False)
    periods = decision.periods(periods_h, sigmas_h)
    assert decision.best is fit and periods["mode"] == "LAM"
    assert periods["precession_period_h"]["period_h"] == pytest.approx(98.4 / 3600)
    assert periods["precession_period_h"]["sigma_h"] == pytest.approx(0.01 / 3600)
    # f_ψ = f₂ − f₁: σ² = σ₁² + σ₂² in frequency.
    sigma_f = np.hypot(0.01 / 98.4**2, 0.02 / 82.5**2)
    assert periods["rotation_period_h"]["sigma_h"] == pytest.approx(sigma_f / f_psi**2 / 3600)
