"""A scenario file that is missing or is a folder is named in one line, not as errno text."""

import pytest

from lightcurve.cli import main
from lightcurve.io.scenario_files import load_toml


def test_a_missing_scenario_file_is_named(tmp_path):
    with pytest.raises(FileNotFoundError, match=r"nutation\.toml: no such scenario file$"):
        load_toml(tmp_path / "nutation.toml")


def test_a_folder_is_not_a_scenario_file(tmp_path):
    with pytest.raises(IsADirectoryError, match=r": a folder, not a scenario file$"):
        load_toml(tmp_path)


def test_the_command_reports_a_missing_scenario_in_one_line(tmp_path, capsys):
    scenario, out = tmp_path / "nutation.toml", tmp_path / "mono"
    assert main(["monocular", str(scenario), "--out", str(out)]) == 2
    error = capsys.readouterr().err
    assert error == f"lightcurve monocular: error: {scenario}: no such scenario file\n"
    assert not out.exists()
