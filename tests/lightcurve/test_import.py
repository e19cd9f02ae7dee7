"""`lightcurve import`: table variants, bad values named by row and column, the three geometry
routes, and the Pomenis table through the import to the Starlink prediction."""

from decimal import Decimal
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from lightcurve import io
from lightcurve.cli import main
from lightcurve.datasets.starlink import POMENIS_PATH, predict_observations, predict_pomenis
from lightcurve.importing import Topocentric, import_photometry
from lightcurve.io.observations import ObservationError
from lightcurve.io.tables import read_table
from lightcurve.sky.epochs import TimeColumn
from lightcurve.sky.sites import get_site
from lightcurve.sky.tle import read_tles, select_object

ROOT = Path(__file__).resolve().parents[2]
CATALOGUE = ROOT / "data" / "tle" / "catalogue.tle"
#: ANIK F-1R (GEO, 107.3° W), seen from Mount Lemmon on the night after its TLE epoch.
NORAD = "28868"
START_US = (58860 * 86400 + 4 * 3600) * 1_000_000  # 2020-01-12T04:00:00 UTC, µs since MJD 0
N = 12


def _instants() -> list[int]:
    """Microseconds since MJD 0 of the measurements (irregular, sub-second)."""
    return [START_US + k * 10_123_457 + (k % 3) * 250_001 for k in range(N)]


def _formats(micro: int) -> dict[str, str]:
    days = Decimal(micro) / Decimal(86_400_000_000)
    iso = pd.Timestamp("1858-11-17") + pd.Timedelta(microseconds=micro)
    return {
        "iso": iso.strftime("%Y-%m-%dT%H:%M:%S.%f"),
        "iso_space_z": iso.strftime("%Y-%m-%d %H:%M:%S.%fZ"),
        "jd": f"{days + Decimal('2400000.5'):.13f}",
        "mjd": f"{days:.13f}",
        "unix": f"{Decimal(micro - 40587 * 86_400_000_000) / Decimal(1_000_000):.6f}",
    }


MAGS = [f"{11.5 + 0.137 * k:.3f}" for k in range(N)]
ERRS = [f"{0.03 + 0.002 * k:.3f}" for k in range(N)]

#: (time format, key of _formats, separator, header, decimal mark)
VARIANTS = [
    ("iso", "iso", ",", True, "."),
    ("iso", "iso_space_z", ";", True, "."),
    ("jd", "jd", ";", False, "."),
    ("mjd", "mjd", " ", True, "."),
    ("mjd", "mjd", "\t", False, ","),
    ("unix", "unix", ",", False, "."),
]


def _write_variant(path: Path, key: str, sep: str, header: bool, decimal: str) -> None:
    lines = ["# observer: test", "# filter: V"]
    if header:
        lines.append(sep.join(["time", "mag", "err"]))
    for micro, mag, err in zip(_instants(), MAGS, ERRS, strict=True):
        cells = [_formats(micro)[key], mag, err]
        if decimal == ",":
            cells = [c.replace(".", ",") for c in cells]
        lines.append(sep.join(cells))
    path.write_text("\n".join(lines) + "\n")


def _import(path: Path, time_format: str, header: bool, out: Path, *extra: str) -> int:
    columns = ["time", "mag", "err"] if header else ["1", "2", "3"]
    argv = ["import", str(path), "--time-column", columns[0], "--time-format", time_format]
    argv += ["--mag-column", columns[1], "--err-column", columns[2]]
    argv += ["--tle", str(CATALOGUE), "--norad", NORAD, "--site", "Mount Lemmon", "--name", "anik"]
    argv += ["--out", str(out)]
    return main([*argv, *extra])


PROVENANCE = ("# imported_from:", "# time:")


def test_six_table_variants_give_identical_observation_files(tmp_path):
    outputs = []
    for k, (time_format, key, sep, header, decimal) in enumerate(VARIANTS):
        table = tmp_path / f"variant{k}.txt"
        _write_variant(table, key, sep, header, decimal)
        out = tmp_path / f"variant{k}.csv"
        extra = ["--decimal", ","] if decimal == "," else []
        assert _import(table, time_format, header, out, *extra) == 0
        lines = out.read_text().splitlines()
        outputs.append([line for line in lines if not line.startswith(PROVENANCE)])
    assert all(output == outputs[0] for output in outputs[1:])
    observations = io.read(tmp_path / "variant0.csv")
    assert len(observations) == N and observations.meta["filter"] == "V"
    assert observations.table["epoch"][1] == "2020-01-12T04:00:10.373458Z"
    np.testing.assert_array_equal(observations.magnitudes, [float(m) for m in MAGS])
    assert set(observations.table["shadow"]) == {"sunlit"}
    assert observations.table["elevation_deg"].between(40, 60).all()
    assert observations.table["airmass"].between(1.1, 1.6).all()


def test_time_scales_tt_and_tdb_convert_to_utc(tmp_path):
    micro = _instants()[:3]
    tt = [m + 69_184_000 for m in micro]  # TT − UTC = 32.184 s + 37 leap seconds in 2020
    table = tmp_path / "tt.csv"
    table.write_text("time,mag,err\n" + "\n".join(f"{_formats(m)['mjd']},12.0,0.05" for m in tt))
    out = tmp_path / "tt_out.csv"
    assert _import(table, "mjd", True, out, "--time-scale", "tt") == 0
    np.testing.assert_allclose(io.read(out).mjd * 86_400e6, micro, atol=1.0)
    with pytest.raises(ValueError, match="Unix time counts UTC seconds"):
        TimeColumn("unix", "tt")


@pytest.fixture
def good_table(tmp_path) -> Path:
    path = tmp_path / "phot.csv"
    _write_variant(path, "iso", ",", True, ".")
    return path


def _corrupt(path: Path, row: int, column: int, value: str) -> None:
    lines = path.read_text().splitlines()
    data = [k for k, line in enumerate(lines) if not line.startswith("#")][1:]
    cells = lines[data[row - 1]].split(",")
    cells[column] = value
    lines[data[row - 1]] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")


@pytest.mark.parametrize(
    ("row", "column", "value", "name", "message"),
    [
        (3, 1, "abc", "mag", "cannot read 'abc' as a number"),
        (4, 1, "", "mag", "missing value"),
        (5, 1, "inf", "mag", "not finite"),
        (6, 2, "0", "err", "magnitude error 0 must be > 0"),
        (7, 2, "-0.1", "err", "must be > 0"),
        (2, 0, "2020-13-45T00:00:00", "time", "cannot read '2020-13-45T00:00:00' as an ISO"),
        (8, 0, "", "time", "missing time"),
        (9, 0, "2020-01-12T04:00:00.000000", "time", "same time as row 1"),
    ],
)
def test_bad_values_are_named_by_row_and_column(good_table, row, column, value, name, message):
    _corrupt(good_table, row, column, value)
    table = read_table(good_table)
    tles = select_object(read_tles(CATALOGUE), NORAD)
    with pytest.raises(ObservationError, match=message) as caught:
        import_photometry(
            table,
            "time",
            TimeColumn("iso"),
            "mag",
            get_site("Mount Lemmon"),
            err_column="err",
            tles=tles,
        )
    assert caught.value.row == row and caught.value.column == name
    assert f"row {row}, column '{name}'" in str(caught.value)
    assert f"(line {row + 3})" in str(caught.value) or "same time" in message


def test_malformed_table_structure(tmp_path, good_table, capsys):
    lines = good_table.read_text().splitlines()
    lines[6] = lines[6] + ",extra"
    bad = tmp_path / "fields.csv"
    bad.write_text("\n".join(lines))
    with pytest.raises(ObservationError, match=r"row 4: has 4 fields, the header has 3 \(line 7"):
        read_table(bad)
    table = read_table(good_table)
    with pytest.raises(ObservationError, match=r"column 'magg'.*found 'mag': misspelled"):
        table.column_index("magg")
    headless = tmp_path / "headless.csv"
    headless.write_text("\n".join(good_table.read_text().splitlines()[3:]))
    with pytest.raises(ObservationError, match=r"no header row: name columns by position 1\.\.3"):
        read_table(headless).column_index("mag")
    # A broken TLE checksum names the file and the line, through the command.
    tle = tmp_path / "anik.tle"
    record = [line for line in CATALOGUE.read_text().splitlines() if line[2:7] == NORAD]
    tle.write_text("ANIK F-1R\n" + record[0][:-1] + "0\n" + record[1] + "\n")
    argv = ["import", str(good_table), "--time-column", "time", "--time-format", "iso"]
    argv += ["--mag-column", "mag", "--err-column", "err", "--tle", str(tle)]
    assert main([*argv, "--site", "Mount Lemmon", "--out", str(tmp_path / "x.csv")]) == 2
    err = capsys.readouterr().err
    assert f"{tle}, line 2: checksum mismatch" in err and err.count("\n") == 1


def test_object_below_the_horizon_is_named(tmp_path):
    """The ISS at times when it is below Mount Lemmon's horizon: wrong time, site or TLE."""
    iss = select_object(read_tles(CATALOGUE), 25544)[-1]
    path = tmp_path / "iss.csv"
    epochs = iss.epoch_mjd + np.array([0.0, 0.1, 0.2])
    path.write_text("mjd,mag\n" + "\n".join(f"{m:.9f},5.0" for m in epochs))
    with pytest.raises(ObservationError, match="below the horizon") as caught:
        import_photometry(
            read_table(path),
            "mjd",
            TimeColumn("mjd"),
            "mag",
            get_site("Mount Lemmon"),
            mag_err=0.1,
            tles=[iss],
        )
    assert caught.value.row == 1 and caught.value.column == "mjd"


def test_drop_bad_rows_lists_them(good_table, tmp_path, capsys):
    _corrupt(good_table, 3, 1, "abc")
    _corrupt(good_table, 6, 2, "0")
    out = tmp_path / "dropped.csv"
    argv = ["import", str(good_table), "--time-column", "time", "--time-format", "iso"]
    argv += ["--mag-column", "mag", "--err-column", "err", "--tle", str(CATALOGUE)]
    argv += ["--norad", NORAD, "--site", "Mount Lemmon", "--drop-bad-rows", "--out", str(out)]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "dropped 2 bad row(s)" in printed and "row 3, column 'mag'" in printed
    observations = io.read(out)
    assert len(observations) == N - 2 and observations.meta["dropped_bad_rows"] == "2"


def test_topocentric_routes_reproduce_the_tle_geometry(tmp_path, good_table):
    """The same positions given as elevation/azimuth/range and as RA/Dec/range give the
    vectors of the TLE route (the directions written with 10 decimals: ≤ 1 m)."""
    site = get_site("Mount Lemmon")
    tles = select_object(read_tles(CATALOGUE), NORAD)
    from_tle = import_photometry(
        read_table(good_table), "time", TimeColumn("iso"), "mag", site, err_column="err", tles=tles
    )
    table = from_tle.table
    topocentric = -table[["obs_x", "obs_y", "obs_z"]].to_numpy()
    distance = np.linalg.norm(topocentric, axis=1)
    ra = np.degrees(np.arctan2(topocentric[:, 1], topocentric[:, 0])) % 360
    dec = np.degrees(np.arcsin(topocentric[:, 2] / distance))
    path = tmp_path / "topo.csv"
    frame = pd.DataFrame(
        {
            "t": table["epoch"],
            "m": table["mag"],
            "el": table["elevation_deg"].map("{:.10f}".format),
            "az": table["azimuth_deg"].map("{:.10f}".format),
            "ra": [f"{v:.10f}" for v in ra],
            "dec": [f"{v:.10f}" for v in dec],
            "r": [f"{v:.6f}" for v in distance],
        }
    )
    frame.to_csv(path, index=False)
    common = (read_table(path), "t", TimeColumn("iso"), "m", site)
    for kind, columns in (("alt-az", ("el", "az", "r")), ("ra-dec", ("ra", "dec", "r"))):
        result = import_photometry(*common, mag_err=0.05, topocentric=Topocentric(kind, columns))
        for column in ("obs_x", "obs_y", "obs_z", "sun_x", "sun_y", "sun_z"):
            np.testing.assert_allclose(result.table[column], table[column], atol=1e-3)
        np.testing.assert_allclose(result.table["airmass"], table["airmass"], rtol=1e-9)
    # Elevation out of range and a negative range are named.
    frame.loc[4, "el"] = "-2.0"
    frame.loc[6, "r"] = "-5"
    frame.to_csv(path, index=False)
    common = (read_table(path), *common[1:])
    for kind, columns, message in (
        ("alt-az", ("el", "az", "r"), r"row 5, column 'el': elevation -2 deg"),
        ("ra-dec", ("ra", "dec", "r"), r"row 7, column 'r': slant -5 km must be > 0"),
    ):
        with pytest.raises(ObservationError, match=message):
            import_photometry(*common, mag_err=0.05, topocentric=Topocentric(kind, columns))


def test_pomenis_table_through_import_gives_the_starlink_prediction(tmp_path, capsys):
    out = tmp_path / "pomenis.csv"
    argv = ["import", str(POMENIS_PATH), "--time-column", "observation_time"]
    argv += ["--time-format", "iso", "--mag-column", "ab_magnitude", "--mag-err", "0.1"]
    argv += ["--alt-az-range-columns", "satellite_altitude,satellite_azimuth,satellite_height"]
    argv += ["--range-kind", "height", "--site", "Mount Lemmon", "--allow-duplicate-epochs"]
    assert main([*argv, "--band", "r", "--magnitude-system", "ab", "--out", str(out)]) == 0
    assert "1173 measurements" in capsys.readouterr().out
    observations = io.read(out)
    assert (observations.meta["band"], observations.meta["magnitude_system"]) == ("r", "ab")
    reference = predict_pomenis()  # what benchmarks/starlink.py reports
    np.testing.assert_array_equal(observations.mjd, reference["mjd"])
    np.testing.assert_array_equal(observations.magnitudes, reference["measured"])
    predicted = predict_observations(observations, get_site("Mount Lemmon"))
    np.testing.assert_allclose(predicted, reference["predicted"], atol=1e-9)
    np.testing.assert_allclose(
        observations.table["phase_angle_deg"], reference["phase_angle_deg"], atol=1e-9
    )
