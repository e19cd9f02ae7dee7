"""Two-period (tumbling) analysis: the series, synthetic signals, simulated tumblers."""

import numpy as np
import pytest

from benchmarks.glint_power import fixed_geometry_curve
from benchmarks.tumbling_periods import egg, lattice_relation, simulate_run
from filters.attitude.torque_free_periods import euler_periods
from lightcurve.analysis.tumbling import euler_reading, tumbling_search, two_period_combinations
from lightcurve.photometry.simulate import GaussianNoise, simulate


@pytest.mark.parametrize("order", [1, 2, 3, 4, 6])
def test_combinations_are_the_half_lattice_of_the_order(order):
    combos = two_period_combinations(order)
    assert len(combos) == order * (order + 1)
    as_set = {tuple(c) for c in combos}
    assert len(as_set) == len(combos)
    assert all(abs(j) + abs(k) <= order and (j, k) != (0, 0) for j, k in combos)
    assert not any((-j, -k) in as_set for j, k in combos)
    with pytest.raises(ValueError, match="order"):
        two_period_combinations(0)


def test_noiseless_two_frequency_signal_is_recovered():
    rng = np.random.default_rng(1)
    t = np.sort(rng.uniform(0, 4 * 3600, 800))
    p1, p2 = 2 * np.pi * t / 700.0, 2 * np.pi * t / 1900.0
    mag = 0.3 * np.cos(2 * p1) + 0.1 * np.cos(p2 + 0.3) + 0.08 * np.cos(p1 - p2)
    # A synthetic signal, not a body's light curve: the series only, without the convex reading.
    result = tumbling_search(
        fixed_geometry_curve(t, mag, 0.01, "two"), (0.05, 2.0), model_reading=False
    )
    assert result.periods_h * 3600 == pytest.approx([700.0, 1900.0], rel=1e-5)
    # The rival's slowly changing coefficients absorb much of f2 (within a cycle per span of
    # the first period's harmonics here), so the margin is smaller than the χ² alone.
    assert result.tumbling and result.delta_bic > 100
    top = {(c["j"], c["k"]) for c in result.combinations[:3]}
    assert top == {(2, 0), (0, 1), (1, -1)}
    assert result.combinations[0]["amplitude_mag"] == pytest.approx(0.3, rel=1e-3)


def _simulated(omega, seed=1):
    t = np.arange(0.0, 3600.0, 3.0)
    geometry = fixed_geometry_curve(t, np.zeros(len(t)), 0.02, "geometry")
    inertia = np.diag([1.0, 2.0, 2.6])
    q0 = np.array([0.1, 0.2, 0.3, 0.927]) / np.linalg.norm([0.1, 0.2, 0.3, 0.927])
    body = egg(np.array([1.0, 1.6, 3.0]), np.array([1.5, 1.4]))
    sim = simulate(
        geometry,
        body,
        q0=q0,
        omega0=omega,
        inertia=inertia,
        noise=GaussianNoise(0.02),
        shadows="none",
        seed=seed,
    )
    return sim, euler_periods(inertia, omega)


def test_simulated_long_axis_tumbler_periods_within_one_percent_by_the_rule():
    """Under this fixed geometry the convex model's search does not reach the simulator's
    own χ² in any reading and picks the short-axis twin (docs/analysis.md); the amplitude
    rule reads the pair right."""
    sim, truth = _simulated(np.array([0.06, 0.03, 0.02]))
    assert truth.mode == "LAM"
    result = tumbling_search(sim, model_reading=False)
    assert result.tumbling
    reading = result.reading
    assert reading["precession_period_h"]["period_h"] * 3600 == pytest.approx(
        truth.precession_period_s, rel=0.01
    )
    assert reading["rotation_period_h"]["period_h"] * 3600 == pytest.approx(
        truth.rotation_period_s, rel=0.01
    )


def test_principal_axis_rotator_is_not_tumbling():
    sim, truth = _simulated(np.array([0.0, 0.0, 0.05]))
    assert truth.mode == "PA"
    result = tumbling_search(sim)
    assert not result.tumbling
    assert result.single.double_peaked_h * 3600 == pytest.approx(truth.rotation_period_s, rel=1e-3)


def test_spin_term_among_the_deeper_one_period_minima_is_a_first_frequency():
    """A seeded GEO tumbler (LAM, 1 h, P_φ = 533 s, P_ψ = 838 s) whose one-period scan has
    an 8.1-s minimum, the 2-s cadence's alias of the spin's second harmonic, and the spin
    ``f_φ + f_ψ`` itself only as its fifth minimum: with the alias dropped and four minima
    tried, the search lands on the true lattice (it had fitted an alias pair, 413 s and
    544 s)."""
    observations, inertia, omega, _, _ = simulate_run(0, 1)
    truth = euler_periods(inertia, omega)
    result = tumbling_search(observations, model_reading=False)  # the search alone
    fitted = 1.0 / (result.periods_h * 3600.0)
    true = 1.0 / np.array([truth.precession_period_s, truth.rotation_period_s])
    assert lattice_relation(fitted, true) == "same"
    assert result.tumbling


def _terms(strong):
    return [
        {"j": j, "k": k, "amplitude_mag": 0.3 if (j, k) == strong else 0.05}
        for j, k in ((2, 0), (0, 2), (1, 0), (0, 1))
    ]


def test_euler_reading_rule():
    """The generator with the stronger second harmonic is the spin f_s = f_φ ∓ f_ψ."""
    # LAM: f_φ = 1, f_ψ = 0.4 per hour; the pair (f_s, f_φ) = (1.4, 1).
    lam = euler_reading([1 / 1.4, 1.0], [1e-4, 1e-4], _terms((2, 0)))
    assert lam["mode"] == "LAM"
    assert lam["precession_period_h"]["period_h"] == pytest.approx(1.0)
    assert lam["rotation_period_h"]["period_h"] == pytest.approx(2.5)
    assert lam["rotation_period_h"]["sigma_h"] > lam["precession_period_h"]["sigma_h"]
    # SAM: f_φ = 1, f_ψ = 0.3; the pair (f_s, f_ψ) = (0.7, 0.3) or (f_φ, f_s) = (1, 0.7).
    for periods, strong in (([1 / 0.7, 1 / 0.3], (2, 0)), ([1.0, 1 / 0.7], (0, 2))):
        sam = euler_reading(periods, [1e-4, 1e-4], _terms(strong))
        assert sam["mode"] == "SAM"
        assert sam["precession_period_h"]["period_h"] == pytest.approx(1.0)
        assert sam["rotation_period_h"]["period_h"] == pytest.approx(1 / 0.3)
    # f_s < f_φ but P_φ > P_ψ/2: no SAM has it.
    assert euler_reading([1.0, 1 / 0.4], [1e-4, 1e-4], _terms((0, 2)))["mode"] == "undetermined"


def test_too_few_points_is_an_error():
    t = np.arange(20.0) * 10
    with pytest.raises(ValueError, match="too few points"):
        tumbling_search(fixed_geometry_curve(t, np.sin(t / 30), 0.01, "short"))


def test_rotator_with_a_drifting_phase_and_a_trend_is_not_tumbling():
    """A one-period light curve whose phase drifts (a changing synodic offset) and whose
    mean brightness follows the geometry: its harmonics must not pass for two periods."""
    t = np.arange(0.0, 5400.0, 6.0)
    x = t / t[-1]
    psi = 2 * np.pi * t / 300.0 + 0.4 * x**2  # a quarter radian of drift over the arc
    mag = 0.3 * np.cos(2 * psi) + 0.1 * np.cos(psi + 0.5) + 0.6 * x**2 - 0.3 * x
    mag = mag + np.random.default_rng(2).normal(0, 0.02, len(t))
    result = tumbling_search(fixed_geometry_curve(t, mag, 0.02, "drifting"), (0.02, 0.5))
    assert not result.tumbling
    assert result.single.period_h * 3600 == pytest.approx(300.0, rel=0.01)
