"""Epochs of photometry and observation files: time columns to exact UTC microseconds.

Times are ISO-8601 strings, Julian dates, Modified Julian Dates or Unix seconds, in UTC, TT
or TDB (:class:`TimeColumn`); :func:`parse_times` converts them to UTC and rounds to the
microsecond (the resolution of observation files), parsing decimal strings exactly so that
the same instants written in any of the formats give identical files. :func:`read_epochs`
reads the epochs of an existing file, :func:`epoch_strings` writes them back as ISO-8601.
"""

from __future__ import annotations

from dataclasses import dataclass
from decimal import ROUND_HALF_EVEN, Decimal, InvalidOperation
from pathlib import Path

import numpy as np
import pandas as pd

from lightcurve.io.observations import (
    MJD_EPOCH,
    ObservationError,
)
from lightcurve.io.tables import CellProblems, RawTable, parquet_table, read_table

__all__ = [
    "MICROSECONDS_PER_DAY",
    "TIME_FORMATS",
    "TIME_SCALES",
    "TimeColumn",
    "epoch_strings",
    "parse_times",
    "read_epochs",
]


TIME_FORMATS = ("iso", "jd", "mjd", "unix")
TIME_SCALES = ("utc", "tt", "tdb")
MICROSECONDS_PER_DAY = 86_400_000_000
_JD_MINUS_MJD = 2_400_000.5
_UNIX_EPOCH_MJD = 40_587


def epoch_strings(micro: np.ndarray) -> np.ndarray:
    """ISO-8601 UTC strings (``…T…Z``, microseconds) of UTC microseconds since MJD 0.

    Written with the ``mjd`` column, they keep every microsecond exactly (an MJD in float64
    resolves 0.6 µs only).
    """
    stamps = MJD_EPOCH + pd.to_timedelta(np.asarray(micro, dtype=np.int64), "us")
    return np.asarray(stamps.strftime("%Y-%m-%dT%H:%M:%S.%fZ"))


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
    table: RawTable, spec: str, time: TimeColumn, problems: CellProblems
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
    from lightcurve.sky.frames import astropy_offline

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
    table = parquet_table(path) if parquet else read_table(path)
    problems = CellProblems(table, drop=False)
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
