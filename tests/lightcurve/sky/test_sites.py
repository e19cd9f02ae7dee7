"""Observatory sites and horizon coordinates (elevation, azimuth, range, height, airmass)."""

import numpy as np
import pytest

from lightcurve.sky.frames import astropy_offline
from lightcurve.sky.sites import Site, get_site, load_sites, site_itrs
from lightcurve.sky.topocentric import (
    airmass,
    horizontal_from_itrs,
    itrs_from_horizontal,
    range_from_height,
)


@pytest.fixture(scope="module")
def u():
    """``astropy.units`` with IERS downloads off, imported only where a test compares with it."""
    return astropy_offline()


REQUIRED = (
    "Mount Lemmon",
    "Haleakala",
    "Kislovodsk",
    "Modra",
    "Zimmerwald",
    "Graz",
    "Siding Spring",
    "La Palma",
)


def test_required_observatories_with_plausible_coordinates():
    names = {site.name for site in load_sites().values()}
    assert set(REQUIRED) <= names
    lemmon = get_site("mount lemmon")
    assert (lemmon.latitude_deg, lemmon.longitude_deg, lemmon.altitude_m) == (
        32.4434,
        -110.7881,
        2790.0,
    )
    # Aliases, case, spaces and punctuation.
    assert get_site("Maui") == get_site("HALEAKALA") == get_site("haleakala-amos")
    assert get_site("Roque de los Muchachos").name == "La Palma"
    assert get_site("Siding-Spring").latitude_deg < 0
    # Mountain sites are high, and every site is on the ground.
    assert get_site("Kislovodsk").altitude_m > 2000 and get_site("La Palma").altitude_m > 2200
    for site in load_sites().values():
        assert 6355 < np.linalg.norm(site_itrs(site)) < 6385


def test_site_specifications_and_errors():
    site = get_site(" 32.4434, -110.7881, 2790 ")
    assert site == Site(32.4434, -110.7881, 2790.0)
    with pytest.raises(ValueError, match="did you mean 'Zimmerwald'"):
        get_site("Zimerwald")
    with pytest.raises(ValueError, match="known sites: Graz, Haleakala"):
        get_site("Nowhere")
    with pytest.raises(ValueError, match="latitude must be in"):
        get_site("95,0,0")
    with pytest.raises(ValueError, match="not on the ground"):
        get_site("30,10,20000")


def test_site_position_matches_astropy_wgs84(u):
    from astropy.coordinates import EarthLocation

    site = get_site("Zimmerwald")
    location = EarthLocation.from_geodetic(
        site.longitude_deg * u.deg, site.latitude_deg * u.deg, site.altitude_m * u.m
    )
    expected = np.array([c.to_value(u.km) for c in location.geocentric])
    np.testing.assert_allclose(site_itrs(site), expected, atol=1e-9)


def test_horizontal_coordinates_match_astropy_altaz(u):
    """Against astropy's topocentric ITRS → AltAz (geometric, no refraction)."""
    from astropy.coordinates import ITRS, AltAz, CartesianRepresentation, EarthLocation
    from astropy.time import Time

    site = get_site("Siding Spring")
    rng = np.random.default_rng(4)
    vectors = rng.normal(size=(50, 3)) * 2000.0
    elevation, azimuth, distance = horizontal_from_itrs(site, vectors)
    location = EarthLocation.from_geodetic(
        site.longitude_deg * u.deg, site.latitude_deg * u.deg, site.altitude_m * u.m
    )
    t = Time(60000.0, format="mjd", scale="utc")
    topocentric = ITRS(CartesianRepresentation(vectors.T * u.km), obstime=t, location=location)
    altaz = topocentric.transform_to(AltAz(obstime=t, location=location))
    np.testing.assert_allclose(elevation, altaz.alt.deg, atol=1e-9)
    np.testing.assert_allclose(azimuth, altaz.az.deg, atol=1e-9)
    np.testing.assert_allclose(distance, altaz.distance.to_value(u.km), rtol=1e-12)
    back = itrs_from_horizontal(site, elevation, azimuth, distance)
    np.testing.assert_allclose(back, vectors, atol=1e-8)


def test_range_from_height_lands_on_the_height():
    import erfa

    site = get_site("Haleakala")
    elevation = np.array([5.0, 20.0, 45.0, 89.9])
    azimuth = np.array([10.0, 100.0, 200.0, 300.0])
    height = np.array([400.0, 550.0, 1200.0, 35786.0])
    distance = range_from_height(site, elevation, azimuth, height)
    point = site_itrs(site) + itrs_from_horizontal(site, elevation, azimuth, distance)
    np.testing.assert_allclose(erfa.gc2gd(1, point * 1000.0)[2] / 1000.0, height, atol=1e-9)
    # Straight up: the range is the height difference.
    up = range_from_height(site, np.array([90.0]), np.array([0.0]), np.array([500.0]))
    assert up[0] == pytest.approx(500.0 - site.altitude_m / 1000.0, abs=1e-9)


def test_airmass_kasten_young():
    """Close to the plane-parallel sec z high in the sky and a little below it (the curved
    atmosphere: 0.3 % at 30° elevation), about 38 at the horizon (Kasten & Young 1989),
    increasing toward the horizon, undefined below it."""
    elevation = np.array([90.0, 60.0, 45.0, 30.0])
    secant = 1 / np.sin(np.radians(elevation))
    np.testing.assert_allclose(airmass(elevation), secant, rtol=3.5e-3)
    assert np.all(airmass(elevation[1:]) < secant[1:])
    low = airmass(np.linspace(0.0, 30.0, 301))
    assert np.all(np.diff(low) < 0) and 37.0 < low[0] < 39.0
    assert np.isnan(airmass(np.array([-1.0]))[0])
