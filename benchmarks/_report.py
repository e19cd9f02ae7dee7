"""A benchmark's command line and JSON report: the parts to run (``--sections``), and the
report printed on stdout and, on request, written to a file."""

from __future__ import annotations

import argparse
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from lightcurve.io.atomic import atomic_write_json


def emit_report(report: dict[str, Any], out: str | Path | None, *, indent: int = 2) -> None:
    """Print ``report`` as JSON and, when ``out`` is given, write it there too.

    Parameters
    ----------
    report : dict
        JSON-ready figures of the benchmark.
    out : str or pathlib.Path, optional
        File written atomically (:func:`lightcurve.io.atomic.atomic_write_json`); None or empty:
        print only.
    indent : int
        Indentation of the printed JSON.
    """
    print(json.dumps(report, indent=indent))
    if out:
        atomic_write_json(out, report)


def add_sections_argument(parser: argparse.ArgumentParser, names: Sequence[str]) -> None:
    """Add ``--sections``: a comma-separated subset of ``names`` (default: all of them).

    ``args.sections`` is then a set of names; an unknown name is an argparse error that lists
    the known ones (instead of a run that silently measures nothing).
    """
    known = tuple(names)

    def parse(text: str) -> set[str]:
        chosen = {name.strip() for name in text.split(",") if name.strip()}
        unknown = sorted(chosen - set(known))
        if unknown or not chosen:
            raise argparse.ArgumentTypeError(
                f"unknown section(s) {', '.join(unknown) or '(none given)'}; "
                f"choose from {', '.join(known)}"
            )
        return chosen

    parser.add_argument(
        "--sections",
        type=parse,
        default=set(known),
        metavar="NAME[,NAME…]",
        help=f"comma-separated parts to run, any of {', '.join(known)} (default: all)",
    )
