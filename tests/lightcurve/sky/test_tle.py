"""TLE reading and checking, element-set choice, SGP4 errors, and the topocentric geometry
against skyfield's independent SGP4 → ITRS → topocentric chain."""

import warnings
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

from lightcurve.sky.sites import get_site
from lightcurve.sky.tle import (
    SGP4Error,
    TLEAgeWarning,
    TLEError,
    checksum,
    decode_norad,
    parse_tles,
    propagate_teme,
    read_tles,
    select_object,
)
from lightcurve.sky.tle_reference import compare_topocentric, skyfield_timescale

CATALOGUE = Path(__file__).resolve().parents[3] / "data" / "tle" / "catalogue.tle"
ISS_LINES = (
    "1 25544U 98067A   18184.80969102  .00001614  00000-0  31745-4 0  9993",
    "2 25544  51.6414 295.8524 0003435 262.6267 204.2868 15.54005638121106",
)


def _with_line(lines, index, text):
    lines = list(lines)
    lines[index] = text
    return "\n".join(lines)


def test_two_and_three_line_records_several_objects_and_histories():
    tles = read_tles(CATALOGUE)
    assert len(tles) == 29 and len({t.norad for t in tles}) == 25
    assert all(t.source == str(CATALOGUE) for t in tles)
    iss = select_object(tles, 25544)
    assert [t.name for t in iss] == ["ISS (ZARYA)"] * 4
    assert np.all(np.diff([t.epoch_mjd for t in iss]) > 0)
    # Epoch 18184.80969102 = 2018-07-03 19:25:57.3 UTC (day 184 of 2018).
    assert iss[2].epoch_mjd == pytest.approx(58302.80969102, abs=1e-9)
    # The same record as two lines, as "0 NAME" three lines, with blank and comment lines.
    two = parse_tles("\n".join(ISS_LINES))
    three = parse_tles("# comment\n\n0 ISS (ZARYA)\n" + "\n".join(ISS_LINES) + "\n\n")
    assert two[0].name is None and three[0].name == "ISS (ZARYA)"
    assert two[0].epoch_mjd == three[0].epoch_mjd == iss[2].epoch_mjd


def test_nearest_element_set_per_row_and_age_warning():
    iss = select_object(read_tles(CATALOGUE), "25544")
    epochs = np.array([t.epoch_mjd for t in iss])
    mjd = np.r_[epochs - 0.2, (epochs[1] + epochs[2]) / 2 - 1, (epochs[1] + epochs[2]) / 2 + 1]
    with pytest.warns(TLEAgeWarning, match=r"2 of 6 epochs are more than 3 days"):
        state = propagate_teme(iss, mjd)
    np.testing.assert_array_equal(state.tle_index, [0, 1, 2, 3, 1, 2])
    np.testing.assert_allclose(state.age_days[:4], -0.2)
    radius = np.linalg.norm(state.position_km, axis=1)
    assert np.all((radius > 6650) & (radius < 6850))  # the ISS at ~400 km
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        propagate_teme(iss, epochs + 0.5)  # within 3 days: no warning


def test_object_selection_errors():
    tles = read_tles(CATALOGUE)
    with pytest.raises(ValueError, match=r"25 objects .* choose one by its NORAD number"):
        select_object(tles)
    with pytest.raises(ValueError, match="no element set for NORAD 99999"):
        select_object(tles, 99999)
    assert decode_norad("A0001") == 100001 and decode_norad("00005") == 5
    with pytest.raises(ValueError, match="not a catalogue number"):
        decode_norad("I0001")


@pytest.mark.parametrize(
    ("index", "text", "line", "message"),
    [
        (
            0,
            ISS_LINES[0][:-1] + "4",
            1,
            "checksum mismatch: the line's digits give 3, column 69 says 4",
        ),
        (1, ISS_LINES[1][:-1] + "0", 2, "checksum mismatch"),
        (0, ISS_LINES[0][:-1], 1, "has 69 characters, this one has 68"),
        (1, ISS_LINES[1] + "9", 2, "has 69 characters, this one has 70"),
        (1, ISS_LINES[0], 2, "expected TLE line 2 \\('2 …'\\), got '1 25544U"),
        (1, ISS_LINES[1][:8] + "51.64x4" + ISS_LINES[1][15:], 2, "inclination '51.64x4"),
        (1, ISS_LINES[1][:8] + "951.6414" + ISS_LINES[1][16:], 2, "outside \\[0, 180\\]"),
        (0, ISS_LINES[0][:20] + "400.80969102" + ISS_LINES[0][32:], 1, "epoch day 400.80969102"),
        (0, ISS_LINES[0][:32] + "x" + ISS_LINES[0][33:], 1, "column 33 must be blank"),
        (1, ISS_LINES[1][:26] + "000343a" + ISS_LINES[1][33:], 2, "eccentricity"),
        (1, "2 25545" + ISS_LINES[1][7:], 2, "number '25545' differs from line 2's '25544'"),
    ],
)
def test_malformed_records_name_the_line(index, text, line, message):
    text = _with_line(ISS_LINES, index, text)
    lines = text.split("\n")
    if "checksum mismatch" not in message and len(lines[index]) == 69:
        # Keep the checksum right so that the field check itself is what fails.
        lines[index] = lines[index][:68] + str(checksum(lines[index]))
        text = "\n".join(lines)
    with pytest.raises(TLEError, match=message) as caught:
        parse_tles("NAME\n" + text, "sats.tle")
    assert caught.value.line == line + 1 and f"sats.tle, line {line + 1}:" in str(caught.value)


def test_structure_errors_name_the_line():
    with pytest.raises(TLEError, match="line 1: TLE line 2 without a line 1"):
        parse_tles(ISS_LINES[1], "a.tle")
    with pytest.raises(TLEError, match="line 2: TLE line 1 is not followed by its line 2"):
        parse_tles("ISS\n" + ISS_LINES[0], "a.tle")
    with pytest.raises(TLEError, match="line 2: two name lines in a row"):
        parse_tles("ISS\nISS again\n" + "\n".join(ISS_LINES), "a.tle")
    with pytest.raises(TLEError, match="no TLE records"):
        parse_tles("# only a comment\n", "a.tle")
    # Without checksum verification a wrong checksum digit passes.
    assert parse_tles(_with_line(ISS_LINES, 0, ISS_LINES[0][:-1] + "4"), verify_checksum=False)


def _verification_set():
    """The sgp4 package's own verification TLEs (Vallado et al. 2006) with their spans."""
    text = resources.files("sgp4").joinpath("SGP4-VER.TLE").read_text()
    records, spans = [], []
    for line in text.splitlines():
        if line.startswith("2 "):
            spans.append([float(v) for v in line[69:].split()])
        records.append(line[:69] if line[:2] in ("1 ", "2 ") else line)
    return "\n".join(records), spans


def test_sgp4_verification_set_propagates_or_reports_its_error_code():
    text, spans = _verification_set()
    # Three records carry deliberately wrong checksums: rejected, with the line named.
    with pytest.raises(TLEError, match=r"SGP4-VER.TLE, line 100: checksum mismatch"):
        parse_tles(text, "SGP4-VER.TLE")
    tles = parse_tles(text, "SGP4-VER.TLE", verify_checksum=False)
    assert len(tles) == len(spans) == 33
    codes = []
    for tle, (start, stop, step) in zip(tles, spans, strict=True):
        minutes = np.unique(np.r_[0.0, np.arange(start, stop, step), stop])
        try:
            state = propagate_teme([tle], tle.epoch_mjd + minutes / 1440.0, max_age_days=None)
        except SGP4Error as error:
            codes.append(error.code)
            assert f"SGP4 error {error.code} (" in str(error) and tle.where in str(error)
        else:
            assert np.all(np.isfinite(state.position_km))
    # The error codes sgp4's own test expects, in file order (1, 1, 6, 6, 4, 3, 6).
    assert codes == [1, 1, 6, 6, 4, 3, 6]


#: LEO, MEO (GPS, O3b, BeiDou-like), GEO, Molniya and HEO element sets of the catalogue.
ACCEPTANCE_OBJECTS = {
    25544: "LEO",
    28057: "LEO",
    43477: "LEO",
    28129: "MEO",
    39191: "MEO",
    28868: "GEO",
    24208: "GEO",
    41105: "GEO",
    8195: "Molniya",
    21897: "Molniya",
    27540: "HEO",
}


def test_topocentric_geometry_matches_skyfield():
    """≤ 1″ in direction and ≤ 1 m in range: 11 objects × 1000 random epochs within two days
    of their TLE epochs (11 000 epochs) × 3 sites (``benchmarks/tle_geometry.py``: 10⁴
    epochs per object)."""
    ts = skyfield_timescale()
    catalogue = read_tles(CATALOGUE)
    sites = [get_site(name) for name in ("Kislovodsk", "Siding Spring", "Haleakala")]
    rng = np.random.default_rng(2024)
    worst_angle, worst_range = 0.0, 0.0
    for norad in ACCEPTANCE_OBJECTS:
        tle = select_object(catalogue, norad)[-1]
        mjd = tle.epoch_mjd + rng.uniform(-2.0, 2.0, 1000)
        angle, distance = compare_topocentric(tle, sites, mjd, ts)
        worst_angle = max(worst_angle, float(angle.max()))
        worst_range = max(worst_range, float(distance.max()))
    assert set(ACCEPTANCE_OBJECTS.values()) >= {"LEO", "MEO", "GEO", "Molniya"}
    assert worst_angle <= 1.0, worst_angle
    assert worst_range <= 1.0, worst_range
