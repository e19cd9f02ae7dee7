"""The command line's help, verbosity flags, usage errors and progress bars."""

import argparse
import contextlib
import inspect
import io
import json
import math

import matplotlib
import matplotlib.image
import numpy as np
import pytest

from lightcurve.cli import _default_text, build_parser, main

#: Options whose default is chosen by the library (``None`` on the parser): the help must
#: still state it.
LIBRARY_DEFAULTS = {
    ("invert", "--particles"),
    ("invert", "--attitude-sigma-deg"),
    ("invert", "--omega-sigma"),
    ("invert", "--omega-max"),
    ("invert", "--q0"),
    ("invert", "--omega0"),
    ("invert", "--library"),
    ("simulate", "--library"),
    ("simulate", "--inertia"),
    ("geometry", "--min-elevation"),
    ("geometry", "--max-sun-elevation"),
}


def _parsers(parser, name="lightcurve"):
    yield name, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for child, sub in action.choices.items():
                yield from _parsers(sub, f"{name} {child}")


def _documented(parser):
    for action in parser._actions:
        if action.help == argparse.SUPPRESS or isinstance(
            action, argparse._HelpAction | argparse._VersionAction | argparse._SubParsersAction
        ):
            continue
        yield action


def _flat(text: str) -> str:
    return " ".join(text.split())


ALL = list(_parsers(build_parser()))


@pytest.mark.parametrize(("name", "parser"), ALL, ids=[name for name, _ in ALL])
def test_every_option_has_help_and_shows_its_default(name, parser):
    text = _flat(parser.format_help())
    assert "``" not in text
    formatter = parser._get_formatter()
    for action in _documented(parser):
        label = f"{name} {'/'.join(action.option_strings) or action.dest}"
        assert action.help, f"{label}: no help"
        shown = _flat(formatter._expand_help(action)) if action.help else ""
        default = action.default
        flag = isinstance(
            action,
            argparse._StoreTrueAction | argparse._StoreFalseAction | argparse._CountAction,
        )
        unset = (
            default is None
            or default is argparse.SUPPRESS
            or (isinstance(default, list) and not default)
        )
        if flag or not action.option_strings or unset:
            continue
        assert f"default: {_default_text(default)}" in shown, f"{label}: {shown!r}"
        assert shown in text  # the expanded help is what --help prints


def test_options_with_library_defaults_state_them():
    parsers = dict(ALL)
    for command, option in LIBRARY_DEFAULTS:
        parser = parsers[f"lightcurve {command}"]
        action = next(a for a in parser._actions if option in a.option_strings)
        assert "(default: " in action.help, f"{command} {option}: {action.help!r}"


def test_invert_help_states_the_library_defaults():
    from lightcurve.inversion import InversionOptions, invert

    defaults = inspect.signature(invert).parameters
    stated = {
        "--particles": defaults["particles"].default,
        "--attitude-sigma-deg": defaults["attitude_sigma_deg"].default,
        "--omega-sigma": math.degrees(defaults["omega_sigma"].default),
        "--omega-max": math.degrees(defaults["omega_max"].default),
        "--model-tolerance": InversionOptions().model_tolerance_mag,
        "--rescue": InversionOptions().rescue_starts,
    }
    parser = dict(ALL)["lightcurve invert"]
    for option, value in stated.items():
        action = next(a for a in parser._actions if option in a.option_strings)
        assert f"(default: {value:g}" in action.help, f"{option}: {action.help!r} vs {value}"
    action = next(a for a in parser._actions if "--rescue-estimate" in a.option_strings)
    assert f"(default: {','.join(InversionOptions().rescue_estimate)})" in action.help


def test_out_is_the_output_option_everywhere():
    for name, parser in ALL:
        options = {o for a in parser._actions for o in a.option_strings}
        assert not options & {"--output", "--outdir", "--output-dir", "--out-file"}, name
        if "--out-dir" in options:  # the deprecated spelling is an alias of --out only
            action = next(a for a in parser._actions if "--out-dir" in a.option_strings)
            assert "--out" in action.option_strings, name


@pytest.mark.parametrize(
    "argv",
    [
        ["-v", "-q", "propagate", "--duration", "60"],
        ["propagate", "--duration", "60", "-v", "-q"],
        ["-q", "propagate", "-v", "--duration", "60"],
    ],
)
def test_verbosity_flags_before_or_after_the_command(argv):
    parser = build_parser(load=["propagate"])
    args = parser.parse_args(argv)
    assert (args.verbose, args.quiet) == (1, 1)


def test_quiet_run_prints_the_result(capsys):
    assert main(["propagate", "--duration", "120", "-q"]) == 0
    assert "q4" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("argv", "command"),
    [
        (["invert"], "lightcurve invert"),
        (["simulate", "x.csv", "--shape", "box", "--bogus"], "lightcurve simulate"),
        (["propagate", "--duration", "ten"], "lightcurve propagate"),
        (["no-such-command"], "lightcurve"),
        (["shapes", "frobnicate"], "lightcurve shapes"),
        # an unknown option is reported by the command it follows (its usage, its --help)
        (["invert", "x.csv", "--method", "ukf", "--out", "r", "--bogus"], "lightcurve invert"),
        (["--bogus"], "lightcurve"),
    ],
)
def test_usage_errors_are_one_line(argv, command, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert err.startswith(f"{command}: error: ") and "--help" in err


# --------------------------------------------------------------------------- progress bars
@pytest.fixture(scope="module")
def short_light_curve(tmp_path_factory):
    """Five minutes of a tumbling box-wing satellite in GEO, 2 s cadence."""
    folder = tmp_path_factory.mktemp("progress")
    geometry, sim = folder / "geo.csv", folder / "sim.csv"
    span = ["--start", "2024-03-10T04:48:00", "--duration", "300", "--cadence", "2"]
    assert main(["geometry", *span, "--geo", "-100", "--out", str(geometry)]) == 0
    truth = ["--q0", "0,0,0,1", "--omega0", "0.5,1,-0.3", "--noise-mag", "0.02"]
    assert main(["simulate", str(geometry), "--shape", "box_wing", *truth, "--out", str(sim)]) == 0
    return sim


def test_period_progress_bar(short_light_curve, tmp_path, capsys):
    out = tmp_path / "period"
    argv = ["period", str(short_light_curve), "--range", "0.02", "0.08", "--orders", "2,3"]
    assert main([*argv, "--progress", "--out", str(out)]) == 0
    assert "period scan" in capsys.readouterr().err
    assert main([*argv, "--no-progress", "--out", str(tmp_path / "quiet")]) == 0
    assert "period scan" not in capsys.readouterr().err
    quiet = json.loads((tmp_path / "quiet" / "summary.json").read_text())
    loud = json.loads((out / "summary.json").read_text())
    assert np.isclose(quiet["period_h"], loud["period_h"], rtol=1e-12)


@pytest.fixture(scope="module")
def inversion(short_light_curve, tmp_path_factory):
    """A short UKF inversion run with --progress: its result folder and its stderr."""
    out = tmp_path_factory.mktemp("inversion")
    argv = ["invert", str(short_light_curve), "--shape", "box_wing", "--method", "ukf"]
    argv += ["--init", "none", "--q0", "0,0,0,1", "--omega0", "0.5,1,-0.3"]
    stderr = io.StringIO()
    with contextlib.redirect_stderr(stderr):
        assert main([*argv, "--progress", "--out", str(out)]) == 0
    return out / short_light_curve.stem, stderr.getvalue()


def test_invert_progress_bars(inversion, short_light_curve):
    _, err = inversion
    assert "invert" in err  # the files' bar
    assert f"{short_light_curve.stem}: " in err and "%|" in err  # the bar of the running file


def test_quiet_invert_draws_no_bar(short_light_curve, tmp_path, capsys):
    argv = ["invert", str(short_light_curve), "--shape", "box_wing", "--method", "ukf"]
    argv += ["--init", "none", "--q0", "0,0,0,1", "--omega0", "0.5,1,-0.3", "-q"]
    assert main([*argv, "--out", str(tmp_path / "quiet")]) == 0
    assert capsys.readouterr().err == ""  # no bar, no status line


def test_quiet_silences_status_lines(tmp_path, capsys):
    argv = ["geometry", "--start", "2024-03-10T04:48:00", "--duration", "60", "--geo", "-100"]
    assert main([*argv, "--out", str(tmp_path / "loud.csv")]) == 0
    assert "epochs" in capsys.readouterr().out
    assert main(["-q", *argv, "--out", str(tmp_path / "quiet.csv")]) == 0
    assert capsys.readouterr().out == ""
    assert (tmp_path / "quiet.csv").read_text() == (tmp_path / "loud.csv").read_text()


def test_plot_draws_the_result(inversion, tmp_path):
    result, _ = inversion
    assert main(["plot", str(result), "--out", str(tmp_path)]) == 0
    for name in ("light_curve.png", "states.png"):
        png = tmp_path / name
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        image = matplotlib.image.imread(png)
        assert image.shape[0] > 200 and image.shape[1] > 200
        assert float(np.std(image[..., :3])) > 0.02  # not a blank canvas


def test_convex_progress_bar(tmp_path, capsys):
    from lightcurve import io as lc_io
    from lightcurve.io.observations import Observations

    obs = lc_io.read("data/ariadne/test_lcs_rel")
    keep = np.isin(obs.lightcurve_ids, [3, 4])
    table = obs.table.loc[keep].iloc[::3].reset_index(drop=True)
    path = tmp_path / "ariadne.csv"
    lc_io.write(Observations(table, obs.meta, obs.source), path)
    argv = ["convex", str(path), "--period-range", "5.760", "5.764", "--poles", "1"]
    argv += ["--rows", "3", "--degree", "2", "--iterations", "3", "--refine", "1"]
    assert main([*argv, "--progress", "--out", str(tmp_path / "convex")]) == 0
    assert "period scan" in capsys.readouterr().err
