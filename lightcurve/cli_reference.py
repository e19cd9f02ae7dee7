"""Generate the CLI reference (``docs/cli.md``) from the parser's own help texts.

    python -m lightcurve.cli_reference > docs/cli.md

``tests/lightcurve/test_cli_reference.py`` fails when the committed page differs from what
the current CLI prints, so the reference cannot drift from the code.
"""

from __future__ import annotations

import argparse
import os

from lightcurve.cli import build_parser

HEADER = """# Command-line reference

Generated from the CLI's own help by `python -m lightcurve.cli_reference > docs/cli.md`;
do not edit by hand. Units are stated in each option's help; quaternions are scalar-last,
inertial → body.
"""


def _subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def _section(name: str, parser: argparse.ArgumentParser, level: int) -> list[str]:
    lines = [f"{'#' * level} `{name}`", "", "```text", parser.format_help().rstrip(), "```", ""]
    for child, sub in _subcommands(parser).items():
        lines += _section(f"{name} {child}", sub, level + 1)
    return lines


def render() -> str:
    """The Markdown reference for every command and sub-command."""
    os.environ["COLUMNS"] = "100"  # stable wrapping of argparse's help
    parser = build_parser()
    lines = [HEADER, "## `lightcurve`", "", "```text", parser.format_help().rstrip(), "```", ""]
    for name, sub in _subcommands(parser).items():
        lines += _section(f"lightcurve {name}", sub, 2)
    return "\n".join(lines).rstrip() + "\n"


if __name__ == "__main__":
    print(render(), end="")
