"""`lightcurve geometry --tle`: spans, the epochs of an existing file, the Earth's shadow, and a
catalogued satellite end to end through geometry → simulate → invert."""

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from lightcurve import io
from lightcurve.cli import main
from lightcurve.inversion import shape_symmetry
from shapes import get_library

ROOT = Path(__file__).resolve().parents[2]
CATALOGUE = ROOT / "data" / "tle" / "catalogue.tle"
SAMPLES = ROOT / "data" / "observations" / "tle"
VECTORS = ["sun_x", "sun_y", "sun_z", "obs_x", "obs_y", "obs_z"]
#: The ISS leaving the Earth's shadow above Kislovodsk on 2018-07-03 (TLE of that day).
ISS_EXIT = ["--tle", str(CATALOGUE), "--norad", "25544", "--site", "Kislovodsk"]
ISS_EXIT += ["--start", "2018-07-03T23:46:00", "--duration", "240", "--cadence", "1"]


def test_umbra_rows_are_dropped_or_flagged(tmp_path, capsys):
    flagged, dropped = tmp_path / "flag.csv", tmp_path / "drop.csv"
    assert main(["geometry", *ISS_EXIT, "--umbra", "flag", "--out", str(flagged)]) == 0
    printed = capsys.readouterr().out
    assert "umbra exit: 2018-07-03T23:47:" in printed and "penumbra exit" in printed
    assert main(["geometry", *ISS_EXIT, "--out", str(dropped)]) == 0
    printed = capsys.readouterr().out
    table = io.read(flagged, require_magnitudes=False).table
    in_umbra = int((table["shadow"] == "umbra").sum())
    assert in_umbra > 10 and (table["shadow"] == "penumbra").sum() >= 5
    kept = io.read(dropped, require_magnitudes=False)
    assert len(kept) == len(table) - in_umbra
    assert kept.meta["dropped_umbra"] == str(in_umbra) and f"{in_umbra} in the umbra" in printed
    # Through the penumbra the sunlit fraction rises from 0 to 1; the ISS is bright-lit after.
    penumbra = table[table["shadow"] == "penumbra"]["sunlit_fraction"].to_numpy()
    assert np.all(np.diff(penumbra) > 0) and 0 < penumbra.min() < penumbra.max() < 1
    assert table["elevation_deg"].min() >= 10 and table["range_km"].between(400, 1500).all()


def test_epochs_from_an_existing_file_keep_its_columns(tmp_path):
    span = tmp_path / "span.csv"
    assert main(["geometry", *ISS_EXIT, "--umbra", "flag", "--out", str(span)]) == 0
    reference = io.read(span, require_magnitudes=False).table
    photometry = tmp_path / "phot.csv"
    pd.DataFrame(
        {"epoch": reference["epoch"][::7], "mag": 3.0, "mag_err": 0.1, "filter": "V"}
    ).to_csv(photometry, index=False)
    out = tmp_path / "again.csv"
    argv = ["geometry", "--tle", str(CATALOGUE), "--norad", "25544", "--site", "Kislovodsk"]
    assert main([*argv, "--epochs-from", str(photometry), "--out", str(out)]) == 0
    again = io.read(out)
    assert len(again) == len(reference[::7]) and set(again.table["filter"]) == {"V"}
    np.testing.assert_allclose(again.table[VECTORS], reference[VECTORS][::7], rtol=1e-12)
    np.testing.assert_allclose(again.magnitudes, 3.0)
    # The same epochs from an observation file, and from a Parquet table of MJD floats
    # (which resolve 0.6 µs: the ISS moves 5 mm in that time).
    pd.DataFrame({"mjd": again.mjd, "mag": 3.0}).to_parquet(tmp_path / "phot.parquet")
    for source, tolerance in ((out, 1e-9), (tmp_path / "phot.parquet", 1e-5)):
        third = tmp_path / "third.csv"
        assert main([*argv, "--epochs-from", str(source), "--out", str(third)]) == 0
        third_table = io.read(third, require_magnitudes=False).table
        np.testing.assert_allclose(third_table[VECTORS], again.table[VECTORS], atol=tolerance)


def test_geometry_argument_errors(tmp_path, capsys):
    out = str(tmp_path / "x.csv")
    cases = [
        (
            ["--geo", "-100", "--norad", "5", "--start", "2020-01-01", "--duration", "60"],
            "--norad needs --tle",
        ),
        (["--geo", "-100", "--epochs-from", out], "--epochs-from needs --tle"),
        ([*ISS_EXIT, "--min-elevation", "-5"], "--min-elevation must be >= 0"),
        ([*ISS_EXIT[:4], "--site", "Atlantis", *ISS_EXIT[6:]], "unknown site 'Atlantis'"),
        (["--tle", str(CATALOGUE), "--start", "2020-01-01", "--duration", "60"], "25 objects"),
    ]
    for argv, message in cases:
        assert main(["geometry", *argv, "--out", out]) == 2
        assert message in capsys.readouterr().err


def test_circular_orbits_take_site_names(tmp_path):
    out = tmp_path / "geo.csv"
    argv = ["geometry", "--geo", "-100", "--site", "Mount Lemmon", "--start", "2024-03-10T04:48"]
    assert main([*argv, "--duration", "60", "--out", str(out)]) == 0
    assert io.read(out, require_magnitudes=False).meta["site"].startswith("Mount Lemmon (32.4434")


def test_catalogued_satellite_end_to_end(tmp_path):
    """ANIK F-1R's TLE, Mount Lemmon, 10 min of the night of 2020-01-12 every 2 s → a tumbling
    box-wing simulated over it → the UKF with the known shape recovers the attitude (the
    commands of data/observations/README.md, whose outputs are the committed samples)."""
    geometry, simulated = tmp_path / "geometry.csv", tmp_path / "simulated.csv"
    argv = ["geometry", "--tle", str(CATALOGUE), "--norad", "28868", "--site", "Mount Lemmon"]
    argv += ["--start", "2020-01-12T04:00:00", "--duration", "600", "--cadence", "2"]
    assert main([*argv, "--out", str(geometry)]) == 0
    sample = io.read(SAMPLES / "anik_f1r_mount_lemmon.csv", require_magnitudes=False).table
    ours = io.read(geometry, require_magnitudes=False).table
    np.testing.assert_allclose(ours[VECTORS], sample[VECTORS], rtol=1e-9)
    argv = ["simulate", str(geometry), "--shape", "box_wing", "--q0", "0.2,-0.1,0.3,0.927"]
    argv += ["--omega0", "0.8,-0.5,1.2", "--noise-mag", "0.05", "--seed", "21"]
    assert main([*argv, "--out", str(simulated)]) == 0
    observations = io.read(simulated)
    np.testing.assert_allclose(
        observations.magnitudes, io.read(SAMPLES / "anik_f1r_box_wing.csv").magnitudes, atol=1e-6
    )
    # A prior 9° and 0.07°/s off the truth; the filter alone (no search).
    argv = ["invert", str(simulated), "--shape", "box_wing", "--method", "ukf", "--init", "none"]
    argv += ["--q0", "0.25,-0.05,0.35,0.9", "--omega0", "0.75,-0.45,1.1"]
    argv += ["--attitude-sigma-deg", "10", "--omega-sigma", "0.1", "--no-progress"]
    assert main([*argv, "--out", str(tmp_path / "inversion")]) == 0
    summary = json.loads((tmp_path / "inversion" / "simulated" / "summary.json").read_text())
    group = shape_symmetry(get_library().load("box_wing"))
    truth = observations.truth[-1]
    error = math.degrees(float(group.attitude_error(np.array(summary["quaternion"]), truth[:4])))
    assert error < 2.0, error
    assert np.abs(np.array(summary["omega_rad_s"]) - truth[4:]).max() < math.radians(0.02)
    assert summary["residual_rms_mag"] < 0.07


@pytest.mark.parametrize("name", ["anik_f1r_mount_lemmon.csv", "anik_f1r_box_wing.csv"])
def test_samples_are_valid_observation_files(name):
    observations = io.read(SAMPLES / name, require_magnitudes=False)
    assert len(observations) == 300 and observations.meta["norad"] == "28868"
    assert set(observations.table["shadow"]) == {"sunlit"}
