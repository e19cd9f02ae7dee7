"""Period search: Fourier periodogram with per-night offsets, aliases, sidereal correction."""

import math

import numpy as np
import pandas as pd
import pytest

from lightcurve import io
from lightcurve.analysis.period import (
    FourierDesign,
    fourier_chi2,
    pab_longitude,
    period_search,
    synodic_to_sidereal,
)
from lightcurve.analysis.spin import SpinState, simulate_rotator
from lightcurve.io.observations import Observations, validate_table
from lightcurve.photometry.simulate import GaussianNoise, simulate
from shapes import primitives
from shapes.material import REGOLITH

ARIADNE = "data/ariadne/test_lcs_rel"


def _table(mjd, mag, sigma, curve, sun=(1.5e8, 0, 0), obs=(0, 4e4, 1e3)):
    n = len(mjd)
    table = pd.DataFrame(
        {
            "mjd": mjd,
            "mag": mag,
            "mag_err": np.full(n, sigma),
            "lightcurve_id": curve,
            "relative": True,
            **{f"sun_{a}": np.full(n, v) for a, v in zip("xyz", sun, strict=True)},
            **{f"obs_{a}": np.full(n, v) for a, v in zip("xyz", obs, strict=True)},
        }
    )
    return Observations(validate_table(table, "synthetic"), {})


def test_fourier_chi2_is_zero_for_an_exact_model_with_offsets():
    rng = np.random.default_rng(3)
    t = np.sort(rng.uniform(0, 5 * 86400, 300))
    curve = (t // 86400).astype(int)
    f = 1 / 20000.0
    psi = 2 * np.pi * f * t
    mag = 0.3 * np.cos(2 * psi) + 0.1 * np.sin(psi) + 0.05 * np.cos(3 * psi + 1) + curve * 0.7
    chi2 = fourier_chi2(t, mag, np.full(300, 0.01), curve, np.array([f, 1.1 * f]), order=3)
    assert chi2[0] < 1e-9 * chi2[1]
    # Without the per-night offsets the same data do not fit.
    one_curve = fourier_chi2(t, mag, np.full(300, 0.01), np.zeros(300), np.array([f]), order=3)
    assert one_curve[0] > 1e3


def test_design_trend_modulation_and_slow_terms():
    """Per-curve cubic trends are projected out exactly; a linearly changing amplitude is
    what ``modulation=1`` fits; terms slower than ``slowest`` get no coefficient."""
    rng = np.random.default_rng(11)
    t = np.sort(rng.uniform(0, 2 * 86400, 400))
    curve = (t // 86400).astype(int)
    tau = 2 * (t - 86400 * curve) / 86400 - 1  # each curve's time on [-1, 1] (nearly)
    f = 1 / 3000.0
    psi = 2 * np.pi * f * t
    trend = 0.4 * tau**3 - 0.2 * tau + curve
    sigma = np.full(len(t), 0.01)
    chi2 = {
        degree: FourierDesign(
            t, 0.3 * np.cos(2 * psi) + trend, sigma, curve, trend_degree=degree
        ).solve(np.array([f]), 2)[1][0]
        for degree in (1, 3)
    }
    assert abs(chi2[3]) < 1e-4 and chi2[1] > 1e3
    growing = (0.3 + 0.1 * (t - 86400 * curve) / 86400) * np.cos(2 * psi)
    design = FourierDesign(t, growing, sigma, curve)
    harmonics = np.array([[1], [2]])
    plain = design.solve_combinations(np.array([[f]]), harmonics)[1][0]
    modulated = design.solve_combinations(np.array([[f]]), harmonics, modulation=1)[1][0]
    assert abs(modulated) < 1e-2 and plain > 1e3
    pair = np.array([[f, 2 * f + 1e-7]])  # (2, -1) is a 0.02-cycle term over the span
    coefficients, _ = design.solve_combinations(pair, np.array([[1, 0], [2, -1]]), slowest=1e-6)
    assert coefficients[0, 1] == 0 and coefficients[0, 3] == 0 and coefficients[0, 0] != 0


def test_multi_night_relative_light_curves_give_the_period_and_its_error():
    rng = np.random.default_rng(7)
    period_h = 7.3
    nights = np.arange(6) * 1.02
    mjd = np.concatenate([60000 + n + np.linspace(0, 0.25, 60) for n in nights])
    curve = np.repeat(np.arange(6), 60)
    psi = 2 * np.pi * (mjd - 60000) * 24 / period_h
    clean = 0.25 * np.cos(2 * psi) + 0.08 * np.cos(psi + 0.4) + 0.04 * np.sin(4 * psi)
    pulls = []
    for seed in range(3):
        noise = np.random.default_rng(seed).normal(0, 0.01, len(mjd))
        obs = _table(mjd, clean + noise + rng.normal(0, 1, 6)[curve], 0.01, curve)
        result = period_search(obs, (3.0, 12.0), orders=(2, 4))
        pulls.append((result.period_h - period_h) / result.sigma_h)
        assert abs(result.period_h / period_h - 1) < 1e-3
        assert {a["kind"] for a in result.aliases} >= {"half", "double"}
        assert result.double_peaked_h == pytest.approx(period_h, rel=1e-3)
        # One harmonic (Lomb–Scargle) sees the double-peaked curve at half the period.
        assert result.lomb_scargle_h == pytest.approx(period_h / 2, rel=2e-3)
    assert np.all(np.abs(pulls) < 4), pulls


@pytest.mark.parametrize(
    ("curves", "synodic_h"),
    [(range(2, 9), 5.7621), (range(24, 31), 5.7626)],
)
def test_ariadne_apparitions_right_alias_or_both_reported(curves, synodic_h):
    """Single-night relative light curves of one apparition (1973 and 1986-87)."""
    obs = io.read(ARIADNE)
    keep = np.isin(obs.lightcurve_ids, list(curves))
    sub = Observations(obs.table.loc[keep].reset_index(drop=True), obs.meta, obs.source)
    result = period_search(sub, (2.0, 12.0), orders=(2, 4, 6))
    periods = [result.period_h] + [
        a["period_h"] for a in result.aliases if a["kind"] in ("half", "double")
    ]
    assert min(abs(p / synodic_h - 1) for p in periods) < 1e-3
    # The double-peaked reading (two maxima per rotation) is Ariadne's period.
    assert result.double_peaked_h == pytest.approx(synodic_h, rel=1e-3)


def test_tumbling_rocket_body_period_within_one_percent():
    """End-over-end tumble (flat spin about a transverse axis), 20 min at 2 s, 0.02 mag."""
    period_s = 90.0
    t = np.arange(0.0, 1200.0, 2.0)
    n = len(t)
    # A GEO-like geometry: fixed Sun, observer 36 000 km away drifting slowly.
    angle = 2 * np.pi * t / 86164.0
    obs_vec = 3.6e4 * np.column_stack([np.cos(angle), np.sin(angle), np.full(n, 0.1)])
    table = pd.DataFrame(
        {
            "mjd": 60000.0 + t / 86400.0,
            **{f"sun_{a}": v for a, v in zip("xyz", (1.0e8, 1.1e8, 0.0), strict=True)},
            **{f"obs_{a}": obs_vec[:, k] for k, a in enumerate("xyz")},
        }
    )
    geometry = Observations(validate_table(table, "rb", require_magnitudes=False), {})
    body = primitives.rocket_body(sections=16)
    q0 = np.array([0.2, -0.1, 0.3, 0.9]) / np.linalg.norm([0.2, -0.1, 0.3, 0.9])
    sim = simulate(
        geometry,
        body,
        q0=q0,
        omega0=[2 * np.pi / period_s, 0.0, 0.0],
        noise=GaussianNoise(0.02),
        seed=4,
    )
    result = period_search(sim, (20 / 3600, 600 / 3600), orders=(2, 4))
    assert abs(result.period_h * 3600 / period_s - 1) < 0.01
    assert result.sigma_h * 3600 < 0.5


def test_pab_corrected_scan_finds_the_sidereal_period():
    """An ellipsoid seen over Ariadne's 1973 apparition: synodic ≠ sidereal; the PAB phase
    (epoch method) recovers the sidereal period, and so does the synodic → sidereal formula."""
    obs = io.read(ARIADNE)
    keep = np.isin(obs.lightcurve_ids, list(range(2, 9)))
    geometry = Observations(obs.table.loc[keep].reset_index(drop=True), obs.meta, obs.source)
    body = primitives.ellipsoid((2.0, 1.2, 1.0), subdivisions=3, materials=REGOLITH)
    spin = SpinState.from_degrees(40.0, 50.0, 7.0, 0.0, float(geometry.mjd.min()))
    sim = simulate_rotator(geometry, body, spin, noise=GaussianNoise(0.005), seed=2)
    pole = (spin.lambda_rad, spin.beta_rad)
    synodic = period_search(sim, (6.9, 7.1), orders=(2, 4))
    sidereal = period_search(sim, (6.9, 7.1), orders=(2, 4), pole=pole)
    assert sidereal.sidereal and not synodic.sidereal
    assert abs(sidereal.period_h - 7.0) < 3 * sidereal.sigma_h + 1e-5
    assert abs(synodic.period_h - 7.0) > 5 * synodic.sigma_h
    converted = synodic_to_sidereal(
        synodic.period_h, sim.mjd, sim.sun_vectors, sim.observer_vectors, pole
    )
    assert abs(converted - 7.0) < abs(synodic.period_h - 7.0) / 3


def test_pab_longitude_about_the_ecliptic_pole_is_the_ecliptic_longitude():
    sun = np.array([[1.0, 0.0, 0.0]]) * 1e8
    observer = np.array([[0.0, 1.0, 0.0]]) * 1e8
    # Pole = ecliptic north: the pole frame is the ecliptic frame; PAB at longitude 45°.
    lon = pab_longitude(sun, observer, (0.0, math.pi / 2))
    assert math.degrees(lon[0]) == pytest.approx(45.0)


def test_bad_inputs():
    mjd = 60000 + np.linspace(0, 2, 200)
    obs = _table(mjd, np.sin(mjd * 50), 0.01, np.zeros(200, int))
    with pytest.raises(ValueError, match="period range"):
        period_search(obs, (-1.0, 5.0))
    with pytest.raises(ValueError, match="narrow --range"):
        period_search(obs, (1e-4, 100.0))


def test_a_range_narrower_than_the_resolution_is_refused():
    # 20 minutes of data cannot resolve periods between 5.75 and 5.77 h: the search used to
    # return a period outside the range (1.34 h, σ = ∞).
    mjd = 60000 + np.linspace(0, 1200, 600) / 86400
    obs = _table(mjd, np.sin(mjd * 5000), 0.01, np.zeros(600, int))
    with pytest.raises(ValueError, match="narrower than the periodogram's resolution"):
        period_search(obs, (5.75, 5.77))
    assert 0.02 <= period_search(obs, (0.02, 1.0), orders=(2,)).period_h <= 1.0
