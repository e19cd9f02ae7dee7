"""The CLI entry point: discovery, version, one-line errors, the propagate demo."""

import subprocess
import sys

import numpy as np
import pandas as pd

from lightcurve import __version__
from lightcurve.cli import build_parser, main


def test_help_lists_commands_and_version():
    parser = build_parser()
    help_text = parser.format_help()
    for name in ("propagate", "simulate", "invert", "shapes"):
        assert name in help_text
    out = subprocess.run(
        [sys.executable, "-m", "lightcurve.cli", "--version"], capture_output=True, text=True
    )
    assert out.returncode == 0
    assert __version__ in out.stdout


def test_help_starts_without_heavy_imports():
    """`lightcurve --help` reads command names from source: torch and astropy stay unloaded."""
    code = (
        "import sys, contextlib, io\n"
        "from lightcurve.cli import main\n"
        "with contextlib.redirect_stdout(io.StringIO()):\n"
        "    try:\n"
        "        main(['--help'])\n"
        "    except SystemExit:\n"
        "        pass\n"
        "print(sorted(m for m in ('torch', 'astropy', 'trimesh') if m in sys.modules))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.stdout.strip() == "[]", out.stderr


def test_every_command_builds_its_parser():
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    for name, command in sub.choices.items():
        assert command.format_help(), name


def test_propagate_demo_conserves_invariants(tmp_path, capsys):
    out = tmp_path / "state.csv"
    assert main(["propagate", "--duration", "120", "--step", "30", "--out", str(out)]) == 0
    table = pd.read_csv(out)
    assert len(table) == 5
    np.testing.assert_allclose(table["energy"], table["energy"][0], rtol=1e-10)
    np.testing.assert_allclose(table["h_norm"], table["h_norm"][0], rtol=1e-10)
    assert "wx_deg_s" in capsys.readouterr().out


def test_user_errors_are_one_line_with_exit_code_2(capsys):
    assert main(["propagate", "--inertia", "1,1,3"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0
    assert "triangle inequality" in err


def test_bad_vector_argument(capsys):
    try:
        main(["propagate", "--omega0", "1,2"])
    except SystemExit as exc:
        assert exc.code == 2
    assert "expected 3 comma-separated numbers" in capsys.readouterr().err


def test_negative_vector_values_need_no_equals_sign(tmp_path):
    out = tmp_path / "state.csv"
    argv = [
        "propagate",
        "--omega0",
        "-5,2.3,-3.5",
        "--q0",
        "-0.6,0,0,0.8",
        "--duration",
        "60",
        "--step",
        "60",
        "--out",
        str(out),
    ]
    assert main(argv) == 0
    table = pd.read_csv(out)
    assert table["wx_deg_s"][0] == -5.0 and table["q1"][0] == -0.6


def test_threads_option_sets_every_pool_before_torch_loads():
    """``lightcurve --threads 1`` reaches torch and the kernels; idle threads sleep."""
    code = (
        "import os, sys, contextlib, io\n"
        "os.environ.pop('OMP_WAIT_POLICY', None)\n"
        "from lightcurve.cli import main\n"
        "with contextlib.redirect_stdout(io.StringIO()):\n"
        "    code = main(['--threads', '1', 'propagate', '--duration', '10', '--step', '5'])\n"
        "import torch\n"
        "from lightcurve.photometry.kernels import get_num_threads\n"
        "print(code, torch.get_num_threads(), get_num_threads(), os.environ['OMP_WAIT_POLICY'])\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.stdout.split() == ["0", "1", "1", "PASSIVE"], out.stderr


def test_threads_value_is_not_taken_for_the_command(capsys):
    from lightcurve.cli import _invoked_command, _requested_threads

    assert _invoked_command(["--threads", "2", "propagate"]) == "propagate"
    assert _requested_threads(["--threads=3", "propagate", "--threads", "9"]) == "3"
    assert main(["--threads", "0", "propagate"]) == 2
    assert "at least 1" in capsys.readouterr().err


def test_unknown_shape_option_fails_at_start_with_one_line(tmp_path, capsys):
    """A misspelt --shapes name stops the batch before any input is read; nothing is left."""
    out = tmp_path / "inv"
    argv = ["invert", "data/observations", "--shapes", "box,boxx", "--method", "ukf"]
    assert main([*argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0
    assert "'boxx'" in err and "box_wing" in err
    assert not out.exists()


def test_q0_must_be_a_unit_quaternion(tmp_path, capsys):
    """``--q0 1,2,3,4`` is an error, not some rotation; rounded components are normalised."""
    out = tmp_path / "state.csv"
    try:
        main(["propagate", "--q0", "1,2,3,4", "--duration", "10", "--out", str(out)])
    except SystemExit as exc:
        assert exc.code == 2
    assert "unit quaternion" in capsys.readouterr().err
    assert not out.exists()
    argv = ["propagate", "--q0", "0,0,0.6,0.801", "--duration", "10", "--step", "10"]
    assert main([*argv, "--out", str(out)]) == 0
    q = pd.read_csv(out)[["q1", "q2", "q3", "q4"]].to_numpy()[0]
    np.testing.assert_allclose(np.linalg.norm(q), 1.0, rtol=1e-12)


def test_output_blocked_by_a_file_is_one_line_and_leaves_nothing(tmp_path, capsys):
    """An --out that cannot be a folder is named in one line; bad inputs create no folder."""
    blocker = tmp_path / "taken"
    blocker.write_text("")
    argv = ["invert", "data/observations/box_tumbling_ccd.csv", "--shapes", "box"]
    assert main([*argv, "--method", "ukf", "--out", str(blocker / "inv")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and f"{blocker} is a file" in err
    missing = ["invert", str(tmp_path / "none.csv"), "--shapes", "box", "--method", "ukf"]
    assert main([*missing, "--out", str(tmp_path / "inv")]) == 2
    assert not (tmp_path / "inv").exists()
