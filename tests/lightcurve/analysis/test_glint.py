"""Glints: detection at a false-alarm level, PAB directions, panel normals, glint periods."""

import math

import numpy as np
import pandas as pd
import pytest

from benchmarks.glint_power import fixed_geometry_curve
from brdf.materials import load_presets
from filters.attitude import quaternion_from_matrix, rotate
from lightcurve.analysis.glint import Glint, detect_glints, glint_period, panel_normal
from lightcurve.analysis.glint.detection import _clipped_mad, _local_fit
from lightcurve.io.observations import Observations, datetime_to_mjd
from lightcurve.photometry.simulate import GaussianNoise, simulate
from lightcurve.sky.ephemeris import CircularOrbit, Site, orbit_geometry
from lightcurve.sky.geometry import phase_angle_bisector
from shapes import Material, primitives

SIDEREAL_DAY = 86164.0905


@pytest.fixture(scope="module")
def geo_night():
    """A nadir-pointing GEO box-wing seen from the equator at the March equinox.

    The body frame is the orbit frame (x along-track, y = −orbit normal, z nadir); the
    satellite turns once per sidereal day about −y, which ``simulate`` reproduces with
    ω = (0, −n, 0). The array normal is put on the night's PAB track (in the body frame).
    """
    start = datetime_to_mjd(pd.DatetimeIndex([pd.Timestamp("2026-03-20T00:00", tz="UTC")]))[0]
    orbit = CircularOrbit.geostationary(-110.0, start)
    mjd = start + np.arange(0.0, 86400.0, 60.0) / 86400.0
    geometry = orbit_geometry(orbit, Site(0.0, -110.0, 0.0, "equator"), mjd, "geo")
    r = orbit.position(geometry.mjd[:1])[0]
    v = orbit.position(geometry.mjd[:1] + 1e-5)[0] - r
    z = -r / np.linalg.norm(r)
    y = -np.cross(r, v) / np.linalg.norm(np.cross(r, v))
    q0 = quaternion_from_matrix(np.array([np.cross(y, z), y, z])[None])[0]
    omega = np.array([0.0, -2 * math.pi / SIDEREAL_DAY, 0.0])
    dry = simulate(
        geometry, primitives.box_wing(), q0=q0, omega0=omega, inertia=np.eye(3), shadows="none"
    )
    pab_body = np.asarray(
        rotate(dry.truth[:, :4], phase_angle_bisector(geometry.sun_vectors, dry.observer_vectors))
    )
    normal = pab_body[len(pab_body) // 4] * [1.0, 0.0, 1.0]
    normal /= np.linalg.norm(normal)
    return geometry, q0, omega, normal


def test_geo_box_wing_array_normal_from_a_night_of_glints(geo_night):
    geometry, q0, omega, normal = geo_night
    shape = primitives.box_wing(array_normal=normal)
    sim = simulate(
        geometry, shape, q0=q0, omega0=omega, inertia=np.eye(3), noise=GaussianNoise(0.02), seed=3
    )
    detection = detect_glints(sim, false_alarm=1e-3)
    assert len(detection.glints) >= 1
    attitudes = [sim.truth[np.argmin(np.abs(sim.times - g.time_s)), :4] for g in detection.glints]
    estimate = panel_normal(detection.glints, attitudes)
    error = math.degrees(math.acos(np.clip(estimate.normal @ normal, -1, 1)))
    assert error < 2.0
    # In the inertial frame the PAB at the glint epoch is the array normal at that instant.
    glint = detection.glints[0]
    q = attitudes[0]
    inertial_normal = np.asarray(rotate(q * [-1, -1, -1, 1], normal))
    assert math.degrees(math.acos(np.clip(glint.pab @ inertial_normal, -1, 1))) < 2.0


def test_no_glint_on_a_glint_free_curve(geo_night):
    """The array faces along-track: it never meets the PAB; MLI gives broad humps only."""
    geometry, q0, omega, _ = geo_night
    shape = primitives.box_wing(array_normal=(1.0, 0.0, 0.0))
    sim = simulate(
        geometry, shape, q0=q0, omega0=omega, inertia=np.eye(3), noise=GaussianNoise(0.02), seed=5
    )
    assert detect_glints(sim, false_alarm=1e-3).glints == []


def _noise_curve(rng, n=800, sigma=0.02):
    t = np.arange(n) * 10.0
    mag = 11 + 0.4 * np.sin(t / 2500) + rng.normal(0, sigma, n)
    return fixed_geometry_curve(t, mag, sigma, "noise")


def test_false_alarm_rate_is_calibrated():
    """200 seeded glint-free curves (trend + Gaussian noise): the fraction with a detection
    matches the stated false-alarm probability (binomial 99.9 % bounds)."""
    rng = np.random.default_rng(11)
    base = _noise_curve(rng, n=400)
    trend = 11 + 0.4 * np.sin(base.times / 2500)
    runs, level = 200, 0.05
    hits = 0
    for _ in range(runs):
        table = base.table.assign(mag=trend + rng.normal(0, 0.02, len(trend)))
        hits += bool(detect_glints(Observations(table, {}), 1800.0, level).glints)
    assert 1 <= hits <= 23, hits


def test_flashes_are_found_with_their_epochs_and_the_glint_period():
    """Gaussian flashes every 137 s (one missed) on a noisy trend; tumbler period."""
    rng = np.random.default_rng(2)
    obs = _noise_curve(rng, n=1000, sigma=0.02)
    epochs = np.array([900.0, 1037.0, 1174.0, 1448.0, 1585.0, 1722.0])  # 1311 s missed
    t = obs.times
    flash = sum(-0.6 * np.exp(-0.5 * ((t - e) / 12.0) ** 2) for e in epochs)
    obs = obs.with_columns(mag=obs.magnitudes + flash)
    glints = detect_glints(obs, 600.0, 1e-3).glints
    assert len(glints) == len(epochs)
    found = np.array([g.time_s for g in glints])
    sigma = np.array([g.sigma_time_s for g in glints])
    assert np.all(np.abs(found - epochs) < 4 * sigma + 1.0)
    period, period_sigma = glint_period(glints)
    assert abs(period - 137.0) < 4 * period_sigma + 0.2
    assert glint_period(glints[:2]) is None


def test_least_squares_normal_of_scattered_glints():
    """Eight glints of one panel, PAB directions scattered by 0.6°: the weighted mean
    direction is within its stated error of the truth."""
    rng = np.random.default_rng(5)
    truth = np.array([0.3, -0.4, 0.866])
    truth /= np.linalg.norm(truth)
    glints = []
    for k in range(8):
        pab = truth + rng.normal(0, 0.01, 3)
        glints.append(
            Glint(
                time_s=100.0 * k,
                sigma_time_s=30.0,
                mjd=60000.0,
                amplitude_mag=1.0,
                significance=20.0,
                duration_s=300.0,
                pab=pab / np.linalg.norm(pab),
                pab_rate=np.array([1e-4, 0.0, 0.0]),
                rows=np.array([k]),
                excess=np.array([1.5]),
            )
        )
    estimate = panel_normal(glints)
    error = math.degrees(math.acos(estimate.normal @ truth))
    assert error < 3 * estimate.sigma_deg
    assert 0.05 < estimate.sigma_deg < 2.0
    # In the body frame: the same glints seen by a body turned 90° about z.
    q = np.array([0.0, 0.0, math.sin(math.pi / 4), math.cos(math.pi / 4)])
    body = panel_normal(glints, [q] * len(glints))
    np.testing.assert_allclose(body.normal, np.asarray(rotate(q, estimate.normal)), atol=1e-12)
    with pytest.raises(ValueError, match="no glint"):
        panel_normal([])


def _two_lobe_array() -> Material:
    preset = load_presets()["starlink-solar-array"]
    return Material(preset.model, preset.params, name="solar array")


def test_geo_box_wing_with_two_lobe_array_flashes_and_gives_its_normal(geo_night):
    """Array material fitted to the Starlink lab table (diffuse + broad + mirror lobe): the
    glint is found and the body-frame array normal recovered within 1°; turned away
    (array facing along-track), the same object shows no glint."""
    geometry, q0, omega, normal = geo_night
    materials = {"solar_array": _two_lobe_array()}
    shape = primitives.box_wing(array_normal=normal, materials=materials)
    sim = simulate(
        geometry, shape, q0=q0, omega0=omega, inertia=np.eye(3), noise=GaussianNoise(0.02), seed=3
    )
    glints = detect_glints(sim, false_alarm=1e-3).glints
    assert len(glints) >= 1
    attitudes = [sim.truth[np.argmin(np.abs(sim.times - g.time_s)), :4] for g in glints]
    estimate = panel_normal(glints, attitudes)
    assert math.degrees(math.acos(np.clip(estimate.normal @ normal, -1, 1))) < 1.0
    away = primitives.box_wing(array_normal=(1.0, 0.0, 0.0), materials=materials)
    sim = simulate(
        geometry, away, q0=q0, omega0=omega, inertia=np.eye(3), noise=GaussianNoise(0.02), seed=5
    )
    assert detect_glints(sim, false_alarm=1e-3).glints == []


def test_no_false_glint_on_a_panel_fading_towards_its_terminator():
    """A flat panel fixed in inertial space, 56° off the night's PAB track, over an 8-hour
    GEO night: its curve bends by 1.6 mag in the last 1.2 h. The local cubic baseline
    (default) gives no glint at FA = 1e-3 for any of three noise draws; the straight line
    does on its own, but not with the bias check (every brightening also measured against
    a local cubic)."""
    start = datetime_to_mjd(pd.DatetimeIndex([pd.Timestamp("2026-01-15T03:20", tz="UTC")]))[0]
    orbit = CircularOrbit.geostationary(-110.0, start)
    mjd = start + np.arange(0.0, 8 * 3600.0, 60.0) / 86400.0
    geometry = orbit_geometry(orbit, Site(0.0, -110.0, 0.0, "equator"), mjd, "geo")
    normal = np.array([0.0, -0.31, -0.95]) / math.hypot(0.31, 0.95)
    x = np.cross([0.0, 0.0, 1.0], normal)
    x /= np.linalg.norm(x)
    q0 = quaternion_from_matrix(np.array([x, np.cross(normal, x), normal])[None])[0]
    panel = primitives.plate(materials=Material("lambert", {"rd": 0.3}))
    straight = 0
    for seed in range(3):
        sim = simulate(
            geometry,
            panel,
            q0=q0,
            omega0=np.zeros(3),
            inertia=np.eye(3),
            noise=GaussianNoise(0.02),
            shadows="none",
            seed=seed,
        )
        assert detect_glints(sim, false_alarm=1e-3).glints == []
        straight += len(detect_glints(sim, false_alarm=1e-3, degree=1, bias_check=False).glints)
        assert detect_glints(sim, false_alarm=1e-3, degree=1).glints == []
    assert straight >= 1


def test_cubic_baseline_does_not_swing_across_a_long_flash_near_the_start():
    """A 6 mag flash (σ = 15 min) one hour into a fading 8-hour curve: clipped from the
    windows beside it, it leaves only a few points on one side, where a cubic fitted to them
    would swing across the gap (splitting the flash and losing up to 1.3 mag of it). The
    baseline falls back to a straight line there: one glint, at the flash, at full height."""
    rng = np.random.default_rng(0)
    obs = _noise_curve(rng, n=500)
    t = obs.times * 6.0  # 60 s cadence
    flash = -6.0 * np.exp(-0.5 * ((t - 4000.0) / 900.0) ** 2)
    table = obs.table.assign(
        mjd=60000 + t / 86400, mag=11 + 1.5 * (t / t[-1]) ** 2 + flash + rng.normal(0, 0.02, 500)
    )
    glints = detect_glints(Observations(table, {}), degree=3).glints
    assert len(glints) == 1
    assert abs(glints[0].time_s - 4000.0) < 60.0
    assert abs(glints[0].amplitude_mag - 6.0) < 0.2


def test_detection_options_are_checked():
    obs = _noise_curve(np.random.default_rng(0), n=100)
    with pytest.raises(ValueError, match="degree"):
        detect_glints(obs, degree=4)
    with pytest.raises(ValueError, match="max_flash_s"):
        detect_glints(obs, max_flash_s=-1.0)
    assert detect_glints(obs, max_flash_s=600.0).window_s == 2400.0


def test_residual_variance_is_that_of_the_smoother_matrix():
    """The residual variance factor ``v_i`` of the local fit equals ``Σ_j (δ_ij − l_ij)²
    (e_j/e_i)²`` with the smoother matrix ``l`` probed column by column (the fit is linear
    in the magnitudes), for unequal errors and with clipped points left out of the fits."""
    rng = np.random.default_rng(4)
    n = 90
    t = np.cumsum(rng.uniform(40.0, 80.0, n))
    e = rng.uniform(0.01, 0.04, n)
    keep = np.ones(n, dtype=bool)
    keep[[30, 31, 55]] = False
    smoother = np.column_stack(
        [_local_fit(t, np.eye(n)[k], e, keep, window=1500.0, degree=3)[0] for k in range(n)]
    )
    _, variance = _local_fit(t, rng.normal(size=n), e, keep, window=1500.0, degree=3)
    expected = np.sum(((np.eye(n) - smoother) * e[None, :] / e[:, None]) ** 2, axis=1)
    np.testing.assert_allclose(variance, expected, rtol=1e-9)
    assert np.all(variance[keep] < 1.0) and np.all(variance[~keep] > 1.0)
    assert variance[0] < np.median(variance[keep]) - 0.05  # a point pulls its fit most at an end


@pytest.mark.parametrize("clip", [0.5, 1.5, 3.0])
def test_mad_of_the_clipped_normal_matches_a_clipped_sample(clip):
    sample = np.random.default_rng(8).normal(size=400_000)
    sample = sample[sample <= clip]
    mad = np.median(np.abs(sample - np.median(sample)))
    assert abs(_clipped_mad(clip) - mad) < 0.004
    assert _clipped_mad(math.inf) == pytest.approx(0.674489750, abs=1e-9)


def test_residual_scatter_is_calibrated_at_the_ends_and_inside():
    """Pure noise (known σ): the brightenings in units of the detector's per-point σ, times its
    scatter estimate over the true σ, have unit spread within a tenth of the window of either
    end (where each point pulls its own fit most) and in the middle half of the curve."""
    rng = np.random.default_rng(7)
    ends, middle = [], []
    for _ in range(30):
        table = _noise_curve(rng, n=400).table
        curve = Observations(table.assign(mag=11.0 + rng.normal(0.0, 0.02, 400)), {})
        detection = detect_glints(curve)
        z = detection.excess_sigma * detection.noise_mag / 0.02
        ends.append(np.r_[z[:10], z[-10:]])
        middle.append(z[100:300])
    assert 0.92 < np.std(np.concatenate(ends)) < 1.08
    assert 0.97 < np.std(np.concatenate(middle)) < 1.03
