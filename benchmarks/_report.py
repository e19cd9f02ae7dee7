"""A benchmark's JSON report: printed on stdout and, on request, written to a file."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from lightcurve.atomic import atomic_write_json


def emit_report(report: dict[str, Any], out: str | Path | None, *, indent: int = 2) -> None:
    """Print ``report`` as JSON and, when ``out`` is given, write it there too.

    Parameters
    ----------
    report : dict
        JSON-ready figures of the benchmark.
    out : str or pathlib.Path, optional
        File written atomically (:func:`lightcurve.atomic.atomic_write_json`); None or empty:
        print only.
    indent : int
        Indentation of the printed JSON.
    """
    print(json.dumps(report, indent=indent))
    if out:
        atomic_write_json(out, report)
