"""Tabulated BRDF measurements (incidence and scatter angles → value) and the lab-table reader.

A `BRDFTable` holds, per measurement, the zenith and azimuth angles (degrees, the edge unit) of
the incoming direction (towards the source) and of the scattered direction (towards the
detector) in the sample frame (normal ``z``, azimuth measured from the sample's reference
direction ``x``), and the BRDF value in sr⁻¹. A negative zenith angle is allowed and means the
opposite azimuth (``(−θ, φ)`` is the direction ``(θ, φ + 180°)``), as in in-plane goniometer
scans.

`read_starlink_table` reads the Starlink v1.5 laboratory tables of Fankhauser, Askari & Tyson
(2023; ``data/starlink/``): whitespace-separated columns ``phi_i theta_i phi_o theta_o brdf``
whose header states that ``(phi, theta)`` are the **zenith** and **azimuth** angles (the reverse
of the usual physics naming); the reader takes the convention from that header line.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["BRDFTable", "BRDFTableError", "read_starlink_table"]

_COLUMNS = ("zenith_in", "azimuth_in", "zenith_out", "azimuth_out", "value")


class BRDFTableError(ValueError):
    """A BRDF table that cannot be read; the message names the file, line and column."""


def _unit_vectors(zenith_deg: np.ndarray, azimuth_deg: np.ndarray) -> np.ndarray:
    zenith, azimuth = np.radians(zenith_deg), np.radians(azimuth_deg)
    return np.stack(
        [np.sin(zenith) * np.cos(azimuth), np.sin(zenith) * np.sin(azimuth), np.cos(zenith)],
        axis=-1,
    )


@dataclass(frozen=True, eq=False)
class BRDFTable:
    """BRDF measurements: angles in degrees (sample frame) and values in sr⁻¹.

    Attributes
    ----------
    zenith_in, azimuth_in : (N,) ndarray
        Direction towards the source (deg).
    zenith_out, azimuth_out : (N,) ndarray
        Direction towards the detector (deg).
    value : (N,) ndarray
        BRDF (sr⁻¹).
    source : str
        Provenance (file name).
    """

    zenith_in: np.ndarray
    azimuth_in: np.ndarray
    zenith_out: np.ndarray
    azimuth_out: np.ndarray
    value: np.ndarray
    source: str = ""

    @classmethod
    def from_columns(cls, columns: Mapping[str, Any], source: str = "") -> BRDFTable:
        """Build a table from a mapping (dict, pandas DataFrame) with the columns
        ``zenith_in, azimuth_in, zenith_out, azimuth_out`` (deg) and ``value`` (sr⁻¹)."""
        missing = [name for name in _COLUMNS if name not in columns]
        if missing:
            raise BRDFTableError(f"{source or 'table'}: missing column(s) {', '.join(missing)}")
        arrays = [np.asarray(columns[name], dtype=np.float64).ravel() for name in _COLUMNS]
        if len({a.size for a in arrays}) != 1:
            raise BRDFTableError(f"{source or 'table'}: columns have different lengths")
        for name, array in zip(_COLUMNS, arrays, strict=True):
            if not np.all(np.isfinite(array)):
                row = int(np.argmin(np.isfinite(array)))
                raise BRDFTableError(f"{source or 'table'}: row {row}, column {name}: not finite")
        return cls(*arrays, source=source)

    def __len__(self) -> int:
        return int(self.value.size)

    def directions(self) -> tuple[np.ndarray, np.ndarray]:
        """Unit vectors ``(L, V)`` (N, 3) towards the source and the detector, sample frame."""
        return (
            _unit_vectors(self.zenith_in, self.azimuth_in),
            _unit_vectors(self.zenith_out, self.azimuth_out),
        )

    def select(self, mask: Any) -> BRDFTable:
        """The rows where ``mask`` (boolean (N,) or index array) selects."""
        return BRDFTable(*(getattr(self, name)[mask] for name in _COLUMNS), source=self.source)


_CONVENTION = re.compile(
    r"\((\w+),\s*(\w+)\)\s+are\s+the\s+zenith\s+and\s+azimuth\s+angles\s+of\s+(\w+)\s+light",
    re.IGNORECASE,
)


def read_starlink_table(path: str | Path) -> BRDFTable:
    """Read a Starlink laboratory BRDF table (Fankhauser et al. 2023).

    The header comments must state which columns are zenith and azimuth angles (``(phi_i,
    theta_i) are the zenith and azimuth angles of ingoing light``, likewise for the scattered
    light) and end with the column names line (``# phi_i theta_i phi_o theta_o brdf``).

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    BRDFTable
        Angles in degrees as in the file (zenith signed), values in sr⁻¹.

    Raises
    ------
    BRDFTableError
        Missing convention or column line, or a bad data line (the message names the file,
        line number and column).
    OSError
        The file cannot be opened.
    """
    path = Path(path)
    lines = path.read_text(encoding="utf-8").splitlines()
    comments = [line.lstrip("#").strip() for line in lines if line.lstrip().startswith("#")]
    header_text = " ".join(comments)
    roles: dict[str, tuple[str, str]] = {}
    for zenith, azimuth, which in _CONVENTION.findall(header_text):
        key = "in" if which.lower() in ("ingoing", "incoming", "incident") else "out"
        roles[key] = (zenith, azimuth)
    if set(roles) != {"in", "out"}:
        raise BRDFTableError(
            f"{path}: the header does not state which columns are the zenith and azimuth "
            "angles of the ingoing and scattered light"
        )
    names = next((c.split() for c in reversed(comments) if "brdf" in c.split()), None)
    needed = {*roles["in"], *roles["out"], "brdf"}
    if names is None or not needed <= set(names):
        raise BRDFTableError(f"{path}: no column line naming {', '.join(sorted(needed))}")
    rows = []
    for number, line in enumerate(lines, start=1):
        fields = line.split()
        if not fields or line.lstrip().startswith("#"):
            continue
        if len(fields) != len(names):
            raise BRDFTableError(
                f"{path}: line {number}: {len(fields)} fields, expected {len(names)} "
                f"({' '.join(names)})"
            )
        row = []
        for name, text in zip(names, fields, strict=True):
            try:
                number_value = float(text)
            except ValueError:
                raise BRDFTableError(
                    f"{path}: line {number}, column {name}: {text!r} is not a number"
                ) from None
            if not math.isfinite(number_value) or (name == "brdf" and number_value < 0):
                raise BRDFTableError(f"{path}: line {number}, column {name}: invalid value {text}")
            row.append(number_value)
        rows.append(row)
    if not rows:
        raise BRDFTableError(f"{path}: no data lines")
    data = np.asarray(rows)
    column = {name: data[:, index] for index, name in enumerate(names)}
    return BRDFTable(
        zenith_in=column[roles["in"][0]],
        azimuth_in=column[roles["in"][1]],
        zenith_out=column[roles["out"][0]],
        azimuth_out=column[roles["out"][1]],
        value=column["brdf"],
        source=path.name,
    )
