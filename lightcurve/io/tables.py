"""Reading photometry tables as observers keep them: text (or Parquet) into string cells.

A photometry table is plain text: comma-, semicolon- or whitespace-separated fields, with or
without a header row, ``#`` comment lines anywhere (``# key: value`` comments before the
data become metadata), and optionally decimal commas. Columns are named by their header
or by their 1-based position (:class:`RawTable`). :class:`CellProblems` reports each bad
cell with its row, column and line in the file, or collects them for dropping.
"""

from __future__ import annotations

import difflib
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from lightcurve.io.observations import (
    ObservationError,
    RowProblem,
)

__all__ = [
    "DELIMITERS",
    "CellProblems",
    "RawTable",
    "numeric_column",
    "parquet_table",
    "read_table",
]


DELIMITERS = {"comma": ",", "semicolon": ";", "whitespace": None}


_NUMBER = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")


@dataclass
class RawTable:
    """A text table as read: string cells and where each row came from.

    Attributes
    ----------
    columns : list of str
        Header names, or ``"1"``, ``"2"``, … without a header.
    rows : list of list of str
        The cells.
    lines : list of int
        File line (1-based) of each row.
    meta : dict
        ``# key: value`` comments before the data.
    source : str
        File name.
    has_header : bool
    decimal : str
        Decimal mark of the numbers.
    """

    columns: list[str]
    rows: list[list[str]]
    lines: list[int]
    meta: dict[str, str] = field(default_factory=dict)
    source: str = ""
    has_header: bool = True
    decimal: str = "."

    def __len__(self) -> int:
        return len(self.rows)

    def column_index(self, spec: str) -> int:
        """Index of a column given by header name or 1-based position.

        Raises
        ------
        ObservationError
            If no column matches (the closest header name is suggested).
        """
        spec = spec.strip()
        if spec in self.columns:
            return self.columns.index(spec)
        lowered = [c.lower() for c in self.columns]
        if lowered.count(spec.lower()) == 1:
            return lowered.index(spec.lower())
        if spec.isdigit() and 1 <= int(spec) <= len(self.columns):
            return int(spec) - 1
        if not self.has_header:
            raise ObservationError(
                f"the table has no header row: name columns by position 1..{len(self.columns)}",
                self.source,
                column=spec,
            )
        close = difflib.get_close_matches(spec, self.columns, n=1, cutoff=0.6)
        hint = f" (found '{close[0]}': misspelled?)" if close else ""
        raise ObservationError(
            f"no such column{hint}; columns: {', '.join(self.columns)}", self.source, column=spec
        )

    def cells(self, spec: str) -> tuple[str, list[str]]:
        """The header name and the cells of a column."""
        index = self.column_index(spec)
        return self.columns[index], [row[index] for row in self.rows]


def _split(line: str, delimiter: str | None) -> list[str]:
    if delimiter is None:
        return line.split()
    return [cell.strip() for cell in line.split(delimiter)]


def _is_number(text: str, decimal: str) -> bool:
    return bool(_NUMBER.fullmatch(text.replace(decimal, ".") if decimal != "." else text))


def read_table(
    path: str | Path,
    delimiter: str = "auto",
    header: bool | None = None,
    decimal: str = ".",
) -> RawTable:
    """Read a delimited text table.

    Parameters
    ----------
    path : path-like
    delimiter : {"auto", "comma", "semicolon", "whitespace"}
        ``auto``: semicolons if the first data line has one, else commas if it has one
        (and the decimal mark is ``.``), else whitespace.
    header : bool, optional
        Whether the first non-comment line is a header; by default it is when none of its
        fields is a number.
    decimal : {".", ","}
        Decimal mark of the numbers.

    Returns
    -------
    RawTable

    Raises
    ------
    ObservationError
        For an empty table or a row whose field count differs from the header's (naming
        the row and the line).
    """
    path = Path(path)
    source = str(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such file")
    if decimal not in (".", ","):
        raise ValueError(f"decimal mark must be '.' or ',', got {decimal!r}")
    try:
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ObservationError(f"not a UTF-8 text file ({exc.reason})", source) from None
    meta: dict[str, str] = {}
    content: list[tuple[int, str]] = []
    for number, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if not stripped:
            continue
        if stripped.startswith("#"):
            key, sep, value = stripped.lstrip("#").partition(":")
            if sep and not content and re.fullmatch(r"[\w .-]+", key.strip()):
                meta[key.strip()] = value.strip()
            continue
        content.append((number, line))
    if not content:
        raise ObservationError("no data rows", source)
    if delimiter == "auto":
        first = content[0][1] if header is False or len(content) == 1 else content[1][1]
        if ";" in first:
            delimiter = "semicolon"
        elif "," in first and decimal == ".":
            delimiter = "comma"
        else:
            delimiter = "whitespace"
    if delimiter not in DELIMITERS:
        raise ValueError(f"delimiter must be auto or one of {', '.join(DELIMITERS)}")
    if delimiter == "comma" and decimal == ",":
        raise ValueError("decimal commas need semicolon- or whitespace-separated fields")
    sep = DELIMITERS[delimiter]
    first = _split(content[0][1], sep)
    if header is None:
        header = not any(_is_number(cell, decimal) for cell in first)
    if header:
        columns = [cell.strip().strip('"') for cell in first]
        body = content[1:]
    else:
        columns = [str(k + 1) for k in range(len(first))]
        body = content
    if not body:
        raise ObservationError("a header row but no data rows", source)
    rows, lines = [], []
    for row_number, (line_number, line) in enumerate(body, start=1):
        cells = [cell.strip('"') for cell in _split(line, sep)]
        if len(cells) != len(columns):
            raise ObservationError(
                f"has {len(cells)} fields, the {'header' if header else 'first row'} has "
                f"{len(columns)} (line {line_number}; wrong separator or a truncated line?)",
                source,
                row=row_number,
            )
        rows.append(cells)
        lines.append(line_number)
    return RawTable(columns, rows, lines, meta, source, bool(header), decimal)


# --------------------------------------------------------------------------- values


class CellProblems:
    """Collects bad cells: raises on the first one, or records them all for dropping."""

    def __init__(self, table: RawTable, drop: bool):
        self.table, self.drop = table, drop
        self.bad = np.zeros(len(table), dtype=bool)
        self.found: list[RowProblem] = []

    def flag(self, mask: np.ndarray, column: str, message: object) -> None:
        mask = np.asarray(mask, dtype=bool) & ~self.bad
        for row in np.flatnonzero(mask):
            text = message(row) if callable(message) else str(message)
            text = f"{text} (line {self.table.lines[row]})"
            if not self.drop:
                raise ObservationError(text, self.table.source, int(row) + 1, column)
            self.found.append(RowProblem(int(row) + 1, column, text))
        self.bad |= mask


def numeric_column(
    table: RawTable, spec: str, problems: CellProblems, unit: str = ""
) -> tuple[str, np.ndarray]:
    """A column as floats; empty, non-numeric and non-finite cells are flagged."""
    name, cells = table.cells(spec)
    text = pd.Series(cells, dtype=str)
    if table.decimal != ".":
        text = text.str.replace(table.decimal, ".", regex=False)
    values = pd.to_numeric(text, errors="coerce").to_numpy(dtype=float)
    empty = text.str.strip().eq("").to_numpy()
    problems.flag(empty, name, "missing value (empty field)")
    problems.flag(
        np.isnan(values) & ~empty, name, lambda r: f"cannot read {cells[r]!r} as a number{unit}"
    )
    problems.flag(np.isinf(values), name, "value is not finite")
    return name, values


def parquet_table(path: Path) -> RawTable:
    """A Parquet file as a :class:`RawTable` of strings (floats written exactly, ``repr``)."""
    import json

    import pyarrow.parquet as pq

    try:
        arrow = pq.read_table(path)
    except (OSError, ValueError) as exc:
        raise ObservationError(f"cannot read Parquet file ({exc})", str(path)) from None
    raw_meta = (arrow.schema.metadata or {}).get(b"lightcurve.meta")
    frame = arrow.to_pandas()
    rows = [[_cell(value) for value in row] for row in frame.itertuples(index=False)]
    lines = list(range(1, len(rows) + 1))
    meta = json.loads(raw_meta) if raw_meta else {}
    return RawTable([str(c) for c in frame.columns], rows, lines, meta, str(path))


def _cell(value: object) -> str:
    if isinstance(value, pd.Timestamp):
        return value.isoformat()
    if value is None or (isinstance(value, float) and np.isnan(value)):
        return ""
    return repr(value) if isinstance(value, float) else str(value)
