"""``-v``/``-q`` at every level of the command line: before the command, after any command and
after any sub-command, with the same meaning and destination (``args.verbose``/``args.quiet``)."""

import argparse
import contextlib
import io
import os
import subprocess
import sys
from pathlib import Path

from lightcurve.cli import build_parser

ROOT = Path(__file__).resolve().parents[2]
SAMPLE = ROOT / "data" / "observations" / "box_tumbling_ccd.csv"

#: Tried in turn as the value of a required argument: the first its type accepts is used.
PLACEHOLDERS = ("1", "1,0,0", "0,0,0,1", "1,1,1,0,0,0", "x")

#: Verbosity flags and the (verbose, quiet) counts they stand for.
FLAGS = {
    ("-v",): (1, 0),
    ("-q",): (0, 1),
    ("-vv",): (2, 0),
    ("--verbose",): (1, 0),
    ("--quiet", "-q"): (0, 2),
    ("-v", "-q"): (1, 1),
}


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def _leaves(parser: argparse.ArgumentParser, path: tuple[str, ...] = ()):
    """``(path, parser)`` of every command or sub-command that has no sub-commands itself."""
    children = _subparsers(parser)
    if not children and path:
        yield path, parser
    for name, child in children.items():
        yield from _leaves(child, (*path, name))


def _values(parser: argparse.ArgumentParser, action: argparse.Action) -> list[str]:
    """Placeholder values for a required argument: as many as its ``nargs`` asks for."""
    count = action.nargs if isinstance(action.nargs, int) else 1
    if action.choices:
        return [str(next(iter(action.choices)))] * count
    for text in PLACEHOLDERS:
        try:
            parser._get_value(action, text)
        except argparse.ArgumentError:
            continue
        return [text] * count
    raise AssertionError(f"{parser.prog} {action.dest}: no placeholder value fits")


def _required(parser: argparse.ArgumentParser) -> list[str]:
    """Arguments that make a leaf's command line complete: required options (one of each
    required mutually exclusive group) and required positionals, filled with placeholders."""
    options: list[str] = []
    for group in parser._mutually_exclusive_groups:
        if group.required:
            action = group._group_actions[0]
            options += [action.option_strings[0], *_values(parser, action)]
    positionals: list[str] = []
    for action in parser._actions:
        if action.option_strings:
            if action.required:
                options += [action.option_strings[0], *_values(parser, action)]
        elif action.nargs not in ("?", "*") and action.dest != argparse.SUPPRESS:
            positionals += _values(parser, action)
    return positionals + options


def _parse(parser: argparse.ArgumentParser, argv: list[str]) -> tuple[int, int] | str:
    """``(verbose, quiet)`` of a command line, or the parser's error message."""
    stderr = io.StringIO()
    try:
        with contextlib.redirect_stderr(stderr):
            args = parser.parse_args(argv)
    except SystemExit:
        return stderr.getvalue().strip()
    return args.verbose, args.quiet


def test_every_command_takes_verbosity_before_and_after_it():
    """Walks the whole parser tree: for every leaf, ``-v``/``-q`` placed before the command,
    after each command level and at the very end parse to the same counts, and counts given
    at different levels add up."""
    parser = build_parser()
    leaves = list(_leaves(parser))
    assert len(leaves) >= len(_subparsers(parser)) + 1  # every command, shapes' actions too
    failures = []
    for path, leaf in leaves:
        rest = _required(leaf)
        baseline = _parse(parser, [*path, *rest])
        if baseline != (0, 0):
            failures.append(f"{' '.join(path)} {' '.join(rest)}: {baseline}")
            continue
        for flags, expected in FLAGS.items():
            before = _parse(parser, [*flags, *path, *rest])
            places = [[*path[:i], *flags, *path[i:], *rest] for i in range(1, len(path) + 1)]
            places.append([*path, *rest, *flags])
            for argv in places:
                after = _parse(parser, argv)
                if not before == after == expected:
                    failures.append(f"{' '.join(argv)}: {after} (before the command: {before})")
        counted = _parse(parser, ["-v", *path, *rest, "-v", "-q"])
        if counted != (2, 1):
            failures.append(f"-v {' '.join(path)} … -v -q: {counted}, expected (2, 1)")
    assert not failures, "\n".join(failures)


def _lightcurve(*argv: str) -> subprocess.CompletedProcess:
    """``python -m lightcurve ARGV`` with this checkout's code: the real entry point and logging."""
    path = os.pathsep.join(filter(None, (str(ROOT), os.environ.get("PYTHONPATH"))))
    return subprocess.run(
        [sys.executable, "-m", "lightcurve", *argv],
        capture_output=True,
        text=True,
        env={**os.environ, "PYTHONPATH": path},
    )


def test_shapes_list_takes_verbosity_after_the_action():
    loud = _lightcurve("shapes", "list", "-v")
    quiet = _lightcurve("shapes", "list", "-q")
    assert loud.returncode == 0, loud.stderr
    assert quiet.returncode == 0, quiet.stderr
    assert "box_wing" in loud.stdout
    assert quiet.stdout == loud.stdout  # the listing is the result: -q keeps it
    assert len(quiet.stderr) <= len(loud.stderr)


def test_invert_takes_verbosity_after_the_arguments(tmp_path):
    argv = ["invert", str(SAMPLE), "--shape", "box", "--method", "ukf"]
    loud = _lightcurve(*argv, "--out", str(tmp_path / "loud"), "-v")
    assert loud.returncode == 0, loud.stderr
    assert "INFO lightcurve" in loud.stderr  # -v after the command: info logging
    assert "inverted" in loud.stderr  # and the status line
    assert (tmp_path / "loud" / SAMPLE.stem / "summary.json").is_file()
    quiet = _lightcurve(*argv, "--out", str(tmp_path / "quiet"), "-q")
    assert quiet.returncode == 0, quiet.stderr
    assert quiet.stdout == quiet.stderr == ""  # no log, no status line, no bar
    assert len(quiet.stdout + quiet.stderr) < len(loud.stdout + loud.stderr)
    assert (tmp_path / "quiet" / SAMPLE.stem / "summary.json").is_file()
