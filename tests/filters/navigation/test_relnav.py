"""Multi-mode relative navigation: Huber IRLS update, the IMU-driven filter, modes, outliers,
relative GNSS from raw measurements and backup sensors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import minimize

from filters.gaussian import joseph_update, kalman_gain
from filters.gnss.constellation import parse_yuma
from filters.gnss.measurements import ReceiverModel
from filters.navigation.hill import cw_input_matrix, cw_transition, mean_motion
from filters.navigation.relnav import RelativeNavigationFilter
from filters.robust import huber_kalman_update, huber_loss, huber_weights
from lightcurve.studies.relnav import (
    ApproachScenario,
    PositionSensor,
    RgnssSensor,
    reference_trajectory,
    simulate_approach,
)

N = mean_motion(6878.137e3)
H = np.hstack([np.eye(3), np.zeros((3, 3))])
SENSORS = {
    "lidar": PositionSensor("lidar", 0.05, 1.0, True),
    "stereo": PositionSensor("stereo", 0.10, 1.0, True),
    "gnss": PositionSensor("gnss", 0.02, 1.0, False),
}


def approach(**changes) -> ApproachScenario:
    """data/scenarios/relnav_approach.toml, shortened to a 600 s run with a 400 s approach."""
    fields = {
        "mean_motion": N,
        "start": np.array([-10.0, 0.0, 0.0]),
        "hold": np.array([-1.0, 0.0, 0.0]),
        "approach_duration": 400.0,
        "duration": 600.0,
        "imu_period": 0.16,
        "accelerometer_noise": 1e-3,
        "thrust_noise": 1e-3,
        "control_frequency": 0.02,
        "control_damping": 0.9,
        "sensors": SENSORS,
        "mode": "non-cooperative",
        "initial_sigma_position": 0.5,
        "initial_sigma_velocity": 0.01,
        "settle": 60.0,
    }
    fields.update(changes)
    return ApproachScenario(**fields)


# --------------------------------------------------------------------------- Huber M-estimation
def test_huber_weights_and_loss():
    r = np.array([0.0, 1.0, -1.345, 2.69, -40.0])
    np.testing.assert_allclose(huber_weights(r), [1, 1, 1, 0.5, 1.345 / 40])
    # ρ is quadratic inside, linear outside, and continuous at the threshold.
    np.testing.assert_allclose(
        huber_loss([1.0, 1.345, 3.0]), [0.5, 0.5 * 1.345**2, 1.345 * 3 - 0.5 * 1.345**2]
    )
    with pytest.raises(ValueError, match="threshold"):
        huber_weights(r, 0.0)


def _prior(rng):
    a = rng.normal(size=(6, 6))
    return rng.normal(size=6), a @ a.T * 1e-4 + np.eye(6) * 1e-5


def test_infinite_threshold_is_the_kalman_update():
    rng = np.random.default_rng(0)
    x, p = _prior(rng)
    z, r = rng.normal(size=3), np.diag([0.01, 0.02, 0.03])
    out = huber_kalman_update(x, p, z, H, r, threshold=np.inf)
    gain, _ = kalman_gain(p, H, r)
    np.testing.assert_allclose(out.x, x + gain @ (z - H @ x), atol=1e-12)
    np.testing.assert_allclose(out.P, joseph_update(p, gain, H, r), atol=1e-14)
    assert out.iterations == 1 and not out.downweighted


@settings(max_examples=12, deadline=None)
@given(st.integers(0, 10_000), st.floats(1.0, 50.0))
def test_irls_reaches_the_huber_objective_minimum(seed, outlier):
    rng = np.random.default_rng(seed)
    x, p = _prior(rng)
    sigma = 0.05
    z = H @ x + sigma * rng.normal(size=3)
    z[rng.integers(3)] += outlier  # a gross error on one component
    out = huber_kalman_update(x, p, z, H, sigma**2 * np.eye(3))
    p_inv = np.linalg.inv(p)

    def objective(v):
        d, res = v - x, (z - H @ v) / sigma
        grad = p_inv @ d - H.T @ np.clip(res, -1.345, 1.345) / sigma
        return 0.5 * d @ p_inv @ d + np.sum(huber_loss(res)), grad

    ref = minimize(objective, x, jac=True, method="BFGS", options={"gtol": 1e-9})
    assert objective(out.x)[0] <= ref.fun + 1e-7
    assert out.downweighted


def test_outlier_influence_is_bounded():
    rng = np.random.default_rng(1)
    x, p = _prior(rng)
    r = 0.05**2 * np.eye(3)
    z = H @ x
    shifts = []
    for size in (1.0, 10.0, 1000.0):
        out = huber_kalman_update(x, p, z + np.array([size, 0.0, 0.0]), H, r)
        shifts.append(np.linalg.norm(out.x - x))
    plain_gain, _ = kalman_gain(p, H, r)
    assert shifts[2] == pytest.approx(shifts[1], rel=1e-6)  # saturated: ψ(r) = c beyond c
    assert shifts[2] < 1e-3 * np.linalg.norm(plain_gain @ [1000.0, 0, 0])


# --------------------------------------------------------------------------- the filter
def test_prediction_is_exact_cw_with_control_input():
    x0 = np.array([-10.0, 0.5, 0.2, 0.01, -0.002, 0.0])
    u = np.array([1e-4, -2e-4, 5e-5])
    kf = RelativeNavigationFilter(x0, np.eye(6) * 1e-4, N, 1e-3, robust="none")
    for _ in range(25):
        kf.predict(u, 0.16)
    expected = cw_transition(N, 4.0) @ x0 + cw_input_matrix(N, 4.0) @ u
    np.testing.assert_allclose(kf.x, expected, atol=1e-12)
    # Process noise grows the velocity variance by σ² Δt per unit time (random walk).
    assert kf.P[3, 3] - 1e-4 == pytest.approx(1e-6 * 0.16**2 * 25, rel=0.05)


def test_filter_rejects_unknown_robust_option():
    with pytest.raises(ValueError, match="robust"):
        RelativeNavigationFilter(np.zeros(6), np.eye(6), N, 1e-3, robust="tukey")


def test_reference_trajectory_is_smooth_from_start_to_hold():
    start, hold, t_app = np.array([-10.0, 0, 0]), np.array([-1.0, 0, 0]), 1200.0
    pos, vel, acc = reference_trajectory(np.array([0.0, 600.0, 1200.0, 5000.0]), start, hold, t_app)
    np.testing.assert_allclose(pos[[0, 2, 3]], [start, hold, hold])
    np.testing.assert_allclose(pos[1], (start + hold) / 2)
    np.testing.assert_allclose(vel[[0, 2, 3]], 0.0)
    assert vel[1, 0] == pytest.approx(1.5 * 9 / t_app)  # peak speed of the cubic
    np.testing.assert_allclose(acc[3], 0.0)


# --------------------------------------------------------------------------- the approach
@pytest.fixture(scope="module")
def outlier_study():
    sc = approach()
    return {
        (rate, robust): simulate_approach(sc, rate, 2.0, robust=robust, seed=3)
        for rate in (0.0, 0.05)
        for robust in ("huber", "none")
    }


def test_clean_accuracy_matches_the_paper(outlier_study):
    clean = outlier_study[(0.0, "none")]
    assert clean.position_rms < 0.1  # paper: 0.098, 0.095, 0.096 m per axis
    assert np.all(clean.position_rms_axes < 0.098)
    assert clean.velocity_rms < 0.008  # paper: 0.008, 0.007, 0.007 m/s
    assert 4.5 < clean.nees_mean < 7.5  # χ²(6) has mean 6
    assert clean.truth[-1, :3] == pytest.approx([-1.0, 0.0, 0.0], abs=0.05)


def test_huber_keeps_accuracy_under_gross_errors(outlier_study):
    huber_clean = outlier_study[(0.0, "huber")].position_rms
    huber_gross = outlier_study[(0.05, "huber")]
    plain_clean = outlier_study[(0.0, "none")].position_rms
    plain_gross = outlier_study[(0.05, "none")]
    assert huber_gross.outliers_injected > 15
    assert huber_gross.outliers_downweighted == huber_gross.outliers_injected
    assert plain_gross.outliers_downweighted == 0
    assert huber_gross.position_rms <= 1.2 * huber_clean
    assert plain_gross.position_rms > 2.0 * plain_clean
    assert huber_clean <= 1.1 * plain_clean  # the price of robustness on clean data is small


def test_modes_select_the_sensors():
    short = {"duration": 200.0, "approach_duration": 150.0}
    results = {
        mode: simulate_approach(approach(mode=mode, **short), 1.0, 2.0, robust="none", seed=0)
        for mode in ("cooperative", "non-cooperative", "semi-cooperative")
    }
    coop, non, semi = (results[m] for m in ("cooperative", "non-cooperative", "semi-cooperative"))
    assert coop.fixes == non.fixes == 200 and semi.fixes == 400
    # Only optical fixes can be gross errors: GNSS fixes stay clean even at rate 1.
    assert coop.outliers_injected == 0
    assert non.outliers_injected == 200 and semi.outliers_injected == 200
    assert coop.position_rms < 0.05


def test_semi_cooperative_beats_single_sensors():
    short = {"duration": 300.0, "approach_duration": 200.0}
    rms = {
        mode: simulate_approach(approach(mode=mode, **short), robust="none", seed=0).position_rms
        for mode in ("cooperative", "non-cooperative", "semi-cooperative")
    }
    assert rms["semi-cooperative"] < rms["cooperative"] < rms["non-cooperative"]


def test_bad_scenarios_and_options():
    with pytest.raises(ValueError, match="mode 'docking'"):
        approach(mode="docking")
    with pytest.raises(ValueError, match="unknown or no sensors"):
        approach(modes={"non-cooperative": ("radar",)})
    with pytest.raises(ValueError, match="settle"):
        approach(settle=700.0)
    with pytest.raises(ValueError, match="outlier rate"):
        simulate_approach(approach(), outlier_rate=1.5)
    with pytest.raises(ValueError, match="sigma"):
        PositionSensor("lidar", 0.0, 1.0, True)


# --------------------------------------------------------------------------- relative GNSS modes
ALMANAC = Path(__file__).resolve().parents[3] / "data" / "gnss" / "gps_week147_yuma.alm"


def rgnss_approach(mode: str, duration: float = 180.0, **rgnss) -> ApproachScenario:
    """The approach with raw-measurement relative GNSS, a lidar and its stereo backup."""
    sensor = RgnssSensor("rgnss", 1.0, parse_yuma(ALMANAC.read_text()), **rgnss)
    sensors = {
        "lidar": PositionSensor("lidar", 0.05, 1.0, True, backup="stereo",
                                outages=((100.0, 130.0),)),
        "stereo": PositionSensor("stereo", 0.10, 1.0, True),
        "rgnss": sensor,
    }  # fmt: skip
    modes = {"cooperative": ("rgnss",), "non-cooperative": ("lidar",),
             "semi-cooperative": ("lidar", "rgnss")}  # fmt: skip
    start = sensor.almanac.toa[0] + 3600.0
    return approach(sensors=sensors, modes=modes, mode=mode, duration=duration,
                    approach_duration=0.6 * duration, gnss_start=start)  # fmt: skip


@pytest.fixture(scope="module")
def paired_modes():
    return {
        (mode, seed): simulate_approach(rgnss_approach(mode), seed=seed)
        for mode in ("cooperative", "non-cooperative", "semi-cooperative")
        for seed in (0, 1)
    }


def test_cooperative_mode_fixes_ambiguities(paired_modes):
    for seed in (0, 1):
        coop = paired_modes[("cooperative", seed)]
        s = coop.summary()
        assert s["time_to_first_fix_s"] is not None and s["time_to_first_fix_s"] <= 60.0
        assert s["ambiguity_fix_rate"] > 0.7 and s["wrong_fix_rate"] == 0.0
        assert coop.gnss_epochs == 180
        assert coop.position_rms < 0.01  # fixed carrier phase: mm level
        assert set(s["mode_time_fractions"]) <= {"imu-only", "rgnss-code", "rgnss-fixed"}
        assert s["mode_time_fractions"]["rgnss-fixed"] > 0.7
        assert 3.0 < coop.nees_mean < 10.0


def test_non_cooperative_backup_covers_the_lidar_outage(paired_modes):
    non = paired_modes[("non-cooperative", 0)]
    fractions = non.summary()["mode_time_fractions"]
    assert fractions["stereo"] == pytest.approx(30.0 / 180.0, abs=0.01)
    assert non.summary()["ambiguity_fix_rate"] is None
    outage = (non.times > 101) & (non.times < 130)
    assert set(non.modes[outage]) == {"stereo"}
    assert non.fixes == 180  # every second a fix: lidar or, in the outage, stereo


def test_semi_cooperative_is_no_worse_than_the_better_single_sensor(paired_modes):
    for seed in (0, 1):
        semi, coop, non = (
            paired_modes[(m, seed)].position_rms
            for m in ("semi-cooperative", "cooperative", "non-cooperative")
        )
        assert semi <= 1.02 * min(coop, non)


def test_navigator_carries_on_with_fewer_than_five_common_satellites():
    obstructed = ReceiverModel(obstructions=((135.0, 165.0, np.radians(75.0)),))
    semi, coop = (
        simulate_approach(rgnss_approach(mode, 220.0, chaser_receiver=obstructed), seed=2)
        for mode in ("semi-cooperative", "cooperative")
    )
    window = (semi.times > 137) & (semi.times < 165)
    assert set(semi.modes[window]) == {"lidar"}  # RGNSS reports no fix, the lidar carries on
    assert set(coop.modes[window]) == {"imu-only"}
    assert semi.modes[-1] == "lidar+rgnss-fixed" and coop.modes[-1] == "rgnss-fixed"
    # With the lidar the error stays at its level; on the IMU alone it grows but is bounded.
    assert np.max(np.linalg.norm(semi.errors[window, :3], axis=1)) < 0.1
    assert np.max(np.linalg.norm(coop.errors[window, :3], axis=1)) < 1.0
    assert semi.gnss_wrong == coop.gnss_wrong == 0
