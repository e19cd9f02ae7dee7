"""Atomic file output: write to a temporary file in the target folder, then rename.

An interrupted run therefore never leaves a half-written result behind: the target either
has its old content or the complete new one. Every writer in :mod:`lightcurve` goes
through these functions.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

__all__ = [
    "atomic_path",
    "atomic_write_json",
    "atomic_write_table",
    "atomic_write_text",
    "json_ready",
    "output_folder",
]


@contextmanager
def atomic_path(target: str | os.PathLike[str], suffix: str = "") -> Iterator[Path]:
    """Yield a temporary path beside ``target``; on success rename it onto ``target``.

    Parameters
    ----------
    target : path-like
        Final file path; its parent folder is created if needed.
    suffix : str
        Suffix of the temporary file (some writers infer the format from it).

    Yields
    ------
    pathlib.Path
        Where to write. Removed if the block raises.
    """
    target = Path(target)
    output_folder(target.parent)
    if target.is_dir():
        raise IsADirectoryError(f"cannot write {target}: it is a folder")
    try:
        fd, tmp = tempfile.mkstemp(
            prefix=f".{target.name}.", suffix=suffix + ".tmp", dir=target.parent
        )
    except OSError as exc:  # unwritable folder, read-only or special file system
        raise OSError(f"cannot write {target}: {exc.strerror or exc}") from None
    os.close(fd)
    tmp_path = Path(tmp)
    umask = os.umask(0)
    os.umask(umask)
    tmp_path.chmod(0o666 & ~umask)  # mkstemp creates 0600; give the file normal permissions
    try:
        yield tmp_path
        with open(tmp_path, "rb") as handle:
            os.fsync(handle.fileno())
        os.replace(tmp_path, target)
    finally:
        if tmp_path.exists():
            tmp_path.unlink()


def output_folder(folder: str | os.PathLike[str]) -> Path:
    """Create the output folder ``folder`` (and its parents), with a one-line error naming
    it when a file stands in the way or the location is not writable."""
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError):
        raise OSError(
            f"cannot create the output folder {folder}: {_blocking_file(folder)} is a file"
        ) from None
    except OSError as exc:
        raise OSError(f"cannot create the output folder {folder}: {exc.strerror or exc}") from None
    return folder


def _blocking_file(folder: Path) -> Path:
    """The first existing non-folder on the way to ``folder`` (what stops ``mkdir``)."""
    for candidate in (*reversed(folder.parents), folder):
        if candidate.exists() and not candidate.is_dir():
            return candidate
    return folder


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
