"""`simulate` without a starting state says that the default profile needs one."""

import pytest

from lightcurve.cli import main


@pytest.mark.parametrize("given", [[], ["--q0", "0,0,0,1"], ["--omega0", "0.5,1,-0.3"]])
def test_the_default_profile_asks_for_its_starting_state(tmp_path, capsys, given):
    command = ["simulate", str(tmp_path / "geo.csv"), "--shape", "box_wing", *given]
    assert main([*command, "--out", str(tmp_path / "sim.csv")]) == 2
    error = capsys.readouterr().err
    assert "(the default) needs --q0 and --omega0" in error
    assert error.count("\n") == 1
    assert not (tmp_path / "sim.csv").exists()
