"""TEME/ITRS/GCRS rotations on the node grid against astropy's own transformations."""

import numpy as np
import pytest

from lightcurve.sky.ephemeris import Site, _sun_astropy, site_position, sun_position
from lightcurve.sky.frames import astropy_offline, frame_rotations, interpolate_at_nodes, rotation_z


@pytest.fixture(scope="module")
def u():
    """``astropy.units`` with IERS downloads off, imported only where a test compares with it."""
    return astropy_offline()


@pytest.fixture(scope="module")
def epochs() -> np.ndarray:
    # 200 epochs over three days (nodes interpolated) plus a leap-second day (2016-12-31).
    rng = np.random.default_rng(5)
    return np.sort(np.r_[58000 + rng.uniform(0, 3, 200), 57753 + rng.uniform(0, 2, 100)])


def _astropy(u, frame_from, frame_to, vectors, mjd):
    from astropy.coordinates import CartesianRepresentation
    from astropy.time import Time

    t = Time(mjd, format="mjd", scale="utc")
    source = frame_from(CartesianRepresentation(vectors.T * u.km), obstime=t)
    return source.transform_to(frame_to(obstime=t)).cartesian.xyz.to_value(u.km).T


def test_rotations_match_astropy_to_a_few_picoradians(epochs, u):
    from astropy.coordinates import GCRS, ITRS, TEME

    rng = np.random.default_rng(6)
    v = rng.normal(size=(len(epochs), 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    rotations = frame_rotations(epochs)
    for matrices, frames in (
        (rotations.teme_to_gcrs, (TEME, GCRS)),
        (rotations.teme_to_itrs, (TEME, ITRS)),
        (rotations.itrs_to_gcrs, (ITRS, GCRS)),
    ):
        ours = np.einsum("nij,nj->ni", matrices, v)
        assert np.abs(ours - _astropy(u, *frames, v, epochs)).max() < 1e-11
        np.testing.assert_allclose(
            matrices @ matrices.transpose(0, 2, 1), np.eye(3)[None].repeat(len(v), 0), atol=1e-12
        )


def test_few_epochs_are_evaluated_exactly():
    calls = []

    def evaluate(mjd):
        calls.append(mjd)
        return mjd**2

    mjd = np.array([60000.1, 60001.7])
    np.testing.assert_array_equal(interpolate_at_nodes(mjd, evaluate), mjd**2)
    np.testing.assert_array_equal(calls[0], mjd)


def test_interpolation_is_exact_for_cubics_and_lines():
    mjd = 60000 + np.linspace(0, 2, 500)
    cubic = interpolate_at_nodes(mjd, lambda t: (t - 60000) ** 3 - 2 * (t - 60000))
    np.testing.assert_allclose(cubic, (mjd - 60000) ** 3 - 2 * (mjd - 60000), atol=1e-9)
    # Linear interpolation reproduces a broken line with its kink on a node (6 h grid).
    line = interpolate_at_nodes(mjd, lambda t: np.abs(t - 60000.75), linear=True)
    np.testing.assert_allclose(line, np.abs(mjd - 60000.75), atol=1e-9)


def test_sun_and_site_positions(epochs, u):
    from astropy.coordinates import EarthLocation
    from astropy.time import Time

    sun = sun_position(epochs)
    assert np.linalg.norm(sun - _sun_astropy(epochs), axis=1).max() < 0.01  # km
    site = Site(32.4434, -110.7881, 2790.0)
    location = EarthLocation.from_geodetic(-110.7881 * u.deg, 32.4434 * u.deg, 2790.0 * u.m)
    reference = location.get_gcrs(Time(epochs, format="mjd", scale="utc"))
    reference = reference.cartesian.xyz.to_value(u.km).T
    assert np.linalg.norm(site_position(site, epochs) - reference, axis=1).max() < 1e-6


def test_rotation_z_turns_axes():
    r = rotation_z(np.array([np.pi / 2]))[0]
    np.testing.assert_allclose(r @ [1.0, 0.0, 0.0], [0.0, -1.0, 0.0], atol=1e-15)
