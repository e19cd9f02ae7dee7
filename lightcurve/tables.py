"""Importing photometry as observers keep it: text tables, their times, and the geometry.

A photometry table is plain text: comma-, semicolon- or whitespace-separated fields, with or
without a header row, ``#`` comment lines anywhere (``# key: value`` comments before the
data become metadata), and optionally decimal commas. Columns are named by their header
or by their 1-based position. Times are ISO-8601 strings, Julian dates, Modified Julian
Dates or Unix seconds, in UTC, TT or TDB; they are converted to UTC and rounded to the
microsecond (the resolution of observation files), parsing decimal strings exactly so that
the same instants written in any of the formats give identical files.

:func:`import_photometry` turns such a table, a site, and either TLEs or topocentric
coordinates recorded with each measurement into a validated
:class:`~lightcurve.observations.Observations` (GCRS vectors in km, the geometry columns of
:mod:`lightcurve.satellite_geometry`). Every bad value is reported with its row (1 = the
first data row), its column and its line in the file; ``drop_bad_rows`` drops such rows and
lists them instead.
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from decimal import ROUND_HALF_EVEN, Decimal, InvalidOperation
from pathlib import Path

import numpy as np
import pandas as pd

from lightcurve.ephemeris import Site
from lightcurve.observations import (
    MJD_EPOCH,
    ObservationError,
    Observations,
    RowProblem,
    validate_table,
)
from lightcurve.tle import TLE

__all__ = [
    "DELIMITERS",
    "MICROSECONDS_PER_DAY",
    "TIME_FORMATS",
    "TIME_SCALES",
    "RawTable",
    "TimeColumn",
    "epoch_strings",
    "import_photometry",
    "parse_times",
    "read_epochs",
    "read_table",
]

DELIMITERS = {"comma": ",", "semicolon": ";", "whitespace": None}
TIME_FORMATS = ("iso", "jd", "mjd", "unix")
TIME_SCALES = ("utc", "tt", "tdb")
MICROSECONDS_PER_DAY = 86_400_000_000
_JD_MINUS_MJD = 2_400_000.5
_UNIX_EPOCH_MJD = 40_587
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


def epoch_strings(micro: np.ndarray) -> np.ndarray:
    """ISO-8601 UTC strings (``…T…Z``, microseconds) of UTC microseconds since MJD 0.

    Written with the ``mjd`` column, they keep every microsecond exactly (an MJD in float64
    resolves 0.6 µs only).
    """
    stamps = MJD_EPOCH + pd.to_timedelta(np.asarray(micro, dtype=np.int64), "us")
    return np.asarray(stamps.strftime("%Y-%m-%dT%H:%M:%S.%fZ"))


class _Problems:
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
    table: RawTable, spec: str, problems: _Problems, unit: str = ""
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


def _decimal_microseconds(text: str, unit_us: int, offset_us: int) -> float:
    """``Decimal(text) · unit + offset`` rounded to an integer number of µs (NaN if invalid)."""
    try:
        value = Decimal(text.strip())
    except InvalidOperation:
        return float("nan")
    if not value.is_finite():
        return float("nan")
    return float((value * unit_us).to_integral_value(ROUND_HALF_EVEN) + offset_us)


@dataclass(frozen=True)
class TimeColumn:
    """How a time column is written.

    Attributes
    ----------
    format : {"iso", "jd", "mjd", "unix"}
        ISO-8601 strings (a ``T`` or a space between date and time; an explicit UTC offset
        such as ``Z`` or ``+02:00`` is honoured), Julian dates, Modified Julian Dates, or
        Unix seconds (POSIX time, which is UTC by definition).
    scale : {"utc", "tt", "tdb"}
        Time scale of the values.
    """

    format: str = "iso"
    scale: str = "utc"

    def __post_init__(self) -> None:
        if self.format not in TIME_FORMATS:
            raise ValueError(f"time format must be one of {', '.join(TIME_FORMATS)}")
        if self.scale not in TIME_SCALES:
            raise ValueError(f"time scale must be one of {', '.join(TIME_SCALES)}")
        if self.format == "unix" and self.scale != "utc":
            raise ValueError("Unix time counts UTC seconds: its time scale must be utc")


def parse_times(
    table: RawTable, spec: str, time: TimeColumn, problems: _Problems
) -> tuple[str, np.ndarray]:
    """A time column as UTC microseconds since MJD 0 (float64, exact integers).

    Decimal numbers are converted exactly (``decimal``), ISO strings by pandas, both
    rounded to the microsecond; TT and TDB go to UTC through astropy.
    """
    name, cells = table.cells(spec)
    if time.format == "iso":
        text = pd.Series(cells, dtype=str).str.strip()
        parsed = pd.to_datetime(text, errors="coerce", format="ISO8601", utc=True)
        ns = (parsed - MJD_EPOCH).to_numpy(dtype="timedelta64[ns]").astype(np.int64)
        micro = np.where(parsed.isna().to_numpy(), np.nan, (ns + 500) // 1000)
        micro = micro.astype(float)
        what = "an ISO-8601 time (YYYY-MM-DDThh:mm:ss[.fff])"
    else:
        if table.decimal != ".":
            cells = [c.replace(table.decimal, ".") for c in cells]
        unit, offset = {
            "jd": (MICROSECONDS_PER_DAY, -4_800_001 * (MICROSECONDS_PER_DAY // 2)),  # JD − MJD
            "mjd": (MICROSECONDS_PER_DAY, 0),
            "unix": (1_000_000, _UNIX_EPOCH_MJD * MICROSECONDS_PER_DAY),
        }[time.format]
        micro = np.array([_decimal_microseconds(c, unit, offset) for c in cells])
        what = {"jd": "a Julian date", "mjd": "a Modified Julian Date", "unix": "Unix seconds"}[
            time.format
        ]
    empty = np.array([not c.strip() for c in cells])
    problems.flag(empty, name, "missing time (empty field)")
    problems.flag(np.isnan(micro) & ~empty, name, lambda r: f"cannot read {cells[r]!r} as {what}")
    if time.scale != "utc":
        micro = _to_utc(micro, time.scale)
    return name, micro


def _to_utc(micro: np.ndarray, scale: str) -> np.ndarray:
    """TT/TDB microseconds since MJD 0 → UTC microseconds (astropy, rounded to 1 µs)."""
    from lightcurve.frames import astropy_offline

    astropy_offline()
    from astropy.time import Time

    out = np.full_like(micro, np.nan)
    ok = np.isfinite(micro)
    if ok.any():
        days = np.floor(micro[ok] / MICROSECONDS_PER_DAY)
        rest = (micro[ok] - days * MICROSECONDS_PER_DAY) / MICROSECONDS_PER_DAY
        utc = Time(days + _JD_MINUS_MJD, rest, format="jd", scale=scale).utc
        out[ok] = np.round(
            (utc.jd1 - _JD_MINUS_MJD) * MICROSECONDS_PER_DAY + utc.jd2 * MICROSECONDS_PER_DAY
        )
    return out


# --------------------------------------------------------------------------- import


@dataclass(frozen=True)
class Topocentric:
    """Topocentric coordinates recorded with each measurement.

    Attributes
    ----------
    kind : {"alt-az", "ra-dec"}
        Elevation and azimuth (deg, azimuth from north through east), or right ascension
        and declination (deg, GCRS axes).
    columns : tuple of str
        The three columns: the two angles and the range.
    range_kind : {"slant", "height"}
        The third column is the site → object distance (km), or the object's height above
        the WGS84 ellipsoid (km), converted to the distance along the line of sight.
    """

    kind: str
    columns: tuple[str, str, str]
    range_kind: str = "slant"

    def __post_init__(self) -> None:
        if self.kind not in ("alt-az", "ra-dec"):
            raise ValueError(f"kind must be 'alt-az' or 'ra-dec', got {self.kind!r}")
        if len(self.columns) != 3:
            raise ValueError(
                f"three columns are needed (two angles and a range), got {self.columns}"
            )
        if self.range_kind not in ("slant", "height"):
            raise ValueError(f"range kind must be 'slant' or 'height', got {self.range_kind!r}")


def _angles_and_range(
    table: RawTable, topocentric: Topocentric, problems: _Problems
) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[str]]:
    names, values = [], []
    for spec, unit in zip(topocentric.columns, (" (deg)", " (deg)", " (km)"), strict=True):
        name, column = numeric_column(table, spec, problems, unit)
        names.append(name)
        values.append(column)
    first, second, distance = values
    if topocentric.kind == "alt-az":
        problems.flag(
            (first < 0) | (first > 90),
            names[0],
            lambda r: f"elevation {first[r]:g} deg is not in [0, 90] (below the horizon?)",
        )
    else:
        problems.flag(
            np.abs(second) > 90,
            names[1],
            lambda r: f"declination {second[r]:g} deg is not in [-90, 90]",
        )
    problems.flag(
        ~(distance > 0),
        names[2],
        lambda r: f"{topocentric.range_kind} {distance[r]:g} km must be > 0",
    )
    return first, second, distance, names


def import_photometry(
    table: RawTable,
    time_column: str,
    time: TimeColumn,
    mag_column: str,
    site: Site,
    *,
    err_column: str | None = None,
    mag_err: float | None = None,
    tles: Sequence[TLE] | None = None,
    topocentric: Topocentric | None = None,
    max_tle_age_days: float | None = 3.0,
    shadow_model: str = "conical",
    umbra: str = "flag",
    drop_bad_rows: bool = False,
    allow_duplicate_epochs: bool = False,
    name: str | None = None,
) -> Observations:
    """An observation table from a photometry table, a site and the object's geometry.

    Parameters
    ----------
    table : RawTable
        From :func:`read_table`.
    time_column, mag_column, err_column : str
        Column names or 1-based positions; magnitudes in mag, errors (1σ) in mag.
    time : TimeColumn
        Format and scale of the times.
    site : Site
    mag_err : float, optional
        One 1σ error (mag) for every row, when the table has no error column.
    tles : sequence of TLE, optional
        Element sets of the object (:func:`lightcurve.tle.select_object`): the geometry
        comes from SGP4.
    topocentric : Topocentric, optional
        Or: the geometry comes from the recorded topocentric coordinates.
    max_tle_age_days : float or None
        Warn when a row is farther than this from its TLE's epoch.
    shadow_model : {"conical", "cylindrical"}
    umbra : {"flag", "drop"}
        Rows with the object in the Earth's umbra: kept (``shadow`` column says
        ``umbra``) or dropped and counted in ``meta['dropped_umbra']``.
    drop_bad_rows : bool
        Drop rows with bad values (listed in ``Observations.dropped``) instead of raising.
    allow_duplicate_epochs : bool
        Accept several rows at one time (e.g. several objects in one table).
    name : str, optional
        Object name for the metadata.

    Returns
    -------
    Observations
        Sorted by time; ``mag``, ``mag_err``, GCRS vectors (km) and the geometry columns.

    Raises
    ------
    ObservationError
        Naming the file, the row, the column and the line of the first bad value.
    """
    from lightcurve import satellite_geometry

    if (tles is None) == (topocentric is None):
        raise ValueError("give either TLEs or topocentric columns for the geometry")
    if (err_column is None) == (mag_err is None):
        raise ValueError("give either an error column or one magnitude error for all rows")
    if mag_err is not None and not mag_err > 0:
        raise ValueError(f"the magnitude error must be > 0 mag, got {mag_err}")
    if umbra not in ("flag", "drop"):
        raise ValueError(f"umbra must be 'flag' or 'drop', got {umbra!r}")
    problems = _Problems(table, drop_bad_rows)
    time_name, micro = parse_times(table, time_column, time, problems)
    _, mag = numeric_column(table, mag_column, problems, " (mag)")
    if err_column is not None:
        err_name, err = numeric_column(table, err_column, problems, " (mag)")
        problems.flag(~(err > 0), err_name, lambda r: f"magnitude error {err[r]:g} must be > 0")
    else:
        err = np.full(len(table), float(mag_err))
    if topocentric is not None:
        first, second, distance, _ = _angles_and_range(table, topocentric, problems)
    rows = np.flatnonzero(~problems.bad)
    if rows.size == 0:
        raise ObservationError("no valid rows", table.source)
    mjd = micro[rows] / MICROSECONDS_PER_DAY
    if tles is not None:
        geometry = satellite_geometry.from_tle(tles, site, mjd, max_tle_age_days, shadow_model)
        elevation = geometry.horizontal[0]
        below = np.zeros(len(table), dtype=bool)
        below[rows] = elevation < 0
        problems.flag(
            below,
            time_name,
            lambda r: (
                f"the object is below the horizon ({elevation[np.searchsorted(rows, r)]:.1f}"
                " deg) at this time: wrong time, time scale, site or TLE?"
            ),
        )
        keep = ~below[rows]
        geometry, rows = geometry.subset(keep), rows[keep]
    else:
        if topocentric.range_kind == "height" and topocentric.kind == "alt-az":
            from lightcurve.topocentric import range_from_height

            distance = distance.copy()
            distance[rows] = range_from_height(site, first[rows], second[rows], distance[rows])
        elif topocentric.range_kind == "height":
            raise ValueError("a height instead of a range is supported with alt-az columns only")
        build = (
            satellite_geometry.from_horizontal
            if topocentric.kind == "alt-az"
            else satellite_geometry.from_radec
        )
        geometry = build(site, mjd, first[rows], second[rows], distance[rows], shadow_model)
    frame = geometry.table()
    frame.insert(0, "epoch", epoch_strings(micro[rows]))
    frame.insert(2, "mag", mag[rows])
    frame.insert(3, "mag_err", err[rows])
    meta: dict[str, str] = {}
    meta.update(table.meta)
    meta.update(
        {
            "object": name or table.meta.get("object") or Path(table.source).stem,
            "frame": "GCRS",
            "site": site.label,
            "target": "satellite",
            "imported_from": Path(table.source).name,
            "time": f"column '{time_name}', {time.format} ({time.scale.upper()}), stored as UTC",
            "shadow_model": shadow_model,
        }
    )
    if tles is not None:
        meta["norad"] = str(tles[0].norad)
        meta["geometry"] = (
            f"SGP4 from {len(tles)} element set(s) in {Path(tles[0].source or 'TLEs').name}"
        )
    else:
        meta["geometry"] = (
            f"{topocentric.kind} columns {', '.join(topocentric.columns)} "
            f"({'range' if topocentric.range_kind == 'slant' else 'height above WGS84'}, km)"
        )
    in_umbra = frame["shadow"].to_numpy() == "umbra"
    if umbra == "drop" and in_umbra.any():
        meta["dropped_umbra"] = str(int(in_umbra.sum()))
        frame, rows = frame.loc[~in_umbra].reset_index(drop=True), rows[~in_umbra]
    order = np.argsort(frame["mjd"].to_numpy(), kind="stable")
    if np.any(np.diff(order) < 0):
        meta["notes"] = "rows sorted by time"
    frame, rows = frame.iloc[order].reset_index(drop=True), rows[order]
    same = np.flatnonzero(np.diff(frame["mjd"].to_numpy()) == 0)
    if same.size and not allow_duplicate_epochs:
        first_row, second_row = int(rows[same[0]]) + 1, int(rows[same[0] + 1]) + 1
        raise ObservationError(
            f"same time as row {first_row}: a repeated measurement? Use "
            "allow_duplicate_epochs (--allow-duplicate-epochs) for tables of several objects",
            table.source,
            second_row,
            time_name,
        )
    if same.size:
        meta["duplicate_epochs"] = "allowed"
    if problems.found:
        meta["dropped_bad_rows"] = str(len(problems.found))
    canonical = validate_table(
        frame, table.source, meta, allow_duplicate_epochs=allow_duplicate_epochs
    )
    return Observations(canonical, meta, table.source, problems.found)


def read_epochs(path: str | Path) -> tuple[pd.DataFrame, dict[str, str], np.ndarray]:
    """The epochs and other columns of an existing observation or photometry file.

    Parameters
    ----------
    path : path-like
        A text table (:func:`read_table`) or a Parquet file with an ``epoch`` (ISO-8601,
        UTC unless it states an offset; preferred) or ``mjd`` (UTC) column.

    Returns
    -------
    columns : pandas.DataFrame
        The other columns (numeric where every value is).
    meta : dict
        The file's metadata.
    micro : (n,) numpy.ndarray
        UTC microseconds since MJD 0 (float64 holding integers).
    """
    path = Path(path)
    parquet = path.suffix.lower() in (".parquet", ".pq")
    table = _parquet_table(path) if parquet else read_table(path)
    problems = _Problems(table, drop=False)
    # The ISO epoch is exact to the microsecond; an MJD in float64 resolves 0.6 µs.
    if "epoch" in table.columns:
        _, micro = parse_times(table, "epoch", TimeColumn("iso"), problems)
    elif "mjd" in table.columns:
        _, micro = parse_times(table, "mjd", TimeColumn("mjd"), problems)
    else:
        raise ObservationError("no 'epoch' (ISO-8601 UTC) or 'mjd' (UTC) column", str(path))
    columns = pd.DataFrame(table.rows, columns=table.columns).drop(
        columns=[c for c in ("epoch", "mjd") if c in table.columns]
    )
    for name in columns:
        numeric = pd.to_numeric(columns[name], errors="coerce")
        if numeric.notna().all():
            columns[name] = numeric
    return columns, table.meta, micro


def _parquet_table(path: Path) -> RawTable:
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
