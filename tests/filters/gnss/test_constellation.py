"""Almanac file, YUMA parsing and satellite orbits against the GPS SPS Performance Standard."""

from __future__ import annotations

import math
import runpy
from pathlib import Path

import numpy as np
import pytest

from filters.gnss.constellation import (
    EARTH_ROTATION_RATE,
    GPS_MU,
    AlmanacError,
    Constellation,
    parse_yuma,
)

DATA = Path(__file__).resolve().parents[3] / "data" / "gnss"
ALMANAC = DATA / "gps_nominal_24slot.alm"


@pytest.fixture(scope="module")
def nominal():
    return runpy.run_path(str(DATA / "nominal_constellation.py"))


@pytest.fixture(scope="module")
def constellation():
    return Constellation(parse_yuma(ALMANAC.read_text(), source=ALMANAC.name))


def test_shipped_file_is_the_generated_one(nominal):
    assert ALMANAC.read_text() == nominal["yuma_text"]()


def test_orbits_reproduce_the_sps_slot_table(nominal, constellation):
    """At the defined epoch each satellite's node right ascension (referred to the Greenwich
    meridian through the table's Greenwich hour angle) and argument of latitude are the
    table's, computed back from the propagated position and velocity."""
    toa = nominal["TOA_S"]
    r, v = constellation.states(toa)
    v = v - np.cross([0.0, 0.0, nominal["NODE_RATE_RAD_S"]], r)  # velocity in the node's frame
    h = np.cross(r, v)
    node = np.arctan2(h[:, 0], -h[:, 1])  # node direction ẑ × h
    node_vector = np.stack([np.cos(node), np.sin(node), np.zeros_like(node)], axis=1)
    w = np.cross(h / np.linalg.norm(h, axis=1, keepdims=True), node_vector)
    latitude_arg = np.arctan2(np.sum(r * w, axis=1), np.sum(r * node_vector, axis=1))
    # Week-start inertial frame → Greenwich at toa → the table's J2000 RAAN.
    raan = np.degrees(node - EARTH_ROTATION_RATE * toa) + nominal["GREENWICH_HOUR_ANGLE_DEG"]
    table = np.array(list(nominal["SLOTS"].values()))
    np.testing.assert_allclose(np.mod(raan - table[:, 0] + 180, 360) - 180, 0, atol=1e-8)
    np.testing.assert_allclose(np.mod(np.degrees(latitude_arg) - table[:, 1] + 180, 360) - 180,
                               0, atol=1e-8)  # fmt: skip
    inclination = np.degrees(np.arccos(h[:, 2] / np.linalg.norm(h, axis=1)))
    np.testing.assert_allclose(inclination, 55.0, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(r, axis=1), 26_559.7e3, rtol=1e-9)  # √A to 1e-6
    # Six planes 60° apart, four satellites each; the Keplerian period of A = 26 559.7 km is
    # within 6 s of half a sidereal day (43 082 s; the J2 drifts make up the rest).
    assert len(np.unique(np.round(table[:, 0], 3))) == 6
    period = 2 * math.pi / constellation.mean_motion
    np.testing.assert_allclose(period, 43_082.0, atol=6.0)


def test_velocity_is_the_derivative_of_position(constellation):
    t = 400_000.0
    h = 0.5
    numeric = (constellation.positions(t + h) - constellation.positions(t - h)) / (2 * h)
    np.testing.assert_allclose(constellation.velocities(t), numeric, atol=2e-6)
    # Eccentric orbits too.
    almanac = parse_yuma(
        ALMANAC.read_text().replace("0.0000000000E+00\nTime", "1.5000000000E-02\nTime")
    )
    eccentric = Constellation(almanac)
    assert np.all(almanac.eccentricity == 0.015)
    numeric = (eccentric.positions(t + h) - eccentric.positions(t - h)) / (2 * h)
    np.testing.assert_allclose(eccentric.velocities(t), numeric, atol=2e-6)
    # Two-body energy v²/2 − μ/r = −μ/(2a) in the frame turning with the node.
    r, v = eccentric.states(np.array([t, t + 5000.0])[:, None])
    v = v - np.cross([0.0, 0.0, almanac.node_rate[0]], r)
    energy = 0.5 * np.sum(v * v, axis=-1) - GPS_MU / np.linalg.norm(r, axis=-1)
    expected = -GPS_MU / (2 * eccentric.semi_major_axis)
    np.testing.assert_allclose(energy, np.broadcast_to(expected, energy.shape), rtol=1e-10)


def test_earth_fixed_positions_rotate_with_the_earth(constellation):
    t = np.array([345_609.0, 350_000.0])[:, None]
    inertial = constellation.positions(t)
    fixed = constellation.earth_fixed_positions(t)
    angle = EARTH_ROTATION_RATE * t[:, 0]
    c, s = np.cos(angle), np.sin(angle)
    rotated = np.stack(
        [c[:, None] * inertial[..., 0] + s[:, None] * inertial[..., 1],
         -s[:, None] * inertial[..., 0] + c[:, None] * inertial[..., 1], inertial[..., 2]],
        axis=-1,
    )  # fmt: skip
    np.testing.assert_allclose(fixed, rotated, atol=1e-6)


def test_parser_errors_name_the_record_and_field():
    text = ALMANAC.read_text()
    with pytest.raises(AlmanacError, match=r"gps.alm: line 4: Eccentricity: not a number"):
        parse_yuma(text.replace("0.0000000000E+00", "zero", 1), source="gps.alm")
    with pytest.raises(AlmanacError, match=r"record 1: missing field 'af1'"):
        parse_yuma(text.replace("Af1(s/s):                   0.0000000000E+00\n", "", 1))
    with pytest.raises(AlmanacError, match="unknown field 'Colour'"):
        parse_yuma(text.replace("Health:", "Colour:", 1))
    with pytest.raises(AlmanacError, match="repeats PRNs"):
        parse_yuma(text.replace("ID:                         02", "ID:                         01"))
    with pytest.raises(AlmanacError, match="no almanac records"):
        parse_yuma("\n\n")


def test_unhealthy_satellites_can_be_dropped():
    text = ALMANAC.read_text().replace(
        "Health:                     000", "Health:                     063", 1
    )
    almanac = parse_yuma(text)
    assert almanac.size == 24 and almanac.healthy().size == 23
    assert 1 not in almanac.healthy().prn
