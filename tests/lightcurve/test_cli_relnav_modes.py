"""``lightcurve relnav`` with the per-mode scenarios: relative GNSS from raw measurements."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pandas as pd
import pytest

from lightcurve.cli import main
from lightcurve.scenarios.relnav import load_relnav_scenario
from tests.lightcurve._scenarios import SCENARIOS, edited_copy

GNSS_KEYS = {
    "position_rms_m",
    "velocity_rms_m_s",
    "ambiguity_fix_rate",
    "wrong_fix_rate",
    "time_to_first_fix_s",
    "mode_time_fractions",
}


def short_copy(tmp_path: Path, name: str, edit: tuple[str, str] | None = None) -> Path:
    """A scenario cut to 100 s (70 s transfer), next to the shipped one's almanac path."""
    source = SCENARIOS / name
    text = source.read_text().replace('"../gnss/', f'"{SCENARIOS.parent / "gnss"}/')
    if edit is not None:
        text = text.replace(*edit, 1)
    cut = {
        r"duration_s = 6000.0": "duration_s = 100.0",
        r"approach_duration_s = [0-9.]+": "approach_duration_s = 70.0",
    }
    return edited_copy(tmp_path, source, cut, text=text)


def test_each_mode_scenario_defines_the_three_modes():
    for name, mode in (
        ("relnav_cooperative.toml", "cooperative"),
        ("relnav_non_cooperative.toml", "non-cooperative"),
        ("relnav_semi_cooperative.toml", "semi-cooperative"),
    ):
        sc, _ = load_relnav_scenario(SCENARIOS / name)
        assert sc.mode == mode
        assert set(sc.modes) == {"cooperative", "non-cooperative", "semi-cooperative"}
        assert sc.sensors["lidar"].backup == "stereo"
        rgnss = sc.sensors["rgnss"]
        assert rgnss.almanac.size == 30 and rgnss.solver.ratio_threshold == 3.0
    semi, _ = load_relnav_scenario(SCENARIOS / "relnav_semi_cooperative.toml")
    assert semi.sensors["rgnss"].chaser_receiver.obstructions[0][:2] == (3000.0, 3300.0)


@pytest.mark.parametrize("mode", ["cooperative", "non-cooperative", "semi-cooperative"])
def test_cli_runs_every_mode(tmp_path, capsys, mode):
    scenario = short_copy(tmp_path, "relnav_cooperative.toml")
    out = tmp_path / mode
    assert main(["relnav", str(scenario), "--out", str(out), "--mode", mode]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary) >= GNSS_KEYS and summary["mode"] == mode
    fractions = summary["mode_time_fractions"]
    assert sum(fractions.values()) == pytest.approx(1.0)
    errors = pd.read_csv(out / "errors.csv")
    assert set(errors["mode"]) == set(fractions)
    printed = capsys.readouterr().out
    if mode == "non-cooperative":
        assert summary["ambiguity_fix_rate"] is None and set(fractions) <= {"lidar", "imu-only"}
    else:
        assert summary["ambiguity_fix_rate"] > 0.5 and summary["wrong_fix_rate"] == 0.0
        assert summary["time_to_first_fix_s"] <= 60.0 and "ambiguities fixed in" in printed
        assert summary["position_rms_m"] < 0.02


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (('almanac = "', 'almanac = "missing/'), r"\[sensors.rgnss\] almanac: cannot read"),
        (("code_sigma_m = 0.5", "code_sigma_m = -0.5"), r"code_sigma_m: must be positive"),
        (("ratio_threshold = 3.0", "ratio_treshold = 3.0"), r"ratio_threshold: missing field"),
        (('kind = "rgnss"', 'kind = "radar"'), r"\[sensors.rgnss\] kind: must be one of"),
        (('backup = "stereo"', 'backup = "camera"'), r"unknown backup 'camera'"),
        (("elevation_mask_deg = 10.0", "elevation_mask_deg = 10.0\nchaser_obstructions = "
          "[[300.0, 200.0, 60.0]]"), r"chaser_obstructions: each window needs t_start < t_end"),
    ],
)  # fmt: skip
def test_bad_gnss_fields_name_file_and_field(tmp_path, capsys, edit, message):
    scenario = short_copy(tmp_path, "relnav_cooperative.toml", edit)
    assert main(["relnav", str(scenario), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "relnav_cooperative.toml" in err and re.search(message, err), err
