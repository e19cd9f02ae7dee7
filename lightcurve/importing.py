"""Importing photometry: a table, a site and the target's geometry into observations.

:func:`import_photometry` turns a photometry table (:mod:`lightcurve.io.tables`) with its time
column (:mod:`lightcurve.sky.epochs`), a site, and either TLEs or topocentric coordinates recorded
with each measurement (:class:`Topocentric`) into a validated
:class:`~lightcurve.io.observations.Observations` (GCRS vectors in km, the geometry columns of
:mod:`lightcurve.sky.satellite_geometry`). Every bad value is reported with its row (1 = the
first data row), its column and its line in the file; ``drop_bad_rows`` drops such rows and
lists them instead.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lightcurve.io.observations import (
    ObservationError,
    Observations,
    validate_table,
)
from lightcurve.io.tables import CellProblems, RawTable, numeric_column
from lightcurve.photometry.bands import band_header
from lightcurve.sky.epochs import MICROSECONDS_PER_DAY, TimeColumn, epoch_strings, parse_times
from lightcurve.sky.sites import Site
from lightcurve.sky.tle import TLE

__all__ = [
    "Topocentric",
    "import_photometry",
]


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
    table: RawTable, topocentric: Topocentric, problems: CellProblems
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
    band: tuple[str, str] | None = None,
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
        Element sets of the object (:func:`lightcurve.sky.tle.select_object`): the geometry
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
    band : (str, str), optional
        ``(band, system)`` of the magnitudes (:mod:`lightcurve.photometry.bands`), recorded
        in the header; the inversion then takes the Sun's magnitude in that band.

    Returns
    -------
    Observations
        Sorted by time; ``mag``, ``mag_err``, GCRS vectors (km) and the geometry columns.

    Raises
    ------
    ObservationError
        Naming the file, the row, the column and the line of the first bad value.
    """
    from lightcurve.sky import satellite_geometry

    if (tles is None) == (topocentric is None):
        raise ValueError("give either TLEs or topocentric columns for the geometry")
    if (err_column is None) == (mag_err is None):
        raise ValueError("give either an error column or one magnitude error for all rows")
    if mag_err is not None and not mag_err > 0:
        raise ValueError(f"the magnitude error must be > 0 mag, got {mag_err}")
    if umbra not in ("flag", "drop"):
        raise ValueError(f"umbra must be 'flag' or 'drop', got {umbra!r}")
    problems = CellProblems(table, drop_bad_rows)
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
            from lightcurve.sky.topocentric import range_from_height

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
    if band is not None:
        meta.update(band_header(*band))
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
