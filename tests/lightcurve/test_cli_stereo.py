"""``lightcurve stereo``: the shipped scenario, the summary contract and scenario errors."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from filters.attitude import tanh_from_inertia
from lightcurve.cli import main
from lightcurve.scenarios.stereo import load_stereo_scenario
from tests.lightcurve._scenarios import SCENARIOS, edited_copy

NOMINAL = SCENARIOS / "stereo_nominal.toml"
RTMSE_KEYS = {"attitude_deg", "omega_rad_s", "position_m", "velocity_m_s", "inertia_k"}


def short_copy(tmp_path: Path, text: str | None = None) -> Path:
    """The nominal scenario (or ``text``) with a 20 s simulation and a 10 s window."""
    cut = {r"duration_s = [0-9.]+": "duration_s = 20.0", r"window_s = [0-9.]+": "window_s = 10.0"}
    return edited_copy(tmp_path, NOMINAL, cut, text=text, name="short.toml")


def test_nominal_scenario_is_the_papers_nominal_case():
    sc = load_stereo_scenario(NOMINAL)
    assert sc.feature_count == 4
    assert sc.target_size == 1.0
    assert sc.angle_noise == 1e-5
    assert sc.duration - sc.window >= 0 and sc.window == 3000.0  # last 50 min
    assert sc.features.shape == (4, 3)
    # ẏ0 = −2 n x0: the relative orbit does not drift, so the target stays in view.
    assert sc.velocity[1] == pytest.approx(-2 * sc.mean_motion * sc.position[0])
    assert 2 * math.pi / sc.mean_motion < sc.duration
    assert np.all(np.isfinite(tanh_from_inertia(sc.inertia)))


def test_cli_writes_summary_and_history(tmp_path, capsys):
    scenario = short_copy(tmp_path)
    out = tmp_path / "out"
    assert main(["stereo", str(scenario), "--runs", "3", "--out", str(out), "--seed", "7"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["rtmse"]) == RTMSE_KEYS
    assert summary["runs"] == 3 and summary["seed"] == 7
    assert all(v > 0 and math.isfinite(v) for v in summary["rtmse"].values())
    assert summary["nees"]["dof"] == 14
    low, high = summary["nees"]["band_95"]
    assert low < 14 < high
    history = pd.read_csv(out / "history.csv")
    assert len(history) == 20 and "sigma_attitude_deg" in history
    assert "RTMSE attitude" in capsys.readouterr().out
    assert not list(out.glob(".*.tmp"))

    again = tmp_path / "again"
    main(["stereo", str(scenario), "--runs", "3", "--out", str(again), "--seed", "7"])
    assert json.loads((again / "summary.json").read_text())["rtmse"] == summary["rtmse"]


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (("angle_rad = 1.0e-5", "angle_rad = -1.0"), r"\[noise\] angle_rad: must be positive"),
        (("feature_count = 4", "feature_count = 13"), r"feature_count must be between 3 and"),
        (("baseline_m = 1.0", 'baseline_m = "1 m"'), r"\[camera\] baseline_m: must be a number"),
        (("size_m = 1.0", "size_meters = 1.0"), r"\[target\] size_m: missing field"),
        (("step_s = 1.0", "step_s = 1.0\nstepsize = 2"), r"\[simulation\] stepsize: unknown field"),
        (("[orbit]", "[orbit\n"), r"not valid TOML"),
    ],
)
def test_bad_scenarios_name_file_and_field(tmp_path, capsys, edit, message):
    scenario = short_copy(tmp_path, NOMINAL.read_text().replace(*edit, 1))
    code = main(["stereo", str(scenario), "--runs", "1", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 2
    assert "short.toml" in err and re.search(message, err), err
    assert not (tmp_path / "o" / "summary.json").exists()


def test_missing_file_and_bad_runs(tmp_path, capsys):
    assert main(["stereo", str(tmp_path / "nope.toml"), "--out", str(tmp_path)]) == 2
    assert "nope.toml" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_info:
        main(["stereo", str(NOMINAL), "--runs", "0", "--out", str(tmp_path / "o")])
    assert exit_info.value.code == 2 and not (tmp_path / "o").exists()
    assert "argument --runs: must be at least 1, got 0" in capsys.readouterr().err
