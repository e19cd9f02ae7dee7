"""`invert --scheduler` without Dask installed says what to install, in one line."""

import sys

from lightcurve.cli import main


def test_scheduler_without_dask_says_what_to_install(tmp_path, monkeypatch, capsys):
    observations = tmp_path / "obs.csv"
    observations.write_text("placeholder\n")
    monkeypatch.setitem(sys.modules, "dask.distributed", None)  # import fails as if absent
    command = ["invert", str(observations), "--shape", "box", "--method", "ukf"]
    code = main([*command, "--scheduler", "tcp://127.0.0.1:1", "--out", str(tmp_path / "out")])
    error = capsys.readouterr().err
    assert code == 2
    assert error.count("\n") == 1
    assert "pip install 'space-lightcurves[distributed]'" in error
