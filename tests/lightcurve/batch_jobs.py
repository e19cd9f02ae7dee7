"""Picklable jobs for the batch-runner tests (a module so that worker processes import it)."""

import time
from pathlib import Path

from lightcurve import io
from lightcurve.io.atomic import atomic_write_table


def count_rows(input_path: Path, result_dir: Path, delay: float = 0.0) -> dict:
    """Read an observation file, write its table, report the row count."""
    observations = io.read(input_path)
    time.sleep(delay)
    atomic_write_table(observations.table, result_dir / "estimates.parquet")
    return {"n_measurements": len(observations), "values": [1.0, float("nan")]}


def count_rows_reporting(input_path: Path, result_dir: Path, progress=None) -> dict:
    """:func:`count_rows` that reports its progress halfway (``progress(fraction, message)``)."""
    if progress is not None:
        progress(0.5, "rows read")
    return count_rows(input_path, result_dir)
