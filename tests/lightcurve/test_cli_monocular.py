"""``lightcurve monocular``: the summary contract, Monte Carlo, external data and bad input."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from filters.attitude import attitude_angle, propagate
from lightcurve.cli import main
from lightcurve.scenarios import ScenarioError
from lightcurve.scenarios.monocular import load_monocular_scenario, read_measurements
from tests.lightcurve._scenarios import SCENARIOS, edited_copy

CONTRACT = {
    "observability_rank",
    "observability_singular_values",
    "L",
    "L_sigma",
    "omega_rad_s",
    "quaternion",
    "converged",
    "attitude_error_deg",
    "omega_error_rad_s",
    "L_error",
}


def short_copy(tmp_path: Path, name: str, duration: float) -> Path:
    """A shipped scenario with a shorter run and a low Lie-derivative order (fast)."""
    source = SCENARIOS / name
    text = source.read_text() + "\n[observability]\nmax_order = 4\n"
    return edited_copy(
        tmp_path, source, {r"duration_s = [0-9.]+": f"duration_s = {duration}"}, text=text
    )


def test_shipped_scenarios_are_the_papers():
    a = load_monocular_scenario(SCENARIOS / "nutation.toml")
    assert np.allclose(a.truth.inertia, [[0.85, 0.13, 0.17], [0.13, 1.37, -0.11], [0.17, -0.11, 1]])
    assert np.allclose(np.degrees(a.truth.omega0), [5.0, 2.3, 3.5])
    assert np.allclose(a.x0[4:7], np.radians([0.5, 0.23, 0.35]))
    assert np.allclose(a.x0[7:], [0.7, 0.7, 0, 0, 0])
    assert np.allclose(a.q, 1e-3 * np.eye(11)) and np.allclose(a.r, 1e-3 * np.eye(3))
    b = load_monocular_scenario(SCENARIOS / "pure_spin.toml")
    assert np.allclose(b.truth.inertia, np.diag([0.85, 1.37, 1.0]))
    assert np.allclose(np.degrees(b.truth.omega0), [0.0, 2.3, 0.0])
    assert np.allclose(b.x0, a.x0) and np.allclose(b.q, a.q) and np.allclose(b.r, a.r)
    p = load_monocular_scenario(SCENARIOS / "nutation_pixels.toml")
    assert p.mode == "pixels" and p.pixels.camera.width == 1024 and p.pixels.pixel_sigma == 0.1


def test_nutation_run_writes_the_summary_contract(tmp_path):
    scenario = short_copy(tmp_path, "nutation.toml", 150.0)
    out = tmp_path / "a"
    assert main(["monocular", str(scenario), "--out", str(out), "--runs", "3", "--seed", "4"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary) >= CONTRACT
    assert "unobservable_directions" not in summary
    assert summary["observability_rank"] == 11
    assert len(summary["L"]) == len(summary["L_sigma"]) == len(summary["L_error"]) == 5
    assert summary["attitude_error_deg"] < 0.5
    # 150 s is too short for the inertia (success needs ~1500 s): it must not claim success.
    assert summary["success"] is False and summary["converged"] is False
    mc = summary["monte_carlo"]
    assert mc["runs"] == 3 and 0.0 <= mc["success_rate"] <= 1.0
    assert set(mc["rms"]) >= {"attitude_deg", "omega_rad_s", "Lxx", "Lyz"}
    table = pd.read_parquet(out / "estimates.parquet")
    assert len(table) == 3 * 151 and set(table["run"]) == {0, 1, 2}
    assert {"q1", "wx", "Lxx", "sigma_Lxx", "nis", "true_q1"} <= set(table.columns)
    for figure in ("quaternion.png", "rates.png", "inertia.png", "errors.png"):
        assert (out / figure).stat().st_size > 10_000


def test_pure_spin_reports_weak_observability(tmp_path):
    scenario = short_copy(tmp_path, "pure_spin.toml", 200.0)
    out = tmp_path / "b"
    assert main(["monocular", str(scenario), "--out", str(out), "--no-plots"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["observability_rank"] == 8 and summary["converged"] is False
    directions = summary["unobservable_directions"]
    assert [list(d) for d in directions] == [["Lxx"], ["Lyy"], ["Lxz"]]
    assert all(abs(d[name] - 1.0) < 1e-9 for d in directions for name in d)
    assert "no inertia result claimed" in summary["assessment"]
    assert summary["observability_singular_values"][8] < 1e-12


def test_external_measurements_run_without_truth(tmp_path):
    t = np.arange(0.0, 101.0)
    states = propagate(np.r_[0, 0, 0, 1.0, np.radians([5.0, 2.3, 3.5])], t, np.diag([1, 2, 3.0]))
    csv = tmp_path / "q.csv"
    frame = pd.DataFrame({"t": t, **{f"q{i + 1}": states[:, i] for i in range(4)}})
    frame.loc[10, ["q1", "q2", "q3", "q4"]] = np.nan  # a gap
    frame.to_csv(csv, index=False)
    out = tmp_path / "ext"
    scenario = short_copy(tmp_path, "nutation.toml", 100.0)
    assert main(["monocular", str(scenario), "--out", str(out), "--measurements", str(csv)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["measurement_mode"] == "external"
    assert "attitude_error_deg" not in summary and summary["epochs"] == 101
    assert summary["observability_evaluated_at"] == "final estimate"
    # The filter follows the (noise-free) measurements closely.
    assert np.degrees(attitude_angle(summary["quaternion"], states[-1, :4])) < 0.5
    assert np.linalg.norm(np.subtract(summary["omega_rad_s"], states[-1, 4:])) < 0.01


@pytest.mark.parametrize(
    ("old", "new", "message"),
    [
        ("sigma_deg = 0.05", "sigma_dg = 0.05", r"\[measurement\] sigma_d"),
        ("inertia0 = [0.7, 0.7, 0.0, 0.0, 0.0]", "inertia0 = [0.7, 0.7]", r"\[filter\] inertia0"),
        ('form = "L"', 'form = "J"', r"\[filter\] form: must be one of"),
        ("[0.17, -0.11, 1.0]]", "[0.17, -0.11, -1.0]]", r"\[truth\] inertia: .*positive definite"),
        ("process_noise = 0.001", "process_noise = -1", r"\[filter\] process_noise"),
    ],
)
def test_bad_scenarios_name_the_field(tmp_path, capsys, old, new, message):
    text = (SCENARIOS / "nutation.toml").read_text()
    assert old in text
    path = tmp_path / "bad.toml"
    path.write_text(text.replace(old, new))
    assert main(["monocular", str(path), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert re.search(message, err) and "bad.toml" in err
    assert not (tmp_path / "o" / "summary.json").exists()


@pytest.mark.parametrize("runs", ["0", "-3", "two"])
def test_bad_run_count_is_caught_before_the_scenario_is_read(tmp_path, capsys, runs):
    """A run count below 1 (or not a number) stops at parsing, one line, nothing written."""
    with pytest.raises(SystemExit) as exit_info:
        main(
            ["monocular", str(tmp_path / "nope.toml"), "--out", str(tmp_path / "o"), "--runs", runs]
        )
    err = capsys.readouterr().err
    assert exit_info.value.code == 2 and "argument --runs:" in err and "nope.toml" not in err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("t,q1,q2,q3,q4\n0,0,0,0,1\n1,0,0,x,1\n", r"line 3, column q3"),
        ("t,q1,q2,q3,q4\n0,0,0,0,1\n0,0,0,0,1\n", r"line 3, column t: times must increase"),
        ("t,q1,q2,q3\n0,0,0,0\n1,0,0,0\n", "missing column"),
    ],
)
def test_bad_measurement_rows_name_line_and_column(tmp_path, text, message):
    csv = tmp_path / "m.csv"
    csv.write_text(text)
    with pytest.raises(ScenarioError, match=message):
        read_measurements(csv)


def test_pixel_mode_runs_end_to_end(tmp_path):
    scenario = short_copy(tmp_path, "nutation_pixels.toml", 30.0)
    out = tmp_path / "pix"
    assert main(["monocular", str(scenario), "--out", str(out), "--no-plots"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    pixels = summary["pixels"]
    assert pixels["tracked_points_min"] >= 20 and pixels["failed_frames"] == 0
    assert pixels["pair_error_deg_max"] < 0.2
    assert summary["attitude_error_deg"] < 0.5


def test_unknown_library_shape_names_the_field(tmp_path, capsys):
    text = (SCENARIOS / "nutation_pixels.toml").read_text()
    path = tmp_path / "shape.toml"
    path.write_text(text.replace('shape = "bennu"', 'shape = "benu"'))
    assert main(["monocular", str(path), "--out", str(tmp_path / "o")]) == 2
    assert "[measurement.target] shape: no library shape 'benu'" in capsys.readouterr().err
