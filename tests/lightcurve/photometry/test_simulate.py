"""Simulation: truth propagation, noise models, round trips and the simulate command."""

import numpy as np
import pandas as pd
import pytest

from filters.attitude import attitude_angle, axisymmetric_solution
from lightcurve import io
from lightcurve.cli import main
from lightcurve.io.observations import TRUTH_COLUMNS
from lightcurve.photometry.render import Renderer
from lightcurve.photometry.simulate import CCDNoise, GaussianNoise, simulate
from lightcurve.sky.ephemeris import CircularOrbit, Site, orbit_geometry, sun_position
from lightcurve.sky.geometry import phase_angle
from shapes import get_library
from tests.lightcurve._round_trip import assert_csv_parquet_round_trip

MOUNT_LEMMON = Site(32.4434, -110.7881, 2790.0, "Mount Lemmon")


@pytest.fixture(scope="module")
def geometry():
    mjd = 60379.2 + np.arange(0.0, 600.0, 2.0) / 86400.0  # 2024-03-10 04:48 UTC, night
    return orbit_geometry(CircularOrbit.geostationary(-100.0, mjd[0]), MOUNT_LEMMON, mjd, "geo")


def test_geometry_is_physical(geometry):
    sun_range = np.linalg.norm(geometry.sun_vectors, axis=1)
    assert np.all(np.abs(sun_range / 1.496e11 - 1) < 0.02)
    obs_range = np.linalg.norm(geometry.observer_vectors, axis=1)
    assert np.all((obs_range > 3.5e7) & (obs_range < 4.2e7))  # GEO slant ranges
    alpha = np.rad2deg(phase_angle(geometry.sun_vectors, geometry.observer_vectors))
    assert np.all((alpha > 0) & (alpha < 180))
    # The Sun's geocentric direction in March is near the vernal equinox (RA ≈ 0).
    sun = sun_position(np.array([60379.5]))[0]
    assert abs(np.degrees(np.arctan2(sun[1], sun[0]))) < 15


def test_simulation_truth_and_noise(geometry):
    shape = get_library().load("box")
    q0 = np.array([0.1, 0.2, 0.3, 0.927])
    q0 /= np.linalg.norm(q0)
    w0 = np.deg2rad([0.5, -1.0, 2.0])
    exact = simulate(geometry, shape, q0=q0, omega0=w0)
    noisy = simulate(geometry, shape, q0=q0, omega0=w0, noise=GaussianNoise(0.05), seed=3)
    again = simulate(geometry, shape, q0=q0, omega0=w0, noise=GaussianNoise(0.05), seed=3)
    pd.testing.assert_frame_equal(noisy.table, again.table)
    residual = noisy.magnitudes - exact.magnitudes
    assert abs(residual.std() - 0.05) < 0.01 and abs(residual.mean()) < 0.01
    truth = exact.truth
    renderer = Renderer(shape)
    np.testing.assert_allclose(
        renderer.magnitude(truth[:, :4], exact.sun_vectors, exact.observer_vectors),
        exact.magnitudes,
        atol=1e-12,
    )
    np.testing.assert_allclose(truth[0, :4], q0, atol=1e-15)
    np.testing.assert_allclose(truth[0, 4:], w0, atol=1e-15)
    assert noisy.meta["noise"] == "gaussian sigma=0.05 mag"


def test_axisymmetric_truth_matches_closed_form(geometry):
    """Simulated truth for an axisymmetric inertia follows the exact torque-free solution."""
    shape = get_library().load("cylinder")
    inertia = np.diag([2.0, 2.0, 1.0])
    q0, w0 = np.array([0.0, 0.0, 0.0, 1.0]), np.array([0.01, 0.0, 0.03])
    truth = simulate(geometry, shape, q0=q0, omega0=w0, inertia=inertia).truth
    q_exact, w_exact = axisymmetric_solution(q0, w0, 2.0, 1.0, geometry.times)
    assert np.max(attitude_angle(truth[:, :4], q_exact)) < 1e-8
    np.testing.assert_allclose(truth[:, 4:], w_exact, atol=1e-10)


def test_ccd_noise_statistics():
    ccd = CCDNoise(aperture_m=0.5, exposure_s=2.0, read_noise_e=5.0)
    rng = np.random.default_rng(4)
    magnitude = np.full(20000, 12.0)
    measured, error = ccd.apply(magnitude, None, rng)
    # The spread of measured magnitudes matches the reported 1σ errors (CCD equation).
    assert np.std(measured) == pytest.approx(np.median(error), rel=0.05)
    assert abs(np.mean(measured) - 12.0) < 3 * np.std(measured) / np.sqrt(20000) + 1e-4
    _, faint_err = ccd.apply(np.full(2000, 22.0), None, rng)
    assert np.nanmedian(faint_err) > 10 * np.median(error)
    with pytest.raises(ValueError, match="aperture_m"):
        CCDNoise(aperture_m=-1.0)


def test_round_trip_of_simulated_file(tmp_path, geometry):
    shape = get_library().load("box_wing")
    sim = simulate(
        geometry,
        shape,
        q0=[0, 0, 0, 1],
        omega0=np.deg2rad([0.3, 0.2, -0.4]),
        noise=GaussianNoise(0.02),
        seed=1,
    )
    again = assert_csv_parquet_round_trip(sim, tmp_path)
    assert all(c in again.table for c in TRUTH_COLUMNS)


def test_simulate_command(tmp_path, capsys):
    geo = tmp_path / "geo.csv"
    out = tmp_path / "sim.parquet"
    assert (
        main(
            [
                "geometry",
                "--start",
                "2024-03-10T04:48:00",
                "--duration",
                "300",
                "--cadence",
                "5",
                "--geo",
                "-100",
                "--name",
                "demo",
                "--out",
                str(geo),
            ]
        )
        == 0
    )
    assert (
        main(
            [
                "simulate",
                str(geo),
                "--shape",
                "box_wing",
                "--q0",
                "0,0,0,1",
                "--omega0",
                "0.5,1,-0.3",
                "--ccd",
                "aperture_m=0.4",
                "exposure_s=1",
                "--seed",
                "2",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    sim = io.read(out)
    assert sim.has_truth and len(sim) == 60
    assert sim.meta["noise"].startswith("ccd aperture_m=0.4")
    assert (
        main(
            [
                "simulate",
                str(geo),
                "--shape",
                "nope",
                "--q0",
                "0,0,0,1",
                "--omega0",
                "0,0,1",
                "--out",
                str(out),
            ]
        )
        == 2
    )
    assert "nope" in capsys.readouterr().err


def test_truth_states_match_the_attitude_core_propagator():
    """The compiled right-hand side gives the attitude core's DOP853 states (full inertia)."""
    from filters.attitude import propagate
    from lightcurve.photometry.simulate import truth_states

    inertia = np.array([[1.0, 0.05, 0.0], [0.05, 1.3, 0.02], [0.0, 0.02, 1.7]])
    q0 = np.array([0.2, -0.4, 0.1, 0.888819])
    omega0 = np.deg2rad([1.5, -0.8, 2.2])
    times = np.linspace(0.0, 600.0, 301)
    ours = truth_states(times, q0, omega0, inertia)
    core = propagate(np.concatenate([q0 / np.linalg.norm(q0), omega0]), times, inertia)
    np.testing.assert_allclose(ours, core, rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match="strictly increasing"):
        truth_states(times[::-1], q0, omega0, inertia)


def test_library_load_without_visibility_table():
    library = get_library()
    full = library.load("itokawa")
    bare = library.load("itokawa", visibility=False)
    assert full.visibility is not None and bare.visibility is None
    np.testing.assert_array_equal(bare.facet_can_be_shadowed, full.facet_can_be_shadowed)
