"""Observation tables: the in-memory form of an observation file and its validation.

An :class:`Observations` holds one table with one row per measurement and the file's
metadata. Columns (the contract of ``docs/formats.md``):

``mjd``
    Epoch, Modified Julian Date, UTC (float64). Files may give ``epoch`` (ISO-8601 UTC)
    instead; both are kept in the table.
``mag``, ``mag_err``
    Apparent magnitude and its 1σ uncertainty (> 0). Absent in geometry-only files.
``sun_x, sun_y, sun_z``
    Object → Sun vector, inertial frame (J2000/GCRS, or ecliptic J2000 for asteroids), km.
``obs_x, obs_y, obs_z``
    Object → observer vector, same frame, km.
Optional: ``filter`` (str), ``exposure_s`` (s), ``lightcurve_id`` (int; rows of one light
curve), ``relative`` (bool; the light curve has an arbitrary magnitude offset), truth
columns ``q1 q2 q3 q4 wx wy wz`` (attitude inertial → body, body rates in rad/s), and the
geometry of Earth satellites written by ``geometry --tle`` and ``import``: ``shadow``
(sunlit, penumbra, umbra, annular), ``sunlit_fraction``, ``phase_angle_deg``, ``range_km``,
``elevation_deg``, ``azimuth_deg``, ``airmass``, ``tle_age_days``; the object's geocentric
position ``obj_x, obj_y, obj_z`` (km) and velocity ``obj_vx, obj_vy, obj_vz`` (km/s), same
inertial frame, written by ``geometry`` (attitude profiles need them); and those of a
simulation under observing conditions: ``extinction_mag`` (mag) and ``saturated`` (bool).

Kilometres and MJD are the file units; the accessors (:attr:`Observations.times`,
:attr:`Observations.sun_vectors`, …) return SI values (s, m).
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from lightcurve.io.observation_rules import (
    OBJECT_RANGE_KM,
    OBJECT_SPEED_KM_S,
    OBSERVER_RANGE_KM,
    SHADOW_STATES,
    SUN_RANGE_KM,
    ObservationError,
)

__all__ = [
    "KM",
    "OBJECT_POSITION_COLUMNS",
    "OBJECT_VELOCITY_COLUMNS",
    "OBSERVER_COLUMNS",
    "SUN_COLUMNS",
    "TRUTH_COLUMNS",
    "ObservationError",
    "Observations",
    "validate_table",
]

KM = 1000.0
SECONDS_PER_DAY = 86400.0
SUN_COLUMNS = ("sun_x", "sun_y", "sun_z")
OBSERVER_COLUMNS = ("obs_x", "obs_y", "obs_z")
TRUTH_COLUMNS = ("q1", "q2", "q3", "q4", "wx", "wy", "wz")
#: Geocentric position (km) and velocity (km/s) of the object, inertial frame.
OBJECT_POSITION_COLUMNS = ("obj_x", "obj_y", "obj_z")
OBJECT_VELOCITY_COLUMNS = ("obj_vx", "obj_vy", "obj_vz")
OBJECT_COLUMNS = (*OBJECT_POSITION_COLUMNS, *OBJECT_VELOCITY_COLUMNS)
MAG_COLUMNS = ("mag", "mag_err")
#: Geometry written alongside the vectors by ``geometry --tle`` and ``import``.
GEOMETRY_NUMERIC = (
    "sunlit_fraction",
    "phase_angle_deg",
    "range_km",
    "elevation_deg",
    "azimuth_deg",
    "airmass",
    "tle_age_days",
)
GEOMETRY_COLUMNS = ("shadow", *GEOMETRY_NUMERIC)
#: Written by ``simulate`` under observing conditions
#: (``lightcurve.photometry.noise.ObservingNoise``).
CONDITIONS_COLUMNS = ("extinction_mag", "saturated")
OPTIONAL_NUMERIC = (
    "exposure_s",
    "lightcurve_id",
    *TRUTH_COLUMNS,
    *GEOMETRY_NUMERIC,
    "extinction_mag",
    *OBJECT_COLUMNS,
)
FLAG_COLUMNS = ("relative", "saturated")
KNOWN_COLUMNS = (
    "epoch",
    "mjd",
    *MAG_COLUMNS,
    *SUN_COLUMNS,
    *OBSERVER_COLUMNS,
    "filter",
    "exposure_s",
    "lightcurve_id",
    "relative",
    *TRUTH_COLUMNS,
    *GEOMETRY_COLUMNS,
    *CONDITIONS_COLUMNS,
    *OBJECT_COLUMNS,
)


@dataclass
class RowProblem:
    """One invalid row found during validation (for ``drop_bad_rows`` reports)."""

    row: int
    column: str | None
    message: str


@dataclass
class Observations:
    """A validated observation table with its metadata.

    Parameters
    ----------
    table : pandas.DataFrame
        Canonical columns (see module docstring), sorted by ``mjd``.
    meta : dict of str
        ``# key: value`` header entries (``object``, ``frame``, ``site``, ``target`` …).
    source : str, optional
        Where the table was read from.
    dropped : list of RowProblem
        Rows removed by ``drop_bad_rows`` and why.
    """

    table: pd.DataFrame
    meta: dict[str, str] = field(default_factory=dict)
    source: str | None = None
    dropped: list[RowProblem] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.table)

    @property
    def mjd(self) -> np.ndarray:
        """Epochs as MJD (UTC), shape (n,)."""
        return self.table["mjd"].to_numpy(dtype=float)

    @property
    def times(self) -> np.ndarray:
        """Seconds since the first epoch, shape (n,) (UTC differences, no leap seconds)."""
        mjd = self.mjd
        return (mjd - mjd[0]) * SECONDS_PER_DAY

    @property
    def sun_vectors(self) -> np.ndarray:
        """Object → Sun vectors in the inertial frame, metres, shape (n, 3)."""
        return self.table[list(SUN_COLUMNS)].to_numpy(dtype=float) * KM

    @property
    def observer_vectors(self) -> np.ndarray:
        """Object → observer vectors in the inertial frame, metres, shape (n, 3)."""
        return self.table[list(OBSERVER_COLUMNS)].to_numpy(dtype=float) * KM

    @property
    def has_object_position(self) -> bool:
        """Whether the object-position columns ``obj_x, obj_y, obj_z`` are present."""
        return all(c in self.table for c in OBJECT_POSITION_COLUMNS)

    @property
    def has_object_velocity(self) -> bool:
        """Whether the object-velocity columns ``obj_vx, obj_vy, obj_vz`` are present."""
        return all(c in self.table for c in OBJECT_VELOCITY_COLUMNS)

    @property
    def object_positions(self) -> np.ndarray:
        """Geocentric object positions in the inertial frame, metres, shape (n, 3)."""
        self._require(OBJECT_POSITION_COLUMNS)
        return self.table[list(OBJECT_POSITION_COLUMNS)].to_numpy(dtype=float) * KM

    @property
    def object_velocities(self) -> np.ndarray:
        """Geocentric object velocities in the inertial frame, m/s, shape (n, 3)."""
        self._require(OBJECT_VELOCITY_COLUMNS)
        return self.table[list(OBJECT_VELOCITY_COLUMNS)].to_numpy(dtype=float) * KM

    @property
    def has_magnitudes(self) -> bool:
        """Whether ``mag`` and ``mag_err`` are present."""
        return all(c in self.table for c in MAG_COLUMNS)

    @property
    def magnitudes(self) -> np.ndarray:
        """Measured magnitudes, shape (n,)."""
        self._require(MAG_COLUMNS)
        return self.table["mag"].to_numpy(dtype=float)

    @property
    def magnitude_errors(self) -> np.ndarray:
        """1σ magnitude errors, shape (n,)."""
        self._require(MAG_COLUMNS)
        return self.table["mag_err"].to_numpy(dtype=float)

    @property
    def has_truth(self) -> bool:
        """Whether the truth columns ``q1..q4, wx..wz`` are present."""
        return all(c in self.table for c in TRUTH_COLUMNS)

    @property
    def truth(self) -> np.ndarray:
        """True states ``[q1..q4, wx, wy, wz]`` (rad/s), shape (n, 7)."""
        self._require(TRUTH_COLUMNS)
        return self.table[list(TRUTH_COLUMNS)].to_numpy(dtype=float)

    @property
    def lightcurve_ids(self) -> np.ndarray:
        """Light-curve index of every row (all zero when the file has one light curve)."""
        if "lightcurve_id" in self.table:
            return self.table["lightcurve_id"].to_numpy(dtype=int)
        return np.zeros(len(self.table), dtype=int)

    @property
    def relative(self) -> np.ndarray:
        """Whether each row belongs to a relative (uncalibrated) light curve."""
        if "relative" in self.table:
            return self.table["relative"].to_numpy(dtype=bool)
        return np.zeros(len(self.table), dtype=bool)

    @property
    def epochs(self) -> pd.DatetimeIndex:
        """Epochs as UTC timestamps."""
        return mjd_to_datetime(self.mjd)

    @property
    def name(self) -> str:
        """Object name from the metadata, else the file stem."""
        if "object" in self.meta:
            return self.meta["object"]
        return str(self.source).rsplit("/", 1)[-1].split(".")[0] if self.source else "object"

    def _require(self, columns: Iterable[str]) -> None:
        missing = [c for c in columns if c not in self.table]
        if missing:
            raise ObservationError(f"missing column(s) {', '.join(missing)}", self.source)

    def with_columns(self, **columns: Sequence[float] | np.ndarray) -> Observations:
        """A copy with columns added or replaced (validated again)."""
        table = self.table.copy()
        for name, values in columns.items():
            table[name] = np.asarray(values)
        return Observations(
            validate_table(table, self.source, self.meta), dict(self.meta), self.source
        )


MJD_EPOCH = pd.Timestamp("1858-11-17T00:00:00", tz="UTC")


def mjd_to_datetime(mjd: np.ndarray) -> pd.DatetimeIndex:
    """MJD (UTC) → timezone-aware UTC timestamps (microsecond resolution)."""
    return MJD_EPOCH + pd.to_timedelta(np.round(np.asarray(mjd) * SECONDS_PER_DAY * 1e6), "us")


#: Largest round-off of an epoch carried as a float64 MJD near the present (a few ulp of
#: ~1.3 µs): epochs within it of whole milliseconds are whole milliseconds.
EPOCH_ROUND_OFF_US = 4


def iso_epochs(mjd: np.ndarray) -> np.ndarray:
    """MJD (UTC) → ISO-8601 strings at the precision of the data, ``…T04:48:07.000Z``.

    float64 MJD carries ~1 µs near the present; printing microseconds would show that
    round-off (``06.999999``). When every epoch lies within :data:`EPOCH_ROUND_OFF_US` of a
    whole millisecond, all are written with milliseconds; otherwise (epochs measured to the
    microsecond) all with microseconds. The ``mjd`` column keeps full precision.
    """
    stamps = mjd_to_datetime(mjd)
    rounded = stamps.round("ms")
    offset_us = np.abs((stamps - rounded).to_numpy().astype("timedelta64[us]").astype(np.int64))
    if offset_us.size and offset_us.max() > EPOCH_ROUND_OFF_US:
        return np.asarray(stamps.strftime("%Y-%m-%dT%H:%M:%S.%fZ"))
    return np.asarray([f"{text[:-3]}Z" for text in rounded.strftime("%Y-%m-%dT%H:%M:%S.%f")])


def datetime_to_mjd(epochs: pd.Series | pd.DatetimeIndex) -> np.ndarray:
    """UTC timestamps → MJD (UTC)."""
    delta = pd.DatetimeIndex(epochs) - MJD_EPOCH
    return delta.total_seconds().to_numpy() / SECONDS_PER_DAY


def _suggest(name: str, columns: Iterable[str]) -> str:
    close = difflib.get_close_matches(name, list(columns), n=1, cutoff=0.6)
    return f" (found '{close[0]}': misspelled?)" if close else ""


def validate_table(
    table: pd.DataFrame,
    source: str | None = None,
    meta: dict[str, str] | None = None,
    *,
    require_magnitudes: bool = True,
    drop_bad_rows: bool = False,
    problems: list[RowProblem] | None = None,
    row_offset: int = 0,
    allow_duplicate_epochs: bool = False,
) -> pd.DataFrame:
    """Check an observation table and return it in canonical form.

    Parameters
    ----------
    table : pandas.DataFrame
        Raw table as read from a file.
    source : str, optional
        File name for messages.
    meta : dict, optional
        File metadata; ``target`` ("satellite" by default, or "asteroid") selects the
        plausible observer-range bounds.
    require_magnitudes : bool
        Require ``mag`` and ``mag_err`` (False for geometry files).
    drop_bad_rows : bool
        Drop invalid rows instead of raising; each is appended to ``problems``.
    problems : list, optional
        Receives :class:`RowProblem` entries when ``drop_bad_rows``.
    row_offset : int
        Added to row numbers in messages (unused rows such as headers before the data).
    allow_duplicate_epochs : bool
        Accept repeated epochs within a light curve (independent measurements at one time,
        as in some DAMIT files). Also enabled by the metadata ``duplicate_epochs: allowed``.

    Returns
    -------
    pandas.DataFrame
        Canonical table: ``mjd`` and ``epoch`` present, float columns as float64, sorted by
        time, index reset.

    Raises
    ------
    ObservationError
        Naming the file, the row and the column of the first problem.
    """
    meta = meta or {}
    problems = [] if problems is None else problems
    table = table.copy()
    table.columns = [str(c).strip() for c in table.columns]
    duplicated = table.columns[table.columns.duplicated()].tolist()
    if duplicated:
        raise ObservationError(f"duplicate column(s) {', '.join(duplicated)}", source)

    required = [*SUN_COLUMNS, *OBSERVER_COLUMNS]
    if require_magnitudes:
        required += list(MAG_COLUMNS)
    if "mjd" not in table and "epoch" not in table:
        raise ObservationError(
            "no time column: give 'epoch' (ISO-8601 UTC) or 'mjd' (UTC)"
            + _suggest("epoch", table.columns)
            + _suggest("mjd", table.columns),
            source,
        )
    for name in required:
        if name not in table:
            raise ObservationError(
                f"missing required column '{name}'" + _suggest(name, table.columns),
                source,
                column=name,
            )

    for group in (OBJECT_POSITION_COLUMNS, OBJECT_VELOCITY_COLUMNS):
        present = [c for c in group if c in table]
        if present and len(present) < 3:
            missing = next(c for c in group if c not in table)
            raise ObservationError(
                f"missing column '{missing}': {', '.join(group)} go together",
                source,
                column=missing,
            )
    if OBJECT_VELOCITY_COLUMNS[0] in table and OBJECT_POSITION_COLUMNS[0] not in table:
        raise ObservationError(
            "object velocity columns without the position columns "
            + ", ".join(OBJECT_POSITION_COLUMNS),
            source,
            column=OBJECT_POSITION_COLUMNS[0],
        )

    bad = np.zeros(len(table), dtype=bool)

    def flag(mask: np.ndarray, column: str | None, message: str) -> None:
        nonlocal bad
        mask = np.asarray(mask, dtype=bool) & ~bad
        if not mask.any():
            return
        rows = np.flatnonzero(mask)
        if not drop_bad_rows:
            first = int(rows[0])
            extra = f" ({rows.size - 1} more row(s) like this)" if rows.size > 1 else ""
            raise ObservationError(message + extra, source, first + 1 + row_offset, column)
        problems.extend(RowProblem(int(r) + 1 + row_offset, column, message) for r in rows)
        bad |= mask

    numeric = [c for c in (*required, *OPTIONAL_NUMERIC, "mjd") if c in table]
    for name in numeric:
        raw = table[name]
        values = pd.to_numeric(raw, errors="coerce")
        missing = raw.isna().to_numpy()
        flag(missing, name, "missing value (empty field or truncated file?)")
        is_nan = values.isna().to_numpy() & ~missing
        if not pd.api.types.is_numeric_dtype(raw):
            text_nan = raw.astype(str).str.strip().str.lower().isin(("nan", "+nan", "-nan"))
            flag(is_nan & text_nan.to_numpy(), name, "value is NaN")
        else:
            flag(is_nan, name, "value is NaN")
        flag(
            is_nan,
            name,
            f"non-numeric value {_first_bad(raw, values)!r}",
        )
        table[name] = values.astype(float)
        flag(
            ~np.isfinite(table[name].to_numpy()) & ~table[name].isna().to_numpy(),
            name,
            "value is not finite (inf)",
        )

    if "epoch" in table:
        parsed = pd.to_datetime(table["epoch"], utc=True, errors="coerce", format="ISO8601")
        flag(parsed.isna().to_numpy(), "epoch", "cannot parse ISO-8601 UTC epoch")
        epoch_mjd = datetime_to_mjd(parsed.fillna(MJD_EPOCH))
        if "mjd" in table:
            mismatch = np.abs(epoch_mjd - table["mjd"].fillna(0).to_numpy()) * SECONDS_PER_DAY
            flag(mismatch > 1e-3, "mjd", "'mjd' and 'epoch' disagree by more than 1 ms")
        else:
            table["mjd"] = epoch_mjd
    table["epoch"] = iso_epochs(table["mjd"].fillna(0).to_numpy())

    if require_magnitudes:
        flag(table["mag_err"].to_numpy() <= 0, "mag_err", "mag_err must be > 0 (1-sigma, mag)")
    for columns, bounds, label in (
        (SUN_COLUMNS, SUN_RANGE_KM, "object->Sun"),
        (
            OBSERVER_COLUMNS,
            OBSERVER_RANGE_KM.get(meta.get("target", "satellite"), OBSERVER_RANGE_KM["satellite"]),
            "object->observer",
        ),
    ):
        ranges = np.linalg.norm(table[list(columns)].fillna(1.0).to_numpy(), axis=1)
        flag(ranges == 0, columns[0], f"{label} vector has zero length")
        flag(
            ranges < bounds[0],
            columns[0],
            f"{label} range {_first(ranges, ranges < bounds[0]):.4g} km is below "
            f"{bounds[0]:.0e} km: vectors must be in km (AU given?)",
        )
        flag(
            ranges > bounds[1],
            columns[0],
            f"{label} range {_first(ranges, ranges > bounds[1]):.4g} km is above "
            f"{bounds[1]:.0e} km: vectors must be in km (metres given?)"
            + (
                " — set '# target: asteroid' for solar-system bodies"
                if label == "object->observer" and meta.get("target") != "asteroid"
                else ""
            ),
        )
    if OBJECT_POSITION_COLUMNS[0] in table:
        distance = np.linalg.norm(
            table[list(OBJECT_POSITION_COLUMNS)].fillna(OBJECT_RANGE_KM[0]).to_numpy(), axis=1
        )
        outside = (distance < OBJECT_RANGE_KM[0]) | (distance > OBJECT_RANGE_KM[1])
        flag(
            outside,
            OBJECT_POSITION_COLUMNS[0],
            f"geocentric object distance {_first(distance, outside):.4g} km is outside "
            f"{OBJECT_RANGE_KM[0]:g}..{OBJECT_RANGE_KM[1]:.0e} km: positions must be "
            "geocentric, in km",
        )
    if OBJECT_VELOCITY_COLUMNS[0] in table:
        speed = np.linalg.norm(table[list(OBJECT_VELOCITY_COLUMNS)].fillna(0.0).to_numpy(), axis=1)
        flag(
            speed > OBJECT_SPEED_KM_S,
            OBJECT_VELOCITY_COLUMNS[0],
            f"object speed {_first(speed, speed > OBJECT_SPEED_KM_S):.4g} km/s is above "
            f"{OBJECT_SPEED_KM_S:g} km/s: velocities must be in km/s (m/s given?)",
        )
    if "sunlit_fraction" in table:
        fraction = table["sunlit_fraction"].fillna(1.0).to_numpy()
        flag((fraction < 0) | (fraction > 1), "sunlit_fraction", "sunlit_fraction not in [0, 1]")
    if "shadow" in table:
        table["shadow"] = table["shadow"].astype(str).str.strip()
        flag(
            ~table["shadow"].isin(SHADOW_STATES).to_numpy(),
            "shadow",
            f"shadow must be one of {', '.join(SHADOW_STATES)}",
        )
    if all(c in table for c in TRUTH_COLUMNS[:4]):
        qn = np.linalg.norm(table[list(TRUTH_COLUMNS[:4])].fillna(1.0).to_numpy(), axis=1)
        flag(np.abs(qn - 1) > 1e-6, "q1", "truth quaternion is not unit norm")

    groups = table["lightcurve_id"].fillna(-1).to_numpy() if "lightcurve_id" in table else None
    mjd = table["mjd"].to_numpy()
    same_group = (
        np.ones(len(table) - 1, dtype=bool) if groups is None else groups[1:] == groups[:-1]
    )
    step = np.diff(mjd)
    if not (allow_duplicate_epochs or meta.get("duplicate_epochs") == "allowed"):
        flag(
            np.r_[False, same_group & (step == 0)],
            "mjd" if "epoch" not in table else "epoch",
            "duplicate epoch",
        )
    flag(
        np.r_[False, same_group & (step < 0)],
        "mjd" if "epoch" not in table else "epoch",
        "epochs are not in increasing order",
    )

    for name in FLAG_COLUMNS:
        if name in table:
            table[name] = table[name].astype(str).str.lower().isin(("1", "true", "yes"))
    if "filter" in table:
        table["filter"] = table["filter"].astype(str)

    table = table.loc[~bad]
    if table.empty:
        raise ObservationError("no valid rows", source)
    if "lightcurve_id" in table:
        table["lightcurve_id"] = table["lightcurve_id"].astype(np.int64)
        table = table.sort_values("mjd", kind="stable")
    order = [c for c in KNOWN_COLUMNS if c in table] + [c for c in table if c not in KNOWN_COLUMNS]
    return table[order].reset_index(drop=True)


def _first(values: np.ndarray, mask: np.ndarray) -> float:
    return float(values[np.flatnonzero(mask)[0]]) if mask.any() else float("nan")


def _first_bad(raw: pd.Series, values: pd.Series) -> object:
    bad = values.isna() & raw.notna()
    return raw[bad].iloc[0] if bad.any() else None
