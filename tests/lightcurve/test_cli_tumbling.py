"""CLI contract of `lightcurve period --tumbling` and `--drift`."""

import json

import numpy as np
import pandas as pd
import pytest

from benchmarks.glint_power import fixed_geometry_curve
from lightcurve.cli import main
from tests.lightcurve._spin_down import spin_down_nights

TWO_PERIOD_KEYS = {
    "periods_h",
    "precession_period_h",
    "rotation_period_h",
    "mode",
    "tumbling",
    "delta_bic",
    "combinations",
}


COLUMNS = ["mjd", "mag", "mag_err", "sun_x", "sun_y", "sun_z", "obs_x", "obs_y", "obs_z"]


def _write(path, t, mag, sigma=0.01):
    fixed_geometry_curve(t, mag, sigma, path.name).table[COLUMNS].to_csv(path, index=False)
    return path


@pytest.fixture
def tumbler_file(tmp_path):
    rng = np.random.default_rng(2)
    t = np.sort(rng.uniform(0, 4 * 3600, 600))
    p1, p2 = 2 * np.pi * t / 700.0, 2 * np.pi * t / 1900.0
    mag = 0.3 * np.cos(2 * p1) + 0.1 * np.cos(p2 + 0.3) + 0.08 * np.cos(p1 - p2)
    return _write(tmp_path / "tumbler.csv", t, mag + rng.normal(0, 0.01, len(t)))


def test_tumbling_summary_keys_and_plot(tumbler_file, tmp_path, capsys):
    out = tmp_path / "out"
    args = ["period", str(tumbler_file), "--range", "0.05", "2", "--tumbling", "--out", str(out)]
    assert main(args) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary) >= TWO_PERIOD_KEYS
    assert summary["tumbling"] is True and summary["delta_bic"] > 10
    periods = sorted(p["period_h"] * 3600 for p in summary["periods_h"])
    assert periods == pytest.approx([700.0, 1900.0], rel=1e-3)
    assert all(p["sigma_h"] > 0 for p in summary["periods_h"])
    assert {"period_h", "sigma_h"} == set(summary["precession_period_h"])
    assert summary["mode"] in ("SAM", "LAM", "undetermined")
    assert {"j", "k", "period_h", "amplitude_mag"} <= set(summary["combinations"][0])
    assert (out / "tumbling_periodogram.png").stat().st_size > 1000
    assert "two periods" in capsys.readouterr().out


def test_without_tumbling_a_residual_structure_only_suggests_it(tumbler_file, tmp_path):
    out = tmp_path / "out"
    assert main(["period", str(tumbler_file), "--range", "0.05", "2", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["tumbling"] is None and summary["periods_h"] is None
    assert "try --tumbling" in summary["two_period_note"]
    assert not (out / "tumbling_periodogram.png").exists()


def test_drift_table_plot_and_derivative(tmp_path):
    files = []
    for k, night in enumerate(spin_down_nights(3)):
        files.append(tmp_path / f"n{k}.csv")
        night.table[COLUMNS].to_csv(files[-1], index=False)
    out = tmp_path / "out"
    args = ["period", *map(str, files), "--range", "0.12", "0.25", "--drift", "--out", str(out)]
    assert main(args) == 0
    summary = json.loads((out / "summary.json").read_text())
    derivative = summary["period_derivative_s_per_day"]
    assert derivative["value"] == pytest.approx(6.0, rel=0.05) and derivative["sigma"] > 0
    # Without --tumbling the two-period search does not run: its keys are null.
    assert summary["tumbling"] is None and summary["periods_h"] is None
    table = pd.read_csv(out / "night_periods.csv")
    assert list(table.columns) == ["file", "series", "mjd", "period_h", "sigma_h", "systematic_h"]
    assert len(table) == 3
    assert (out / "night_periods.png").stat().st_size > 1000


def test_bad_options_and_files(tumbler_file, tmp_path, capsys):
    out = str(tmp_path / "out")
    assert main(["period", str(tumbler_file), "--quadratic", "--out", out]) == 2
    assert "--quadratic needs --drift" in capsys.readouterr().err
    assert main(["period", str(tumbler_file), "--drift", "--range", "0.05", "2", "--out", out]) == 2
    assert "at least 2" in capsys.readouterr().err
