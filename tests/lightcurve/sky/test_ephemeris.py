"""Heliocentric two-body orbits and asteroid observing geometry (lightcurve.sky.ephemeris)."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lightcurve.sky.ephemeris import (
    AU_KM,
    ITOKAWA_APPARITIONS,
    ITOKAWA_ORBIT,
    HeliocentricOrbit,
    asteroid_geometry,
    earth_heliocentric,
    hg_magnitude,
    itokawa_geometry,
    nightly_epochs,
)

J2000_MJD = 51544.5
#: The Earth–Moon barycentre's mean elements at J2000 (Standish 1992, "Keplerian elements
#: for approximate positions of the major planets", table 1): a, e, i, Ω, ϖ, L.
EARTH_MEAN_ELEMENTS = (1.00000261, 0.01671123, -0.00001531, 0.0, 102.93768193, 100.46457166)


def test_earth_mean_elements_reproduce_astropy_earth():
    """Keplerian motion from Standish's mean elements stays within 1e-3 AU of astropy's
    Earth over 2000–2010 (measured 4.3e-4 AU: the Moon's pull on the Earth, 4700 km, and
    the neglected element rates)."""
    a, e, i, node, varpi, longitude = EARTH_MEAN_ELEMENTS
    orbit = HeliocentricOrbit(a, e, i, node, varpi - node, longitude - varpi, J2000_MJD)
    mjd = np.linspace(J2000_MJD, J2000_MJD + 3652.5, 200)
    error = np.linalg.norm(orbit.position(mjd) - earth_heliocentric(mjd), axis=1)
    assert error.max() < 1e-3 * AU_KM
    assert orbit.period_days == pytest.approx(365.256, abs=0.01)


@settings(max_examples=30, deadline=None)
@given(
    a=st.floats(0.5, 5.0),
    e=st.floats(0.0, 0.9),
    i=st.floats(0.0, 179.5),
    node=st.floats(0.0, 359.0),
    peri=st.floats(0.0, 359.0),
    mean=st.floats(0.0, 359.0),
    dt=st.floats(-2000.0, 2000.0),
)
def test_state_to_elements_round_trip(a, e, i, node, peri, mean, dt):
    """Elements → state at another epoch → elements describe the same orbit; Kepler's
    equation holds; the velocity is the derivative of the position; energy is conserved."""
    orbit = HeliocentricOrbit(a, e, i, node, peri, mean, J2000_MJD)
    t = np.array([J2000_MJD + dt])
    anomaly = float(orbit.eccentric_anomaly(t)[0])
    m = math.radians(mean) + orbit.mean_motion * dt * 86400.0
    assert math.remainder(anomaly - e * math.sin(anomaly) - m, 2 * math.pi) == (
        pytest.approx(0.0, abs=1e-12)
    )
    r, v = orbit.position(t)[0], orbit.velocity(t)[0]
    again = HeliocentricOrbit.from_state(r, v, float(t[0]))
    later = np.array([J2000_MJD + dt + 123.4])
    scale = a * AU_KM
    assert np.linalg.norm(again.position(later) - orbit.position(later)) < 1e-8 * scale
    h = 1e-4  # day
    numeric = (orbit.position(t + h) - orbit.position(t - h)) / (2 * h * 86400.0)
    assert np.linalg.norm(numeric[0] - v) < 1e-6 * np.linalg.norm(v)
    assert again.semi_major_axis_au == pytest.approx(a, rel=1e-10)
    assert again.eccentricity == pytest.approx(e, abs=1e-10)


def test_orbit_errors():
    with pytest.raises(ValueError, match="eccentricity"):
        HeliocentricOrbit(1.0, 1.2, 0, 0, 0, 0, J2000_MJD)
    with pytest.raises(ValueError, match="semi-major"):
        HeliocentricOrbit(-1.0, 0.1, 0, 0, 0, 0, J2000_MJD)
    with pytest.raises(ValueError, match="bound"):
        HeliocentricOrbit.from_state(np.array([AU_KM, 0, 0]), np.array([0, 60.0, 0]), 0.0)


def test_hg_magnitude_at_opposition_and_with_phase():
    assert hg_magnitude(15.0, 0.15, 2.0, 1.0, 0.0) == pytest.approx(15.0 + 5 * math.log10(2.0))
    # Fainter with phase; the steeper G = 0 law fades faster than G = 0.5.
    v = hg_magnitude(15.0, np.array([0.0, 0.5]), 1.0, 1.0, math.radians(20.0))
    assert v[0] > v[1] > 15.0


def test_itokawa_apparitions_2001_and_2004():
    """The 2004 approach passes within 0.02 AU (0.0133 AU on 2004 June 26); the Earth is
    then seen from Itokawa far above its equator (its pole is near the ecliptic south pole),
    while in 2001 it is below: the two apparitions see opposite hemispheres."""
    epochs = nightly_epochs(ITOKAWA_APPARITIONS, every_days=5.0, hours=2.0, cadence_minutes=30.0)
    assert np.all(np.diff(epochs) > 0) and len(epochs) == 4 * (16 + 48)
    geometry = itokawa_geometry(epochs)
    table = geometry.table
    observer = table[["obs_x", "obs_y", "obs_z"]].to_numpy()
    sun = table[["sun_x", "sun_y", "sun_z"]].to_numpy()
    distance = np.linalg.norm(observer, axis=1)
    latitude = np.degrees(np.arcsin(observer[:, 2] / distance))
    phase = np.degrees(
        np.arccos(np.sum(observer * sun, axis=1) / (distance * np.linalg.norm(sun, axis=1)))
    )
    assert table["v_predicted"].max() <= 18.0 and phase.max() <= 90.0
    in_2001 = table["mjd"].to_numpy() < 52500
    assert in_2001.any() and (~in_2001).any()
    assert distance.min() < 0.02 * AU_KM
    assert latitude[~in_2001].max() > 30.0 and latitude[in_2001].min() < -15.0
    assert table["lightcurve_id"].nunique() == len(np.unique(np.floor(table["mjd"])))
    with pytest.raises(ValueError, match="needs absolute_magnitude"):
        asteroid_geometry(ITOKAWA_ORBIT, epochs, max_magnitude=18.0)
    with pytest.raises(ValueError, match="no epoch of itokawa"):
        asteroid_geometry(
            ITOKAWA_ORBIT, epochs, name="itokawa", absolute_magnitude=19.2, max_magnitude=5.0
        )
