"""Observation files: round trips, the DAMIT reader, and every malformed-input message."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from lightcurve import io
from lightcurve.io.observations import TRUTH_COLUMNS, ObservationError, Observations, validate_table
from tests.lightcurve._round_trip import assert_csv_parquet_round_trip

ROOT = Path(__file__).resolve().parents[3]
ARIADNE = ROOT / "data" / "ariadne" / "test_lcs_rel"

HEADER = "# object: test-sat\n# frame: GCRS\n"
COLUMNS = "epoch,mag,mag_err,sun_x,sun_y,sun_z,obs_x,obs_y,obs_z"
ROW = "2024-01-01T00:00:{s:02d}Z,{mag},0.05,1.4e8,2.0e7,1.0e6,3.0e4,1.0e4,5.0e3"


def write_csv(tmp_path, rows, header=HEADER, columns=COLUMNS, name="obs.csv"):
    path = tmp_path / name
    path.write_text(header + columns + "\n" + "\n".join(rows) + "\n")
    return path


def good_rows(n=5):
    return [ROW.format(s=i, mag=10 + 0.1 * i) for i in range(n)]


def test_csv_reads_with_metadata_and_si_accessors(tmp_path):
    obs = io.read(write_csv(tmp_path, good_rows()))
    assert len(obs) == 5 and obs.meta == {"object": "test-sat", "frame": "GCRS"}
    np.testing.assert_allclose(obs.times, np.arange(5.0), atol=1e-5)
    np.testing.assert_allclose(obs.sun_vectors[0], [1.4e11, 2.0e10, 1.0e9])
    np.testing.assert_allclose(obs.observer_vectors[0], [3.0e7, 1.0e7, 5.0e6])
    assert obs.mjd[0] == pytest.approx(60310.0)
    assert obs.name == "test-sat"


def test_round_trip_csv_parquet_identical(tmp_path):
    obs = io.read(write_csv(tmp_path, good_rows()))
    truth = np.tile([0.0, 0.0, 0.6, 0.8, 0.01, 0.02, -0.03], (5, 1))
    obs = obs.with_columns(**{c: truth[:, i] for i, c in enumerate(TRUTH_COLUMNS)})
    assert assert_csv_parquet_round_trip(obs, tmp_path).has_truth


def test_ariadne_damit_file():
    obs = io.read(ARIADNE)
    assert len(obs) == 1541
    assert len(np.unique(obs.lightcurve_ids)) == 37
    assert obs.relative.all()
    assert obs.meta["frame"] == "ecliptic J2000"
    assert obs.meta["target"] == "asteroid"
    absolute = io.read(ARIADNE.with_name("test_lcs_abs"))
    assert len(np.unique(absolute.lightcurve_ids[~absolute.relative])) == 16


def test_mjd_column_and_geometry_only_files(tmp_path):
    rows = ["60310.0,1.4e8,0,0,3e4,0,0", "60310.5,1.4e8,0,0,3e4,0,0"]
    path = write_csv(tmp_path, rows, header="", columns="mjd,sun_x,sun_y,sun_z,obs_x,obs_y,obs_z")
    with pytest.raises(ObservationError, match="missing required column 'mag'"):
        io.read(path)
    obs = io.read(path, require_magnitudes=False)
    assert obs.times[1] == pytest.approx(43200.0)
    assert not obs.has_magnitudes


SUN, OBSERVER = "1.4e8,2.0e7,1.0e6", "3.0e4,1.0e4,5.0e3"


def _vectors(old: str, new: str) -> list[str]:
    """One otherwise good row with the vector ``old`` (:data:`SUN` or :data:`OBSERVER`)
    replaced by ``new`` (km)."""
    return [ROW.format(s=0, mag=10).replace(old, new)]


@pytest.mark.parametrize(
    ("columns", "pattern"),
    [
        (
            COLUMNS.replace("mag_err", "mag_er"),
            r"missing required column 'mag_err' \(found 'mag_er': misspelled\?\)",
        ),
        (COLUMNS.replace("epoch", "time"), "no time column"),
    ],
)
def test_malformed_header_messages_name_the_column(tmp_path, columns, pattern):
    path = write_csv(tmp_path, good_rows(), columns=columns)
    with pytest.raises(ObservationError, match=pattern) as info:
        io.read(path)
    assert str(path) in str(info.value)


@pytest.mark.parametrize(
    ("rows", "pattern"),
    [
        (
            [*good_rows(2), ROW.format(s=2, mag="bright")],
            r"row 3, column 'mag': non-numeric value 'bright'",
        ),
        ([*good_rows(2), ROW.format(s=2, mag="nan")], r"row 3, column 'mag': value is NaN"),
        ([*good_rows(2), ROW.format(s=2, mag="inf")], r"row 3, column 'mag': .*not finite"),
        (
            [*good_rows(3), ROW.format(s=3, mag=10).replace(",0.05,", ",0,")],
            r"row 4, column 'mag_err': mag_err must be > 0",
        ),
        (
            [ROW.format(s=1, mag=10), ROW.format(s=0, mag=10)],
            r"row 2, column 'epoch': epochs are not in increasing order",
        ),
        (
            [ROW.format(s=1, mag=10), ROW.format(s=1, mag=11)],
            r"row 2, column 'epoch': duplicate epoch",
        ),
        (
            _vectors(OBSERVER, "0,0,0"),
            r"row 1, column 'obs_x': object->observer vector has zero length",
        ),
        (
            _vectors(OBSERVER, "3.0,1.0,0.5"),
            r"row 1, column 'obs_x': object->observer range 3.202 km is below .*AU given",
        ),
        (
            _vectors(OBSERVER, "3.0e10,1.0e10,5.0e9"),
            r"row 1, column 'obs_x': .*metres given\?.*target: asteroid",
        ),
        (
            _vectors(SUN, "0.9,0.1,0.0"),
            r"row 1, column 'sun_x': object->Sun range .* below",
        ),
        (
            [*good_rows(3), "2024-01-01T00:00:09Z,10.0,0.05,1.4e8"],
            r"row 4: has 4 fields, the header has 9 \(truncated",
        ),
        (
            ["not-a-date,10,0.05,1.4e8,2.0e7,1.0e6,3.0e4,1.0e4,5.0e3"],
            r"row 1, column 'epoch': cannot parse ISO-8601",
        ),
    ],
)
def test_malformed_csv_messages_name_row_and_column(tmp_path, rows, pattern):
    path = write_csv(tmp_path, rows)
    with pytest.raises(ObservationError, match=pattern) as info:
        io.read(path)
    assert str(path) in str(info.value)


def test_drop_bad_rows_keeps_the_rest(tmp_path):
    rows = [*good_rows(3), ROW.format(s=3, mag="nan"), ROW.format(s=4, mag=12), "2024-01-01"]
    obs = io.read(write_csv(tmp_path, rows), drop_bad_rows=True)
    assert len(obs) == 4
    assert sorted(p.row for p in obs.dropped) == [4, 6]
    assert {p.column for p in obs.dropped} >= {"mag"}


def test_metadata_and_format_errors(tmp_path):
    path = write_csv(tmp_path, good_rows(), header="# object test\n")
    with pytest.raises(ObservationError, match="line 1: metadata lines must read"):
        io.read(path)
    empty = tmp_path / "empty.csv"
    empty.write_text("")
    with pytest.raises(ObservationError, match="no header row"):
        io.read(empty)
    with pytest.raises(FileNotFoundError, match="no such observation file"):
        io.read(tmp_path / "missing.csv")


def test_truncated_parquet_and_damit(tmp_path):
    obs = io.read(write_csv(tmp_path, good_rows()))
    io.write(obs, tmp_path / "a.parquet")
    data = (tmp_path / "a.parquet").read_bytes()
    (tmp_path / "cut.parquet").write_bytes(data[: len(data) // 2])
    with pytest.raises(ObservationError, match=r"cut.parquet: cannot read Parquet"):
        io.read(tmp_path / "cut.parquet")
    text = ARIADNE.read_text().splitlines()
    (tmp_path / "cut_damit").write_text("\n".join(text[:50]) + "\n2438882.5 1.0 1.4")
    with pytest.raises(ObservationError, match=r"cut_damit: line 51: expected 8 fields, found 3"):
        io.read(tmp_path / "cut_damit")


def test_validate_table_directly():
    table = pd.DataFrame(
        {
            "mjd": [1.0, 2.0],
            "sun_x": [1.5e8] * 2,
            "sun_y": [0.0] * 2,
            "sun_z": [0.0] * 2,
            "obs_x": [4e4] * 2,
            "obs_y": [0.0] * 2,
            "obs_z": [0.0] * 2,
            "mag": [5.0, 6.0],
            "mag_err": [0.1, 0.1],
            "q1": [0.0, 0.0],
            "q2": [0.0] * 2,
            "q3": [0.0] * 2,
            "q4": [1.0, 2.0],
            "wx": [0.0] * 2,
            "wy": [0.0] * 2,
            "wz": [0.0] * 2,
        }
    )
    with pytest.raises(ObservationError, match="row 2, column 'q1': truth quaternion is not unit"):
        validate_table(table, "mem")
    table.loc[1, "q4"] = 1.0
    obs = Observations(validate_table(table, "mem"))
    assert obs.truth.shape == (2, 7)
