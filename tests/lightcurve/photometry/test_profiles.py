"""Attitude profiles, object-position columns, `simulate --profile` and mode identification."""

import math

import numpy as np
import pandas as pd
import pytest

from filters.attitude import attitude_angle, attitude_matrix
from lightcurve import io
from lightcurve.attitude_modes import TUMBLING, identify_attitude_mode
from lightcurve.cli import main
from lightcurve.inversion import batch_problem, shape_symmetry
from lightcurve.io.observations import ObservationError, validate_table
from lightcurve.photometry.measurement import PhotometricModel
from lightcurve.photometry.profiles import (
    body_rates,
    euler_offsets_deg,
    offset_quaternion,
    profile_attitude,
)
from lightcurve.photometry.simulate import GaussianNoise, simulate, truth_states
from lightcurve.sky.ephemeris import CircularOrbit, Site, orbit_geometry
from shapes import get_library

MOUNT_LEMMON = Site(32.4434, -110.7881, 2790.0, "Mount Lemmon")


@pytest.fixture(scope="module")
def night():
    """A GEO slot over one night of 2024 January, every 10 min."""
    mjd = 60324.0 + np.arange(0.0, 15 * 3600.0, 600.0) / 86400.0
    orbit = CircularOrbit.geostationary(-100.0, mjd[0])
    return orbit_geometry(orbit, MOUNT_LEMMON, mjd, "geo")


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def test_circular_orbit_velocity_is_the_derivative_of_the_position():
    orbit = CircularOrbit(7000.0, 51.6, 40.0, 10.0, 60000.0)
    mjd = 60000.0 + np.array([0.0, 1000.0, 5000.0]) / 86400.0
    h = 0.5 / 86400.0
    numeric = (orbit.position(mjd + h) - orbit.position(mjd - h)) / 1.0
    # MJD rounding (10⁻¹¹ day) limits the central difference over 1 s to ~10⁻⁶.
    assert np.allclose(orbit.velocity(mjd), numeric, rtol=1e-5)
    assert np.allclose(np.linalg.norm(orbit.velocity(mjd), axis=1), 7000.0 * orbit.mean_motion)


def test_geometry_writes_object_position_and_velocity(night):
    position = night.object_positions / 1e3
    assert np.allclose(np.linalg.norm(position, axis=1), 42164.17, rtol=1e-9)
    speed = np.linalg.norm(night.object_velocities, axis=1) / 1e3
    assert np.allclose(speed, 3.0747, atol=1e-3)  # GEO speed, km/s
    # The observer vector is the site minus the object: the site is on the Earth.
    site = position + night.observer_vectors / 1e3
    assert np.all(np.abs(np.linalg.norm(site, axis=1) - 6373.0) < 15.0)


def test_object_columns_are_validated(night):
    table = night.table
    with pytest.raises(ObservationError, match=r"'obj_vz'.*go together"):
        validate_table(table.drop(columns="obj_vz"), "f.csv", require_magnitudes=False)
    metres = table.assign(obj_vx=table["obj_vx"] * 1e3)
    with pytest.raises(ObservationError, match=r"f.csv, row 1, column 'obj_vx'.*m/s given"):
        validate_table(metres, "f.csv", require_magnitudes=False)
    metres = table.assign(obj_x=table["obj_x"] * 1e3)
    with pytest.raises(ObservationError, match=r"column 'obj_x'.*geocentric"):
        validate_table(metres, "f.csv", require_magnitudes=False)
    bad = table.assign(obj_y=table["obj_y"].astype(object))
    bad.loc[3, "obj_y"] = "inf"
    with pytest.raises(ObservationError, match=r"row 4, column 'obj_y'.*not finite"):
        validate_table(bad, "f.csv", require_magnitudes=False)
    no_position = table.drop(columns=["obj_x", "obj_y", "obj_z"])
    with pytest.raises(ObservationError, match="velocity columns without the position"):
        validate_table(no_position, "f.csv", require_magnitudes=False)


def test_profile_axes(night):
    r, v, s = night.object_positions, night.object_velocities, night.sun_vectors
    nadir = attitude_matrix(profile_attitude("nadir", position=r, velocity=v))
    assert np.allclose(np.einsum("nij,nj->ni", nadir, _unit(-r)), [0, 0, 1], atol=1e-12)
    assert np.allclose(np.einsum("nij,nj->ni", nadir, _unit(v)), [1, 0, 0], atol=1e-12)
    steered = attitude_matrix(
        profile_attitude("nadir", position=r, velocity=v, sun=s, yaw_steering=True)
    )
    sun_body = np.einsum("nij,nj->ni", steered, _unit(s))
    assert np.allclose(sun_body[:, 1], 0.0, atol=1e-12) and np.all(sun_body[:, 0] > 0)
    assert np.allclose(np.einsum("nij,nj->ni", steered, _unit(-r)), [0, 0, 1], atol=1e-12)
    sun = attitude_matrix(profile_attitude("sun-pointing", sun=s))
    assert np.allclose(np.einsum("nij,nj->ni", sun, _unit(s)), [0, 0, 1], atol=1e-12)
    pole = sun @ np.array([0.0, 0.0, 1.0])
    assert np.allclose(pole[:, 1], 0.0, atol=1e-12) and np.all(pole[:, 0] > 0)


def test_offset_composes_on_the_body_side(night):
    r, v = night.object_positions, night.object_velocities
    offset = np.array([4.0, -7.0, 9.0])
    q_off = offset_quaternion(offset)
    assert np.allclose(euler_offsets_deg(q_off), offset)
    plain = profile_attitude("nadir", position=r, velocity=v)
    turned = profile_attitude("nadir", position=r, velocity=v, offset=q_off)
    expected = attitude_matrix(q_off) @ attitude_matrix(plain)
    assert np.allclose(attitude_matrix(turned), expected, atol=1e-12)
    # Roll alone turns about the body x axis: x stays along the velocity.
    rolled = profile_attitude("nadir", position=r, velocity=v, offset=offset_quaternion([5, 0, 0]))
    assert np.allclose(attitude_matrix(rolled)[0] @ _unit(v)[0], [1, 0, 0], atol=1e-12)


def test_body_rates_match_the_torque_free_integration():
    times = np.arange(0.0, 20.0, 0.05)
    inertia = np.diag([3.0, 4.0, 5.0])
    states = truth_states(times, [0.1, 0.2, 0.3, 0.927], np.radians([2.0, -1.0, 3.0]), inertia)
    rates = body_rates(times, states[:, :4])
    assert np.max(np.abs(rates[1:-1] - states[1:-1, 4:])) < 1e-6  # rad/s; ω̇Δt² scale


def test_nadir_rates_are_the_orbit_rate(night):
    q = profile_attitude("nadir", position=night.object_positions, velocity=night.object_velocities)
    rates = body_rates(night.times, q)
    n = CircularOrbit(42164.17).mean_motion
    # LVLH turns once per orbit about the orbit normal, the body's −y axis.
    assert np.allclose(rates, [0.0, -n, 0.0], atol=1e-9)


def test_simulate_profile_command(tmp_path, night):
    geometry = tmp_path / "g.csv"
    io.write(night, geometry)
    out = tmp_path / "s.csv"
    args = ["simulate", str(geometry), "--shape", "box_wing", "--out", str(out)]
    assert main([*args, "--profile", "inertial", "--offset-deg", "0,0,30"]) == 0
    table = io.read(out).table
    q = table[["q1", "q2", "q3", "q4"]].to_numpy()
    assert np.allclose(q, offset_quaternion([0, 0, 30]), atol=1e-12)
    assert np.allclose(table[["wx", "wy", "wz"]].to_numpy(), 0.0, atol=1e-15)
    assert main([*args, "--profile", "nadir", "--yaw-steering", "--seed", "3"]) == 0
    meta = io.read(out).meta
    assert meta["profile"] == "nadir yaw-steering" and meta["offset_deg"] == "0,0,0"
    # Today's default is unchanged: torque-free from --q0/--omega0.
    assert main([*args, "--q0", "0,0,0,1", "--omega0", "0,0,1"]) == 0
    assert "profile" not in io.read(out).meta


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--profile", "nadir", "--omega0", "0,0,1"], "--omega0 does not apply"),
        (["--profile", "sun-pointing", "--yaw-steering"], "--yaw-steering applies"),
        (["--q0", "0,0,0,1"], "needs --q0 and --omega0"),
        (["--profile", "nadir"], "nadir profile needs the object's position"),
    ],
)
def test_simulate_profile_errors(tmp_path, night, capsys, extra, message):
    geometry = tmp_path / "g.csv"
    io.write(night, geometry)
    if "nadir profile needs" in message:
        table = night.table.drop(columns=["obj_x", "obj_y", "obj_z", "obj_vx", "obj_vy", "obj_vz"])
        pd.DataFrame(table).to_csv(geometry, index=False)
    args = ["simulate", str(geometry), "--shape", "box", "--out", str(tmp_path / "s.csv")]
    assert main([*args, *extra]) != 0
    assert message in capsys.readouterr().err


def _model(observations, shape):
    return PhotometricModel(observations, {shape.name: shape})


def test_mode_identification_tells_stabilised_from_tumbling(night):
    """A nadir box-wing with a few degrees of offset and a box-wing tumbling at 1°/s, one
    night at 10-min cadence: each called right at p ≥ 0.9, the offset recovered."""
    shape = get_library().load("box_wing")
    order = shape_symmetry(shape).order
    position, velocity = night.object_positions, night.object_velocities
    offset = np.array([3.0, -4.0, 6.0])
    stabilised = simulate(
        night,
        shape,
        noise=GaussianNoise(0.03),
        seed=1,
        profile="nadir",
        offset_deg=offset,
    )
    q0, omega0 = np.array([0.3, -0.5, 0.1, 0.806]), np.radians([0.6, -0.5, 0.6])
    tumbling = simulate(night, shape, q0=q0, omega0=omega0, noise=GaussianNoise(0.03), seed=2)
    found = {}
    for name, obs, start in (
        ("stabilised", stabilised, stabilised.truth[0]),
        ("tumbling", tumbling, tumbling.truth[0]),
    ):
        model = _model(obs, shape)
        keep = np.isin(night.mjd, obs.mjd)
        found[name] = identify_attitude_mode(
            model,
            batch_problem(model),
            {0: [(start[:4], start[4:], 0.0)]},  # as if the tumbling search found it
            [order],
            position=position[keep],
            velocity=velocity[keep],
            search_candidates=512,
        )
    calm, spinning = found["stabilised"], found["tumbling"]
    assert calm.mode == "nadir" and calm.probability >= 0.9 and not calm.none_fits
    error = attitude_angle(offset_quaternion(calm.offsets_deg), offset_quaternion(offset))
    assert math.degrees(error) < 2.0
    keys = calm.summary()
    assert len(keys["attitude_offset_sigma_deg"]) == 3
    for weak in keys["attitude_offset_weak_axes"]:  # each interval holds the fitted point
        assert weak["sigma_deg"] > 1.0 and weak["interval_deg"][0] <= 0 <= weak["interval_deg"][1]
    # The sampled posterior's 95 % intervals hold the true offset.
    bounds = np.asarray(keys["attitude_offset_intervals_deg"]["95"])
    assert np.all((bounds[:, 0] <= offset) & (offset <= bounds[:, 1])), bounds
    assert keys["attitude_offset_posterior"]["samples"] >= 32 * 400
    assert spinning.mode == TUMBLING and spinning.probability >= 0.9
    summary = spinning.summary()
    assert summary["attitude_mode"] == TUMBLING and summary["attitude_offsets_deg"] is None
    # Every profile fails the consistency test on the tumbling light curve.
    assert not any(h.consistent for h in spinning.hypotheses if h.mode != TUMBLING)


def test_yaw_steering_needs_no_velocity():
    """Yaw-steered, the attitude depends on the position and the Sun only: the same with or
    without the velocity; without yaw steering the velocity stays required."""
    from lightcurve.photometry.profiles import nadir_attitude

    rng = np.random.default_rng(4)
    position = rng.normal(size=(50, 3)) * 7e6
    velocity = rng.normal(size=(50, 3)) * 7e3
    sun = rng.normal(size=(50, 3))
    with_velocity = nadir_attitude(position, velocity, sun, yaw_steering=True)
    without = nadir_attitude(position, None, sun, yaw_steering=True)
    assert np.max(np.degrees(attitude_angle(with_velocity, without))) < 1e-9
    with pytest.raises(ValueError, match="needs the velocity unless it is yaw-steered"):
        nadir_attitude(position, None, sun)
