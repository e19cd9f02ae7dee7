"""What every observation table must satisfy, importable without pandas.

The error type of bad observation input, the plausible vector ranges used to catch vectors
given in the wrong unit, and the reading of a text file with a clear error.
:mod:`lightcurve.io.observations` validates tables with them; readers that work on plain
arrays (:mod:`lightcurve.io.damit`) use them too, so that reading a file does not have to load
pandas.
"""

from __future__ import annotations

from pathlib import Path

__all__ = [
    "OBJECT_RANGE_KM",
    "OBJECT_SPEED_KM_S",
    "OBSERVER_RANGE_KM",
    "SHADOW_STATES",
    "SUN_RANGE_KM",
    "ObservationError",
    "read_text",
]

# Plausible ranges (km) used to catch vectors given in the wrong unit.
SUN_RANGE_KM = (1e6, 1e11)
OBSERVER_RANGE_KM = {"satellite": (100.0, 1e9), "asteroid": (1e3, 1e11)}
# Geocentric distance (km) and speed (km/s) of an Earth-orbiting object: from below the
# Earth's polar radius (6357 km) to well beyond the Moon; speeds below escape from LEO.
OBJECT_RANGE_KM = (6300.0, 2e6)
OBJECT_SPEED_KM_S = 20.0
# Values of the ``shadow`` column: how much of the Sun's disc the object sees past the Earth.
SHADOW_STATES = ("sunlit", "penumbra", "umbra", "annular")


class ObservationError(ValueError):
    """Bad observation input; the message names the file, the row and the column.

    Attributes
    ----------
    source : str or None
        File name.
    row : int or None
        Data row (1-based, first data row = 1).
    column : str or None
        Column name.
    """

    def __init__(
        self,
        message: str,
        source: str | None = None,
        row: int | None = None,
        column: str | None = None,
    ) -> None:
        self.source, self.row, self.column = source, row, column
        where = [str(source)] if source else []
        if row is not None:
            where.append(f"row {row}")
        if column:
            where.append(f"column '{column}'")
        super().__init__(f"{', '.join(where)}: {message}" if where else message)


def read_text(path: Path) -> str:
    """A text file's content; :class:`ObservationError` if it is not UTF-8."""
    try:
        return path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise ObservationError(f"not a UTF-8 text file ({exc.reason})", str(path)) from None
