"""Every `lightcurve …` command shown in README.md and docs/ is one the CLI accepts.

Parse only (nothing runs): a command line in a code block must parse exactly as written; a
synopsis line (`[--runs N]`, `SCENARIO.toml`) and a command quoted inline in the text must name
an existing command and only options that command has. Every `data/…` path the pages show
must exist in the checkout. docs/cli.md is generated from the parser and checked elsewhere.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import re
import shlex
from pathlib import Path

import pytest

from lightcurve.cli import _attach_negative_values, build_parser

ROOT = Path(__file__).resolve().parents[1]
PAGES = [
    ROOT / "README.md",
    *sorted(page for page in (ROOT / "docs").glob("*.md") if page.name != "cli.md"),
]
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))
FENCE = re.compile(r"^```(\w*)\n(.*?)^```", re.S | re.M)
#: A placeholder of a synopsis: `SCENARIO.toml`, `DIR`, `N`, `NAME`.
PLACEHOLDER = re.compile(r"[A-Z][A-Z_]*(\.[a-z]+)?")


def shell_commands() -> list[tuple[str, str]]:
    """``(page:line, command)`` of each `lightcurve` line in the pages' shell code blocks."""
    found = []
    for page in PAGES:
        text = page.read_text()
        for block in FENCE.finditer(text):
            if block.group(1) not in ("", "bash", "sh"):
                continue
            first = text[: block.start(2)].count("\n") + 1
            lines = block.group(2).split("\n")
            number = 0
            while number < len(lines):
                start, command = number, lines[number]
                while command.endswith("\\") and number + 1 < len(lines):
                    number += 1
                    command = command[:-1] + " " + lines[number].strip()
                number += 1
                command = re.sub(r"^(\w+=\S+\s+)+", "", command.strip())  # OMP_NUM_THREADS=1 …
                if command.startswith("lightcurve "):
                    found.append((f"{page.name}:{first + start}", command))
    return found


def inline_commands() -> list[tuple[str, str]]:
    """``(file, span)`` of each inline code span that quotes a `lightcurve` command."""
    found = []
    for path in PAGES + NOTEBOOKS:
        if path.suffix == ".ipynb":
            cells = json.loads(path.read_text())["cells"]
            text = "\n".join("".join(c["source"]) for c in cells if c["cell_type"] == "markdown")
        else:
            text = FENCE.sub("", path.read_text())
        for span in re.findall(r"`(lightcurve [^`]+)`", text):
            found.append((path.name, span))
    return found


SHELL = shell_commands()
INLINE = inline_commands()


@pytest.fixture(scope="module")
def parser() -> argparse.ArgumentParser:
    return build_parser()


def subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def unknown_options(parser: argparse.ArgumentParser, words: list[str]) -> list[str]:
    """Options among ``words`` (after ``lightcurve``) that their command does not have; a
    word naming no command where one is expected is reported too."""
    problems = []
    for word in words:
        commands = subcommands(parser)
        if word.rstrip(":") in commands:
            parser = commands[word.rstrip(":")]
            if word.endswith(":"):  # an error message quoted: `lightcurve shapes: error: …`
                return problems
        elif commands and parser.prog == "lightcurve" and not word.startswith("-"):
            if PLACEHOLDER.fullmatch(word) or word.startswith("<"):  # `lightcurve COMMAND`
                return problems
            problems.append(f"no command {word!r}")
            return problems
        else:
            for option in re.findall(r"(?<![\w-])(--?[a-z][\w-]*)", word):
                if option not in parser._option_string_actions:
                    problems.append(f"{parser.prog} has no option {option}")
    return problems


def parse_error(parser: argparse.ArgumentParser, words: list[str]) -> str | None:
    """argparse's message when ``words`` do not parse, else None."""
    stderr = io.StringIO()
    with contextlib.redirect_stderr(stderr), contextlib.redirect_stdout(io.StringIO()):
        try:
            parser.parse_args(_attach_negative_values(words))
        except SystemExit as exc:
            if exc.code:
                return stderr.getvalue().strip()
    return None


def test_the_pages_show_commands():
    pages = {where.split(":")[0] for where, _ in SHELL}
    assert {"README.md", "index.md", "observations.md", "shapes.md"} <= pages
    assert len(SHELL) >= 30 and len(INLINE) >= 30


@pytest.mark.parametrize(("where", "command"), SHELL, ids=[where for where, _ in SHELL])
def test_shown_command_parses(parser, where, command):
    words = shlex.split(command, comments=True)[1:]
    if any("[" in word or "|" in word or PLACEHOLDER.fullmatch(word) for word in words):
        assert not unknown_options(parser, words), f"{where}: {command}"  # a synopsis
    else:
        assert parse_error(parser, words) is None, f"{where}: {command}"


@pytest.mark.parametrize(
    ("where", "span"), INLINE, ids=[f"{w}-{i}" for i, (w, _) in enumerate(INLINE)]
)
def test_quoted_command_exists(parser, where, span):
    assert not unknown_options(parser, span.split()[1:]), f"{where}: `{span}`"


def test_the_check_catches_a_wrong_command(parser):
    assert parse_error(parser, ["invert", "obs.csv", "--shape", "box", "--no-such-flag"])
    assert parse_error(parser, ["simulate", "geo.csv", "--shape"])
    assert unknown_options(parser, ["shapes", "add", "--no-such-flag"])
    assert unknown_options(parser, ["invent", "--out", "x"])


def test_shown_data_paths_exist():
    missing = []
    for path in PAGES + NOTEBOOKS:
        text = path.read_text()
        for match in re.finditer(r"(?<![\w/.-])((?:[\w.-]+/)*data/[\w./-]*\w)", text):
            if not (ROOT / match.group(1)).exists():
                missing.append(f"{path.name}: {match.group(1)}")
    assert not missing
