"""Relative GNSS end to end: measurement model, fixes of a LEO formation, loss of common
view, cycle slips."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from filters.gnss.constellation import Constellation, parse_yuma
from filters.gnss.formation import FormationScenario, simulate_formation
from filters.gnss.measurements import (
    EARTH_RADIUS,
    ReceiverModel,
    simulate_observations,
    visible_satellites,
)
from filters.gnss.relative import RelativeGnssSolver
from filters.navigation.hill import circular_orbit

ALMANAC = Path(__file__).resolve().parents[3] / "data" / "gnss" / "gps_week147_yuma.alm"


@pytest.fixture(scope="module")
def almanac():
    return parse_yuma(ALMANAC.read_text())


def test_simulated_double_differences_are_ranges_plus_integer_cycles(almanac):
    const = Constellation(almanac)
    t = almanac.toa[0] + np.arange(5.0)
    r, _ = circular_orbit(EARTH_RADIUS + 500e3, math.radians(51.6), 0.3, 1.0, t - t[0])
    x = np.stack([r, r + np.array([300.0, -800.0, 450.0])])
    quiet = ReceiverModel(code_sigma=1e-9, phase_sigma=1e-9, clock_random_walk=1e-9)
    obs = simulate_observations(const, t, x, quiet, np.random.default_rng(2))
    seen = obs.truth["visible"].all(axis=(0, 1))
    assert seen.sum() >= 5
    rho = obs.truth["range"][..., seen]
    n = obs.truth["ambiguity"][..., seen]
    sd = lambda v: v[1] - v[0]  # noqa: E731
    dd = lambda v: v[..., 1:] - v[..., :1]  # noqa: E731
    # Clocks and fractional phases cancel; code DD = range DD, phase DD = range DD / λ + ΔN.
    np.testing.assert_allclose(dd(sd(obs.code[..., seen])), dd(sd(rho)), atol=1e-5)
    np.testing.assert_allclose(
        dd(sd(obs.phase[..., seen])), dd(sd(rho)) / obs.wavelength + dd(sd(n)), atol=1e-4
    )
    # Single differences keep the receiver clock difference (common to the satellites of an
    # epoch, drifting in time) and the fractional phases: not integers.
    frac = sd(obs.phase[..., seen]) - sd(rho) / obs.wavelength - sd(n)
    assert np.all(np.ptp(frac, axis=-1) < 1e-4) and abs(frac[0, 0] - round(frac[0, 0])) > 1e-3


def test_elevation_mask_and_earth_blockage():
    leo = np.array([EARTH_RADIUS + 500e3, 0.0, 0.0])
    zenith = np.array([3e7, 0.0, 0.0])
    horizon = np.array([EARTH_RADIUS + 500e3, 2.6e7, 0.0])  # just above the local horizontal
    below = np.array([0.0, 2.6e7, -1.2e7])  # below the horizon, clear of the Earth
    behind = np.array([-3e7, 0.0, 0.0])  # behind the Earth
    sats = np.stack([zenith, horizon, below, behind])
    np.testing.assert_array_equal(
        visible_satellites(leo, sats, math.radians(10)), [True, False, False, False]
    )
    np.testing.assert_array_equal(
        visible_satellites(leo, sats, math.radians(-30)), [True, True, True, False]
    )
    model = ReceiverModel(obstructions=((100.0, 200.0, math.radians(60)),))
    np.testing.assert_allclose(np.degrees(model.mask_at([50.0, 150.0])), [10.0, 60.0])


@pytest.fixture(scope="module")
def formation_runs(almanac):
    scenario = FormationScenario(almanac, duration=90.0)
    return [simulate_formation(scenario, seed) for seed in range(4)]


def test_leo_formation_fixes_within_a_minute(formation_runs):
    for run in formation_runs:
        assert run.time_to_first_fix is not None and run.time_to_first_fix <= 60.0
        assert not run.wrong_fix
        assert not run.detected_slips  # no false alarms on clean data
    pooled = lambda key: np.sqrt(np.nanmean(np.concatenate(  # noqa: E731
        [getattr(r, key) for r in formation_runs]) ** 2, axis=0))  # fmt: skip
    assert np.all(pooled("fixed_errors") < 0.012)  # m, per Hill axis
    assert np.all(pooled("code_errors") < 2.0)
    assert np.all(pooled("code_errors") > 0.2)  # code is code: no phase leaks in
    assert np.all(pooled("velocity_errors") < 0.03)  # m/s


def test_carrier_smoothed_code_is_unbiased_and_consistent(formation_runs):
    runs = len(formation_runs)
    late = lambda key: np.concatenate(  # noqa: E731
        [getattr(r, key)[r.times >= 30.0] for r in formation_runs])  # fmt: skip
    err, std, raw = late("smoothed_errors"), late("smoothed_std"), late("code_errors")
    # Unbiased: the pooled mean is within 3 standard errors, counting each run as one sample
    # (its errors are correlated over the smoothing window).
    assert np.all(np.abs(err.mean(axis=0)) < 3.0 * np.sqrt(np.mean(std**2, axis=0) / runs))
    # The covariance model holds: normalised errors of unit RMS (loosely: few independent
    # samples), and the smoothing pays: 30 s and more of averaging beat the snapshot ≥ 3×.
    assert 0.4 < np.sqrt(np.mean((err / std) ** 2)) < 2.0
    assert np.all(np.sqrt(np.mean(err**2, axis=0)) < np.sqrt(np.mean(raw**2, axis=0)) / 3.0)
    # The predicted spread shrinks with the window: σ/√n for the channels tracked throughout.
    early = np.concatenate([r.smoothed_std[9] for r in formation_runs])
    final = np.concatenate([r.smoothed_std[-1] for r in formation_runs])
    assert np.all(final < early / 2.0)


def test_fewer_than_five_common_satellites_means_no_fix_then_refix(almanac):
    blocked = ReceiverModel(obstructions=((45.0, 60.0, math.radians(75.0)),))
    run = simulate_formation(FormationScenario(almanac, duration=110.0, receiver=blocked), 1)
    window = (run.times >= 45) & (run.times < 60)
    assert np.all(run.status[window] == "none") and np.all(run.satellites[window] < 5)
    assert run.status[44] == "fixed"  # fixed before the obstruction
    after = run.status[run.times >= 60]
    assert after[-1] == "fixed" and not run.wrong_fix


def test_no_fix_message_names_the_satellite_count(almanac):
    const = Constellation(almanac)
    solver = RelativeGnssSolver(const)
    prn = almanac.prn[:6]
    code = np.full(6, 2.2e7)
    code[4:] = np.nan
    sol = solver.process(almanac.toa[0], prn, code, code, code, code)
    assert sol.status == "none" and sol.satellites == 4
    assert "4 satellites in common view, fewer than 5" in sol.message
    assert np.all(np.isnan(sol.position))


@pytest.mark.parametrize("cycles", [1, -7])
def test_cycle_slip_is_detected_and_the_ambiguity_refixed(almanac, formation_runs, cycles):
    clean = formation_runs[2]
    k = int(np.searchsorted(clean.times, 60.0))
    assert clean.status[k - 1] == "fixed"
    prn = min(clean.fixed_ambiguities[k])  # a non-reference satellite with a fixed ambiguity
    scenario = FormationScenario(almanac, duration=90.0, slips=((60.0, 1, prn, cycles),))
    run = simulate_formation(scenario, 2)
    assert [p for t, p in run.detected_slips] == [prn] and run.detected_slips[0][0] == 60.0
    # Re-initialised and fixed again (the others pin the baseline), to the slipped integer.
    before, after = run.fixed_ambiguities[k - 1], run.fixed_ambiguities[k]
    assert after[prn] - before[prn] == cycles
    # Its carrier smoothing restarts, the others carry on, and the slip does not leak in.
    assert run.smoothing[k][prn] == 1
    assert all(n == run.smoothing[k - 1][p] + 1 for p, n in run.smoothing[k].items() if p != prn)
    assert np.all(np.abs(run.smoothed_errors[k:]) < 4.0 * run.smoothed_std[k:])
    assert run.status[-1] == "fixed" and not run.wrong_fix


def test_slip_on_the_reference_reinitialises_everything(almanac, formation_runs):
    clean = formation_runs[3]
    k = int(np.searchsorted(clean.times, 50.0))
    ref = int(clean.references[k])
    scenario = FormationScenario(almanac, duration=90.0, slips=((50.0, 0, ref, 2),))
    run = simulate_formation(scenario, 3)
    assert {p for t, p in run.detected_slips if t == 50.0} >= {ref}
    assert run.fixed_ambiguities[k] == {} and run.status[-1] == "fixed" and not run.wrong_fix
    assert set(run.smoothing[k].values()) == {1}  # every channel's smoothing restarts


def test_formation_scenario_checks(almanac):
    with pytest.raises(ValueError, match="phase_sigma"):
        dataclasses.replace(ReceiverModel(), phase_sigma=0.0)
