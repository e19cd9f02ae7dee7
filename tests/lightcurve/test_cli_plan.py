"""``lightcurve plan``: the shipped Eros scenario, the summary contract and scenario errors."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from filters.navigation.gravity import EROS_MU
from lightcurve.cli import main
from lightcurve.scenarios.landing import load_scenario

EROS = Path(__file__).resolve().parents[2] / "data" / "scenarios" / "eros_landing.toml"
STRATEGIES = ("every_step", "fisher_trace", "improved")


def edited(tmp_path: Path, *replacements: tuple[str, str]) -> Path:
    """A copy of the Eros scenario with regex replacements applied."""
    text = EROS.read_text()
    for pattern, new in replacements:
        text, count = re.subn(pattern, new, text, flags=re.MULTILINE)
        assert count == 1, pattern
    path = tmp_path / "scenario.toml"
    path.write_text(text)
    return path


def short(tmp_path: Path) -> Path:
    """A 12 s descent with statistics after 6 s (same start, faster descent)."""
    return edited(
        tmp_path,
        (r"^duration_s = .*$", "duration_s = 12.0"),
        (r"^settle_time_s = .*$", "settle_time_s = 6.0"),
    )


def test_shipped_scenario_is_the_papers_table_1_and_2():
    sc = load_scenario(EROS)
    model = sc.model
    assert model.dynamics.gravity.mu == EROS_MU == 446300.0
    assert model.dynamics.gravity.degree == 2
    assert sc.steps == 103 and model.dt == 1.0 and sc.settle_step == 50
    assert model.camera.width == model.camera.height == 1024
    assert 2 * math.degrees(math.atan(512 / model.camera.fx)) == pytest.approx(69.0)
    assert model.pixel_sigma == 0.06 and len(model.anchors) == 10
    np.testing.assert_allclose(sc.trajectory.start_position, [8, 5, 4])
    np.testing.assert_allclose(sc.trajectory.start_velocity, [-0.1, -0.1, -0.1])
    np.testing.assert_allclose(
        sc.initial_sigma, [1, 1, 1, 0.01, 0.01, 0.01, *[math.radians(2)] * 3]
    )
    assert np.linalg.norm(model.dynamics.spin) == pytest.approx(2 * math.pi / (5.27 * 3600))


def test_plan_writes_the_summary_contract(tmp_path, capsys):
    out = tmp_path / "out"
    assert (
        main(["plan", str(short(tmp_path)), "--out", str(out), "--runs", "3", "--seed", "4"]) == 0
    )
    assert "summary.json" in capsys.readouterr().out
    summary = json.loads((out / "summary.json").read_text())
    assert summary["runs"] == 3 and summary["seed"] == 4 and summary["settle_time_s"] == 6.0
    for name in STRATEGIES:
        entry = summary["strategies"][name]
        assert entry["images_total"] == 13
        for key in ("position_error_std_m", "velocity_error_std_m_s", "attitude_error_std_deg"):
            assert entry[key]["mean"] > 0 and entry[key]["spread"] >= 0
            assert len(entry[key]["per_axis_mean"]) == 3
        times = entry["observation_times_s"]
        assert len(times) == 3 and all(t[0] == 0.0 and t == sorted(t) for t in times)
        assert np.mean([len(t) for t in times]) == entry["images_used"]["mean"]
        assert entry["images_used"]["max"] <= 13
    assert summary["strategies"]["every_step"]["images_used"]["mean"] == 13
    trace_used = summary["strategies"]["fisher_trace"]["images_used"]["mean"]
    assert summary["strategies"]["improved"]["images_used"]["mean"] <= trace_used < 13
    gaps = np.diff(summary["strategies"]["fisher_trace"]["observation_times_s"][0])
    assert gaps.max() <= summary["s_max"]
    assert summary["comparison"]["fisher_trace_images_fraction"] == pytest.approx(trace_used / 13)
    assert summary["paper"]["images_used"] == {"fisher_trace": 55, "every_step": 104}


def test_same_seed_gives_the_same_summary(tmp_path):
    path = short(tmp_path)
    for name in ("a", "b"):
        assert main(["plan", str(path), "--out", str(tmp_path / name), "--runs", "2"]) == 0
    a, b = (json.loads((tmp_path / n / "summary.json").read_text()) for n in ("a", "b"))
    a.pop("elapsed_s"), b.pop("elapsed_s")
    assert a == b


@pytest.mark.parametrize(
    ("replacement", "message"),
    [
        ((r"^s_max = 2", "s_max = 0"), r"\[planner\] s_max: must be >= 1"),
        ((r"^spacing_m = .*$", "spacing_m = -1.0"), r"\[landmarks\] spacing_m: must be positive"),
        ((r"^step_s = .*$", "step_s = 0.7"), r"\[trajectory\] step_s: must divide"),
        ((r"^settle_time_s = .*$", "settle_time_s = 200.0"), r"\[planner\] settle_time_s"),
        ((r"^pixels = 1024", "pixel = 1024"), r"\[camera\] pixels: missing field"),
        ((r"^iterations = 10", "iterations = 10\nfoo = 1"), r"\[filter\] foo: unknown field"),
        (
            (r"^    \[2, 0, -0.052478, 0.0\],", "    [2, 3, 0.1, 0.0],"),
            r"gravity_coefficients: coefficient row 0",
        ),
        (
            (r"^position_m = .*$", "position_m = [0.0, 0.0, 16000.0]"),
            r"\[site\] position_m: .*spin axis",
        ),
    ],
)
def test_scenario_errors_name_the_field(tmp_path, capsys, replacement, message):
    path = edited(tmp_path, replacement)
    assert main(["plan", str(path), "--out", str(tmp_path / "o"), "--runs", "1"]) == 2
    err = capsys.readouterr().err
    assert re.search(message, err), err
    assert str(path) in err and not (tmp_path / "o" / "summary.json").exists()


def test_missing_file_and_bad_runs(tmp_path, capsys):
    assert main(["plan", str(tmp_path / "none.toml"), "--out", str(tmp_path)]) == 2
    assert "none.toml" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_info:
        main(["plan", str(EROS), "--out", str(tmp_path / "o"), "--runs", "0"])
    assert exit_info.value.code == 2 and not (tmp_path / "o").exists()
    assert "argument --runs: must be at least 1, got 0" in capsys.readouterr().err
