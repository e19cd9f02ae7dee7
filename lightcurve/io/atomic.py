"""Atomic result files of :mod:`lightcurve`: text, JSON and tables.

Built on the project's one atomic writer, :func:`shapes.files.atomic_path` (temporary file
in the target folder, ``fsync``, ``os.replace``), which this module re-exports with
:func:`~shapes.files.output_folder` as part of its interface. An interrupted run therefore
never leaves a half-written result behind: the target either has its old content or the
complete new one. Every writer in :mod:`lightcurve` goes through these functions.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from shapes.files import atomic_path, output_folder

if TYPE_CHECKING:
    import pandas as pd

__all__ = [
    "atomic_path",
    "atomic_write_csv",
    "atomic_write_json",
    "atomic_write_table",
    "atomic_write_text",
    "json_ready",
    "output_folder",
]


def atomic_write_text(target: str | os.PathLike[str], text: str) -> None:
    """Write UTF-8 text atomically."""
    with atomic_path(target) as tmp:
        tmp.write_text(text, encoding="utf-8")


def json_ready(value: Any) -> Any:
    """Nested dicts/lists with numpy values as Python numbers and NaN/inf as None.

    JSON has no NaN or infinity, and :func:`atomic_write_json` rejects them.
    """
    if isinstance(value, dict):
        return {str(k): json_ready(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_ready(v) for v in value]
    if isinstance(value, np.ndarray):
        return json_ready(value.tolist())
    if isinstance(value, float | np.floating):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.bool_):
        return bool(value)
    return value


def atomic_write_json(target: str | os.PathLike[str], data: Any) -> None:
    """Write JSON atomically (indented, UTF-8, NaN/inf rejected)."""
    atomic_write_text(target, json.dumps(data, indent=2, allow_nan=False) + "\n")


def atomic_write_table(table: pd.DataFrame, target: str | os.PathLike[str]) -> None:
    """Write a table atomically as CSV or Parquet, chosen by the target's suffix."""
    suffix = Path(target).suffix.lower()
    with atomic_path(target, suffix=suffix) as tmp:
        if suffix == ".parquet":
            table.to_parquet(tmp, index=False)
        elif suffix == ".csv":
            table.to_csv(tmp, index=False)
        else:
            raise ValueError(f"{target}: unknown table format {suffix!r} (use .csv or .parquet)")


def atomic_write_csv(columns: Mapping[str, np.ndarray], target: str | os.PathLike[str]) -> None:
    """Write equal-length columns atomically as CSV, without pandas.

    The same text as ``pandas.DataFrame(columns).to_csv(target, index=False)``: a header row,
    numbers in Python's shortest round-trip form, ``True``/``False``, NaN as an empty field.
    """
    values = [np.asarray(v).tolist() for v in columns.values()]
    if len({len(v) for v in values}) > 1:
        raise ValueError(f"{target}: columns of different lengths")
    rows = (
        ",".join("" if isinstance(v, float) and math.isnan(v) else str(v) for v in row)
        for row in zip(*values, strict=True)
    )
    atomic_write_text(target, "".join(f"{line}\n" for line in [",".join(columns), *rows]))
