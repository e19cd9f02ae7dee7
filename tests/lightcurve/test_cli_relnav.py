"""``lightcurve relnav``: the shipped scenario, the summary contract, modes and errors."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from lightcurve.cli import main
from lightcurve.scenarios.relnav import load_relnav_scenario
from tests.lightcurve._scenarios import SCENARIOS, edited_copy

APPROACH = SCENARIOS / "relnav_approach.toml"
CONTRACT = {"position_rms_m", "velocity_rms_m_s", "outliers_injected", "outliers_downweighted"}


def short_copy(tmp_path: Path, text: str | None = None) -> Path:
    """The approach scenario (or ``text``) cut to 120 s with a 100 s transfer."""
    cut = {
        r"duration_s = 6000.0": "duration_s = 120.0",
        r"approach_duration_s = [0-9.]+": "approach_duration_s = 100.0",
    }
    return edited_copy(tmp_path, APPROACH, cut, text=text, name="short.toml")


def test_shipped_scenario_is_the_papers():
    sc, seed = load_relnav_scenario(APPROACH)
    np.testing.assert_allclose(sc.start, [-10, 0, 0])
    np.testing.assert_allclose(sc.hold, [-1, 0, 0])
    assert sc.duration == 6000.0 and sc.imu_period == 0.16
    lidar = sc.sensors["lidar"]
    assert (lidar.sigma, lidar.period, lidar.optical) == (0.05, 1.0, True)
    assert sc.modes["cooperative"] == ("gnss",)
    assert sc.modes["non-cooperative"] == ("lidar",)
    assert set(sc.modes["semi-cooperative"]) == {"lidar", "gnss"}
    assert sc.mode == "non-cooperative" and seed == 0


def test_cli_summary_contract_and_outliers(tmp_path, capsys):
    scenario = short_copy(tmp_path)
    out = tmp_path / "gross"
    args = ["relnav", str(scenario), "--out", str(out), "--outlier-rate", "0.2"]
    assert main([*args, "--outlier-size", "3", "--robust", "huber"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary) >= CONTRACT
    assert summary["fixes"] == 120
    assert 12 < summary["outliers_injected"] < 36
    assert summary["outliers_downweighted"] >= 0.9 * summary["outliers_injected"]
    assert summary["mode"] == "non-cooperative" and summary["robust"] == "huber"
    errors = pd.read_csv(out / "errors.csv")
    assert len(errors) == 751 and {"time_s", "error_x", "sigma_vz", "true_x"} <= set(errors)
    assert "position RMS" in capsys.readouterr().out

    plain = tmp_path / "plain"
    main(
        ["relnav", str(scenario), "--out", str(plain), "--outlier-rate", "0.2", "--robust", "none"]
    )
    plain_summary = json.loads((plain / "summary.json").read_text())
    assert plain_summary["outliers_injected"] == summary["outliers_injected"]  # same seed
    assert plain_summary["outliers_downweighted"] == 0
    assert plain_summary["position_rms_m"] > 3 * summary["position_rms_m"]


def test_cli_mode_and_seed_override(tmp_path):
    scenario = short_copy(tmp_path)
    out = tmp_path / "coop"
    assert (
        main(["relnav", str(scenario), "--out", str(out), "--mode", "cooperative", "--seed", "4"])
        == 0
    )
    summary = json.loads((out / "summary.json").read_text())
    assert summary["sensors"] == ["gnss"] and summary["seed"] == 4


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (('mode = "non-cooperative"', 'mode = "docking"'), r"mode: must be one of"),
        (("sigma_m = 0.05", "sigma_m = 0.0"), r"\[sensors.lidar\] sigma_m: must be positive"),
        (('cooperative = ["gnss"]', 'cooperative = ["radar"]'),
         r"\[modes\] cooperative: unknown sensor"),
        (("damping = 0.9", "dampin = 0.9"), r"\[control\] damping: missing field"),
        (("settle_s = 60.0", "settle_s = 500.0"), r"settle"),
    ],
)  # fmt: skip
def test_bad_scenarios_name_file_and_field(tmp_path, capsys, edit, message):
    scenario = short_copy(tmp_path, APPROACH.read_text().replace(*edit, 1))
    assert main(["relnav", str(scenario), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "short.toml" in err and re.search(message, err), err


@pytest.mark.parametrize(
    ("option", "message"),
    [
        (["--outlier-rate", "1.5"], "--outlier-rate"),
        (["--outlier-size", "-1"], "--outlier-size"),
        (["--mode", "docking"], "--mode 'docking'"),
    ],
)
def test_bad_options(tmp_path, capsys, option, message):
    assert main(["relnav", str(short_copy(tmp_path)), "--out", str(tmp_path / "o"), *option]) == 2
    assert message in capsys.readouterr().err
