"""`lightcurve calibrate` and `simulate --calibration` through the public commands."""

import json

import numpy as np
import pandas as pd
import pytest
from astropy.time import Time

from lightcurve.cli import main

NOISE = 0.02
TRUTH = {"bus": {"rd": 0.26, "rs": 0.4}}


def _geometry(folder, start):
    path = folder / f"geo_{start[:10]}.csv"
    argv = ["geometry", "--start", start, "--duration", "3600", "--cadence", "20"]
    assert main([*argv, "--geo", "-100", "--name", "bw", "--out", str(path)]) == 0
    return path


@pytest.fixture(scope="module")
def nights(tmp_path_factory):
    """Three GEO nights of a nadir-pointing box-wing whose bus differs from the library's
    and whose brightness is 0.3 mag fainter, simulated through `simulate --calibration`."""
    folder = tmp_path_factory.mktemp("calibrate")
    from shapes import get_library

    library = get_library().load("box_wing")
    materials = {
        group: {"brdf": m.brdf, "params": {**m.params, **TRUTH.get(group, {})}, "name": m.name}
        for group, m in library.materials.items()
    }
    truth = folder / "truth.json"
    truth.write_text(
        json.dumps(
            {
                "shape": "box_wing",
                "magnitude_offset": 0.3,
                "offset_deg": [0, 0, 0],
                "materials": materials,
            }
        )
    )
    files = []
    for k, start in enumerate(
        ("2024-03-10T05:00:00", "2024-03-14T04:00:00", "2024-03-20T06:00:00")
    ):
        out = folder / f"night{k}.csv"
        argv = ["simulate", str(_geometry(folder, start)), "--shape", "box_wing"]
        argv += ["--profile", "nadir", "--yaw-steering", "--noise-mag", str(NOISE)]
        argv += ["--seed", str(k), "--calibration", str(truth), "--out", str(out)]
        assert main(argv) == 0
        files.append(out)
    return folder, files


def test_calibrate_recovers_the_bus_and_the_scale_within_2_sigma(nights, capsys):
    folder, files = nights
    out = folder / "fit"
    argv = ["calibrate", *map(str, files), "--shape", "box_wing", "--profile", "nadir"]
    argv += ["--yaw-steering", "--fit", "scale,material", "--parameters", "bus.rd,bus.rs"]
    assert main([*argv, "--folds", "3", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    for key, true in (("bus.rd", 0.26), ("bus.rs", 0.4), ("magnitude_offset", 0.3)):
        entry = summary["parameters"][key]
        assert abs(entry["value"] - true) <= 2.0 * entry["sigma"], (key, entry)
    assert summary["cv_rms_mag"] < 1.5 * NOISE
    assert summary["nights"] == 3 and len(summary["folds"]) == 3
    assert set(summary) >= {"train_rms_mag", "cv_rms_mag", "cv_bias_mag", "unconstrained"}
    # the calibration simulates the object back: the same light curve as the truth's
    again = folder / "again.csv"
    argv = ["simulate", str(folder / "geo_2024-03-10.csv"), "--shape", "box_wing"]
    argv += ["--profile", "nadir", "--yaw-steering", "--calibration"]
    assert main([*argv, str(out / "calibration.json"), "--out", str(again)]) == 0
    assert main([*argv, str(folder / "truth.json"), "--out", str(folder / "exact.csv")]) == 0
    from lightcurve import io

    difference = io.read(again).magnitudes - io.read(folder / "exact.csv").magnitudes
    assert np.sqrt(np.mean(difference**2)) < NOISE


def test_bad_requests_get_one_clean_line(nights, capsys):
    folder, files = nights
    base = ["calibrate", str(files[0]), "--shape", "box_wing", "--profile", "nadir"]
    out = ["--out", str(folder / "bad")]
    assert main([*base, "--fit", "scale,colour", *out]) != 0
    assert "--fit: unknown item(s) colour" in capsys.readouterr().err
    assert main([*base, "--fit", "scale", "--parameters", "bus.rd", *out]) != 0
    assert "--parameters goes with --fit material" in capsys.readouterr().err
    assert main([*base, "--parameters", "hull.rd", *out]) != 0
    assert "no material group 'hull'" in capsys.readouterr().err
    bad = folder / "bad.json"
    bad.write_text("{}")
    argv = ["simulate", str(files[0]), "--shape", "box_wing", "--profile", "nadir"]
    assert main([*argv, "--calibration", str(bad), "--out", str(folder / "x.csv")]) != 0
    assert "not a calibration file" in capsys.readouterr().err
    assert main([*base, "--fit", "scale,articulation", *out]) != 0
    assert "--fit articulation: box_wing has no moving parts" in capsys.readouterr().err
    with pytest.raises(SystemExit):  # argparse's own one line
        main([*base, "--earthshine", "sometimes", *out])
    assert "invalid choice: 'sometimes'" in capsys.readouterr().err


def test_a_tracking_array_s_offset_through_the_public_commands(tmp_path):
    """simulate (a box-wing whose arrays track the Sun 8° off, LEO passes with the Earth's
    light) → calibrate --fit scale,articulation → simulate --calibration: the offset is
    recovered within 2σ and the calibrated model reproduces the truth's light curve."""
    from lightcurve import io

    geometry = tmp_path / "leo.csv"
    argv = ["geometry", "--start", "2024-06-10T02:00:00", "--duration", "21600"]  # 83 epochs
    argv += ["--cadence", "10", "--radius", "6928", "--inclination", "53", "--raan", "180"]
    argv += ["--name", "sat", "--out", str(geometry)]
    assert main(argv) == 0
    truth = tmp_path / "truth.json"
    truth.write_text(
        json.dumps(
            {
                "shape": "box_wing_tracking",
                "magnitude_offset": 0.2,
                "offset_deg": [0, 0, 0],
                "joint_offsets_deg": {"arrays": 8.0},
                "earthshine": True,
                "materials": {},
            }
        )
    )
    observed = tmp_path / "observed.csv"
    fly = ["--shape", "box_wing_tracking", "--profile", "nadir", "--shadows", "none"]
    argv = ["simulate", str(geometry), *fly, "--noise-mag", str(NOISE), "--calibration"]
    assert main([*argv, str(truth), "--out", str(observed)]) == 0
    assert "earthshine_fraction" in io.read(observed).table
    fit = tmp_path / "fit"
    argv = ["calibrate", str(observed), *fly, "--fit", "scale,articulation", "--out", str(fit)]
    assert main(argv) == 0
    summary = json.loads((fit / "summary.json").read_text())
    assert summary["earthshine"] is True
    for key, true in (("arrays.joint_offset_deg", 8.0), ("magnitude_offset", 0.2)):
        entry = summary["parameters"][key]
        assert abs(entry["value"] - true) <= 2.0 * entry["sigma"], (key, entry)
    again, exact = tmp_path / "again.csv", tmp_path / "exact.csv"
    argv = ["simulate", str(geometry), *fly, "--calibration"]
    assert main([*argv, str(fit / "calibration.json"), "--out", str(again)]) == 0
    assert main([*argv, str(truth), "--out", str(exact)]) == 0
    difference = io.read(again).magnitudes - io.read(exact).magnitudes
    assert np.sqrt(np.mean(difference**2)) < NOISE


def test_the_pomenis_workflow_through_the_public_commands(tmp_path, capsys):
    """import → calibrate (the built-in Starlink, yaw-steered nadir profile) gives the
    calibration of the dataset module's own attitude law, and a calibration on half the
    nights predicts the other half as the cross-validation does."""
    from lightcurve.datasets.starlink import (
        MOUNT_LEMMON,
        POMENIS_PATH,
        pomenis_geometry,
        read_pomenis,
        starlink_model,
    )
    from lightcurve.photometry.calibration import cross_validate, night_index

    text = POMENIS_PATH.read_text()
    comments = "".join(line + "\n" for line in text.splitlines() if line.startswith("#"))
    table = pd.read_csv(POMENIS_PATH, comment="#")
    night = night_index(
        Time(pd.to_datetime(table["observation_time"]).to_numpy()).mjd, MOUNT_LEMMON.longitude_deg
    )
    halves = []
    for k, rows in enumerate((night % 2 == 0, night % 2 == 1)):
        source, out = tmp_path / f"half{k}.csv", tmp_path / f"half{k}_obs.csv"
        source.write_text(comments + table[rows].to_csv(index=False))
        argv = ["import", str(source), "--time-column", "observation_time", "--time-format"]
        argv += ["iso", "--mag-column", "ab_magnitude", "--mag-err", "0.1", "--site"]
        argv += ["Mount Lemmon", "--alt-az-range-columns"]
        argv += ["satellite_altitude,satellite_azimuth,satellite_height", "--range-kind"]
        argv += ["height", "--allow-duplicate-epochs", "--out", str(out)]
        assert main(argv) == 0
        halves.append(out)
    fit = ["--shape", "starlink_v1_5", "--profile", "nadir", "--yaw-steering", "--shadows"]
    fit += ["none", "--parameters", "chassis.ab,solar_array.ab", "--starts", "1"]
    both = tmp_path / "both"
    argv = ["calibrate", *map(str, halves), *fit, "--folds", "5", "--out", str(both)]
    assert main(argv) == 0
    summary = json.loads((both / "summary.json").read_text())
    observations, q = pomenis_geometry(read_pomenis())
    reference = cross_validate(
        starlink_model(),
        q,
        observations,
        night_index(observations.mjd, MOUNT_LEMMON.longitude_deg),
        folds=5,
        parameters=["chassis.ab", "solar_array.ab"],
        shadows="none",
        starts=1,  # CLI and API compared start for start
    )
    assert summary["n_observations"] == 1173 and summary["nights"] == 79
    assert summary["train_rms_mag"] == pytest.approx(reference["train_rms_mag"], abs=0.01)
    assert summary["cv_rms_mag"] == pytest.approx(reference["cv_rms_mag"], abs=0.02)
    # calibrated on the even nights, the odd ones predicted through simulate --calibration
    even = tmp_path / "even"
    assert main(["calibrate", str(halves[0]), *fit, "--out", str(even)]) == 0
    predicted = tmp_path / "odd_predicted.csv"
    argv = ["simulate", str(halves[1]), "--shape", "starlink_v1_5", "--profile", "nadir"]
    argv += ["--yaw-steering", "--shadows", "none", "--calibration"]
    assert main([*argv, str(even / "calibration.json"), "--out", str(predicted)]) == 0
    from lightcurve import io

    measured, model = io.read(halves[1]), io.read(predicted)
    common = np.intersect1d(measured.mjd, model.mjd)
    residual = (
        measured.table.set_index("mjd").loc[common, "mag"].to_numpy()
        - model.table.drop_duplicates("mjd").set_index("mjd").loc[common, "mag"].to_numpy()
    )
    assert abs(np.sqrt(np.mean(residual**2)) - summary["cv_rms_mag"]) < 0.1
