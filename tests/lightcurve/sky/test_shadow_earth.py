"""Earth shadow: crossing times of a LEO eclipse against an independent cone geometry, and the
sunlit fraction in the penumbra."""

from pathlib import Path

import numpy as np
import pytest

from lightcurve.sky.ephemeris import _sun_astropy
from lightcurve.sky.shadow_earth import (
    EARTH_RADIUS_KM,
    SUN_RADIUS_KM,
    earth_shadow,
    shadow_events,
)
from lightcurve.sky.tle import read_tles, select_object

CATALOGUE = Path(__file__).resolve().parents[3] / "data" / "tle" / "catalogue.tle"
STEP_S = 10.0


@pytest.fixture(scope="module")
def eclipse():
    """GRACE-FO 2 (polar LEO, January 2020): skyfield's GCRS positions and astropy's Sun."""
    from skyfield.api import EarthSatellite, load

    tle = select_object(read_tles(CATALOGUE), 43477)[0]
    ts = load.timescale(builtin=True)
    satellite = EarthSatellite(tle.line1, tle.line2, ts=ts)

    def positions(mjd):
        whole = np.floor(mjd)
        t = ts.utc(1858, 11, 17 + whole, 0, 0, (mjd - whole) * 86400.0)
        return satellite.at(t).position.km.T, _sun_astropy(mjd)

    start = tle.epoch_mjd + 3000 / 86400.0  # the eclipse starts ~650 s later
    return start, positions


def _independent_crossings(inside, start, positions):
    """Times where ``inside(r, s)`` changes: a 10 s scan, then a 0.02 s scan around each."""
    coarse = start + np.arange(0.0, 3000.0, STEP_S) / 86400.0
    state = inside(*positions(coarse))
    times = []
    for k in np.flatnonzero(state[1:] != state[:-1]):
        fine = coarse[k] + np.arange(0.0, STEP_S + 0.02, 0.02) / 86400.0
        fine_state = inside(*positions(fine))
        j = np.flatnonzero(fine_state[1:] != fine_state[:-1])[0]
        times.append(0.5 * (fine[j] + fine[j + 1]))
    return np.array(times)


def _cylinder(r, s):
    s_hat = s / np.linalg.norm(s, axis=1, keepdims=True)
    along = np.sum(r * s_hat, axis=1)
    return (along < 0) & (np.linalg.norm(r - along[:, None] * s_hat, axis=1) < EARTH_RADIUS_KM)


def _cone(kind):
    """Inside the umbra cone (apex behind the Earth) or the penumbra cone (apex between the
    Earth and the Sun), from the common tangents of the two spheres."""

    def inside(r, s):
        distance = np.linalg.norm(s, axis=1)
        s_hat = s / distance[:, None]
        along = np.sum(r * s_hat, axis=1)  # toward the Sun
        perpendicular = np.linalg.norm(r - along[:, None] * s_hat, axis=1)
        if kind == "umbra":
            apex = -distance * EARTH_RADIUS_KM / (SUN_RADIUS_KM - EARTH_RADIUS_KM)
            half_angle = np.arcsin((SUN_RADIUS_KM - EARTH_RADIUS_KM) / distance)
            return (along < 0) & (perpendicular < (along - apex) * np.tan(half_angle))
        apex = distance * EARTH_RADIUS_KM / (SUN_RADIUS_KM + EARTH_RADIUS_KM)
        half_angle = np.arcsin((SUN_RADIUS_KM + EARTH_RADIUS_KM) / distance)
        return (along < 0) & (perpendicular < (apex - along) * np.tan(half_angle))

    return inside


@pytest.mark.parametrize(
    ("model", "references"),
    [
        ("cylindrical", {"umbra": _cylinder}),
        ("conical", {"umbra": _cone("umbra"), "penumbra": _cone("penumbra")}),
    ],
)
def test_eclipse_entry_and_exit_within_a_second(eclipse, model, references):
    start, positions = eclipse
    mjd = start + np.arange(0.0, 3000.0, STEP_S) / 86400.0
    events = shadow_events(mjd, *positions(mjd), model=model)
    for boundary, inside in references.items():
        ours = np.array([e.mjd for e in events if e.boundary == boundary])
        entering = [e.entering for e in events if e.boundary == boundary]
        reference = _independent_crossings(inside, start, positions)
        assert len(ours) == len(reference) == 2 and entering == [True, False]
        assert np.abs(ours - reference).max() * 86400.0 < 1.0
    if model == "conical":
        kinds = [e.kind for e in events]
        assert kinds == ["penumbra entry", "umbra entry", "umbra exit", "penumbra exit"]


def test_sunlit_fraction_in_the_penumbra(eclipse):
    start, positions = eclipse
    mjd = start + np.arange(0.0, 3000.0, STEP_S) / 86400.0
    events = shadow_events(mjd, *positions(mjd))
    for first, second in ((events[0], events[1]), (events[2], events[3])):
        t = np.linspace(first.mjd, second.mjd, 400)
        shadow = earth_shadow(*positions(t))
        inner = shadow.state[3:-3]
        assert np.all(inner == "penumbra")
        fraction = shadow.sunlit_fraction
        assert np.all((fraction >= 0) & (fraction <= 1))
        step = np.diff(fraction)
        assert np.all(step <= 0) if first.entering else np.all(step >= 0)
        begin, end = (1.0, 0.0) if first.entering else (0.0, 1.0)
        assert fraction[0] == pytest.approx(begin, abs=0.02)
        assert fraction[-1] == pytest.approx(end, abs=0.02)


def test_sunlit_fraction_matches_a_grid_over_the_solar_disc():
    """Overlap of the discs against counting grid points of the Sun's disc outside the
    Earth's (the same planar discs, counted instead of integrated)."""
    rng = np.random.default_rng(3)
    sun = np.array([1.496e8, 0.0, 0.0])
    a = np.arcsin(SUN_RADIUS_KM / 1.496e8)
    for _ in range(5):
        radius = rng.uniform(6800.0, 7200.0)
        b = np.arcsin(EARTH_RADIUS_KM / radius)
        c = rng.uniform(b - 0.9 * a, b + 0.9 * a)  # a separation inside the penumbra
        # Place the object so that the Sun–Earth separation seen from it is c.
        position = radius * np.array([-np.cos(c), np.sin(c), 0.0])
        shadow = earth_shadow(position[None], sun[None])
        a_seen, b_seen, c_seen = (
            np.arcsin(SUN_RADIUS_KM / np.linalg.norm(sun - position)),
            b,
            np.arccos(-position @ (sun - position) / (radius * np.linalg.norm(sun - position))),
        )
        u, v = np.meshgrid(np.linspace(-1, 1, 801), np.linspace(-1, 1, 801))
        disc = u**2 + v**2 <= 1
        covered = (u * a_seen - c_seen) ** 2 + (v * a_seen) ** 2 <= b_seen**2
        expected = 1 - (disc & covered).sum() / disc.sum()
        assert shadow.state[0] == "penumbra"
        assert shadow.sunlit_fraction[0] == pytest.approx(expected, abs=3e-3)


def test_states_far_from_the_earth_and_in_front_of_it():
    sun = np.array([[1.496e8, 0.0, 0.0]] * 3)
    positions = np.array([[7000.0, 0.0, 0.0], [-7000.0, 0.0, 0.0], [-2.0e6, 0.0, 0.0]])
    shadow = earth_shadow(positions, sun)
    assert list(shadow.state) == ["sunlit", "umbra", "annular"]
    # Beyond the umbra's apex (1.38e6 km) the Earth covers a central part of the Sun.
    b = np.arcsin(EARTH_RADIUS_KM / 2.0e6)
    a = np.arcsin(SUN_RADIUS_KM / (1.496e8 + 2.0e6))
    assert shadow.sunlit_fraction[2] == pytest.approx(1 - (b / a) ** 2)
    cylinder = earth_shadow(positions, sun, "cylindrical")
    assert list(cylinder.state) == ["sunlit", "umbra", "umbra"]
    with pytest.raises(ValueError, match="shadow model must be one of"):
        earth_shadow(positions, sun, "spherical")
