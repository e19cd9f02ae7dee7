"""CLI contract of `lightcurve period`, `lightcurve glint` and `lightcurve convex`."""

import json

import numpy as np
import pandas as pd
import pytest

from lightcurve import io
from lightcurve.cli import main
from lightcurve.io.observations import Observations, validate_table
from shapes import load

ARIADNE = "data/ariadne/test_lcs_rel"


@pytest.fixture(scope="module")
def ariadne_subset(tmp_path_factory):
    """Three 1973 nights of Ariadne, every other point, as a CSV observation file."""
    obs = io.read(ARIADNE)
    keep = np.isin(obs.lightcurve_ids, [3, 4, 7])
    table = obs.table.loc[keep].iloc[::2].reset_index(drop=True)
    path = tmp_path_factory.mktemp("data") / "ariadne_1973.csv"
    io.write(Observations(table, obs.meta, obs.source), path)
    return path


@pytest.fixture(scope="module")
def flashes(tmp_path_factory):
    """A slowly varying curve with four flashes 150 s apart (a tumbling panel)."""
    rng = np.random.default_rng(1)
    t = np.arange(0.0, 900.0, 2.0)
    flash = sum(-0.8 * np.exp(-0.5 * ((t - e) / 5.0) ** 2) for e in (200, 350, 500, 650))
    table = pd.DataFrame(
        {
            "mjd": 60000 + t / 86400,
            "mag": 9 + 0.1 * np.sin(t / 300) + flash + rng.normal(0, 0.01, len(t)),
            "mag_err": 0.01,
            "sun_x": 1.5e8,
            "sun_y": 0.0,
            "sun_z": 0.0,
            "obs_x": 0.0,
            "obs_y": 3.6e4,
            "obs_z": 3e3,
        }
    )
    path = tmp_path_factory.mktemp("data") / "flashes.csv"
    io.write(Observations(validate_table(table, "flashes"), {}), path)
    return path


def test_period_command_summary(ariadne_subset, tmp_path, capsys):
    out = tmp_path / "period"
    assert main(["period", str(ariadne_subset), "--range", "2", "12", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert {"period_h", "sigma_h", "aliases"} <= set(summary)
    periods = [summary["period_h"]] + [a["period_h"] for a in summary["aliases"]]
    assert min(abs(p / 5.762 - 1) for p in periods) < 2e-3
    assert all({"period_h", "chi2", "delta_chi2", "kind"} <= set(a) for a in summary["aliases"])
    curve = pd.read_csv(out / "periodogram.csv")
    assert list(curve.columns) == ["period_h", "chi2"] and len(curve) > 100
    assert (out / "periodogram.png").stat().st_size > 1000
    assert "period" in capsys.readouterr().out


def test_glint_command(flashes, tmp_path, capsys):
    out = tmp_path / "glint"
    assert main(["glint", str(flashes), "--normal", "--window", "300", "--out", str(out)]) == 0
    report = json.loads((out / "glints.json").read_text())
    assert len(report["glints"]) == 4
    assert report["glint_period_s"] == pytest.approx(150.0, abs=1.0)
    assert report["panel_normal"]["frame"] == "inertial"
    assert len(pd.read_csv(out / "glints.csv")) == 4
    assert "4 glint(s)" in capsys.readouterr().out
    # The body frame needs attitude columns, which this file has not.
    assert main(["glint", str(flashes), "--normal", "--frame", "body"]) == 2
    assert "q1..q4" in capsys.readouterr().err


def test_convex_command_writes_solutions_shape_and_fit(ariadne_subset, tmp_path, capsys):
    out = tmp_path / "convex"
    args = ["convex", str(ariadne_subset), "--period", "5.762", "--poles", "2"]
    args += ["--rows", "3", "--degree", "3", "--iterations", "8", "--plots", "--out", str(out)]
    assert main(args) == 0
    summary = json.loads((out / "summary.json").read_text())
    solutions = summary["solutions"]
    assert 1 <= len(solutions) <= 2
    for s in solutions:
        assert {"lambda_deg", "beta_deg", "period_h", "rms", "chi2"} <= set(s)
    assert [s["chi2"] for s in solutions] == sorted(s["chi2"] for s in solutions)
    shape = load(out / "shape.obj")
    assert shape.is_watertight and shape.volume == pytest.approx(1.0, rel=1e-6)
    fitted = pd.read_csv(out / "fit.csv")
    assert {"observed", "model", "mjd"} <= set(fitted.columns)
    assert (out / "shape.png").exists() and (out / "fit.png").exists()
    assert "pole (" in capsys.readouterr().out
    # The shape library accepts the model.
    library = str(tmp_path / "library")
    assert main(["shapes", "--library", library, "add", "ariadne", str(out / "shape.obj")]) == 0


def test_convex_period_scan(ariadne_subset, tmp_path):
    out = tmp_path / "scan"
    args = ["convex", str(ariadne_subset), "--period-range", "5.755", "5.770", "--poles", "2"]
    args += ["--rows", "3", "--degree", "3", "--iterations", "5", "--refine", "2"]
    assert main([*args, "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["scan"]["pole_starts"] == 2
    scan = pd.read_csv(out / "scan.csv")
    assert len(scan) == summary["scan"]["periods"] and scan["period_h"].is_monotonic_increasing
    assert not (out / "shape.png").exists() and not (out / "fit.png").exists()  # no --plots


def test_user_errors_are_one_line(ariadne_subset, tmp_path, capsys):
    assert main(["convex", str(ariadne_subset), "--out", str(tmp_path / "x")]) == 2
    assert "--period" in capsys.readouterr().err
    bad = ["convex", str(ariadne_subset), "--period", "5", "--free", "q", "--out", str(tmp_path)]
    assert main(bad) == 2
    assert "--free" in capsys.readouterr().err
    assert main(["period", str(tmp_path / "missing.csv"), "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert "missing.csv" in err and err.count("\n") == 0
