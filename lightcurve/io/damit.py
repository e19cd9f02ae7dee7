"""DAMIT light-curve text files (Kaasalainen & Ďurech), parsed into arrays without pandas.

The format: first line the number of light curves; each starts with ``N flag`` (flag 0 =
relative, 1 = calibrated) followed by N lines ``JD brightness sx sy sz ex ey ez``
(brightness in intensity units; asteroid → Sun and asteroid → Earth vectors in AU, ecliptic
J2000). :func:`lightcurve.io.read_damit` makes an observation table of it (validated by
:func:`lightcurve.io.observations.validate_table`); the convex inversion reads it directly
(:meth:`lightcurve.analysis.convex.Photometry.read`), which spares a command the import of pandas.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lightcurve.io.observation_rules import (
    OBSERVER_RANGE_KM,
    SUN_RANGE_KM,
    ObservationError,
    read_text,
)

__all__ = ["AU_KM", "DamitLightcurves", "read_lightcurves"]

AU_KM = 149_597_870.7
#: Metres per kilometre: the accessors below return SI values like
#: :class:`lightcurve.io.observations.Observations`.
_KM = 1000.0


@dataclass(frozen=True)
class DamitLightcurves:
    """The points of a DAMIT file, in file order (each light curve sorted by time).

    Offers the accessors of :class:`lightcurve.io.observations.Observations` that the convex
    inversion uses, with the same values.

    Attributes
    ----------
    mjd : (N,) float
        JD − 2400000.5 (light-time corrected, as in the file).
    magnitudes : (N,) float
        ``−2.5 log10(brightness)``.
    magnitude_errors : (N,) float
        The constant ``mag_err`` given to the reader.
    sun_km, observer_km : (N, 3) float
        Object → Sun and object → Earth vectors, ecliptic J2000, km.
    lightcurve_ids : (N,) int
        Light curve of each point, 0 … n − 1 in file order.
    relative : (N,) bool
        Whether each point's light curve is relative (flag 0).
    meta : dict of str
        ``object``, ``frame``, ``target``, ``time``, ``source_format`` (and ``notes`` on
        curves sorted or with repeated epochs).
    source : str
        The file.
    """

    mjd: np.ndarray
    magnitudes: np.ndarray
    magnitude_errors: np.ndarray
    sun_km: np.ndarray
    observer_km: np.ndarray
    lightcurve_ids: np.ndarray
    relative: np.ndarray
    meta: dict
    source: str

    @property
    def sun_vectors(self) -> np.ndarray:
        """Object → Sun vectors (m), shape (N, 3)."""
        return self.sun_km * _KM

    @property
    def observer_vectors(self) -> np.ndarray:
        """Object → Earth vectors (m), shape (N, 3)."""
        return self.observer_km * _KM

    def passes_table_checks(self) -> bool:
        """Whether :func:`lightcurve.io.observations.validate_table` accepts these points as
        they are: every value finite and the vectors' lengths within the plausible ranges
        of :mod:`lightcurve.io.observation_rules` (for an asteroid)."""
        values = (self.mjd, self.magnitudes, self.sun_km, self.observer_km)
        if not all(np.isfinite(v).all() for v in values):
            return False
        for vectors, (low, high) in (
            (self.sun_km, SUN_RANGE_KM),
            (self.observer_km, OBSERVER_RANGE_KM["asteroid"]),
        ):
            ranges = np.linalg.norm(vectors, axis=1)
            if np.any(ranges < low) or np.any(ranges > high):
                return False
        return True


def read_lightcurves(path: str | Path, mag_err: float = 0.01) -> DamitLightcurves:
    """Parse a DAMIT light-curve file (see the module docstring).

    Magnitudes are ``−2.5 log10(brightness)``; DAMIT files carry no uncertainties, so every
    point gets ``mag_err``. Rows within each light curve are sorted by time (a few real
    light curves are not); this is recorded in ``meta['notes']``.

    Raises
    ------
    ObservationError
        On a malformed file (naming the line) or a brightness ≤ 0 (naming the row).
    ValueError
        If ``mag_err`` is not positive.
    """
    if mag_err <= 0:
        raise ValueError(f"mag_err must be > 0, got {mag_err}")
    path = Path(path)
    source = str(path)
    lines = read_text(path).splitlines()

    def fields(index: int, count: int) -> list[str]:
        if index >= len(lines):
            raise ObservationError(f"file ends at line {len(lines)} (truncated?)", source)
        parts = lines[index].split()
        if len(parts) != count:
            raise ObservationError(
                f"line {index + 1}: expected {count} fields, found {len(parts)} (truncated?)",
                source,
            )
        return parts

    try:
        n_curves = int(fields(0, 1)[0])
    except ValueError:
        raise ObservationError("line 1: expected the number of light curves", source) from None
    rows, notes, cursor = [], [], 1
    for curve in range(n_curves):
        try:
            n_points, flag = (int(v) for v in fields(cursor, 2))
        except ValueError:
            raise ObservationError(f"line {cursor + 1}: expected 'N flag'", source) from None
        cursor += 1
        block = []
        for _ in range(n_points):
            parts = fields(cursor, 8)
            try:
                block.append([float(v) for v in parts])
            except ValueError:
                raise ObservationError(f"line {cursor + 1}: non-numeric field", source) from None
            cursor += 1
        block = np.array(block).reshape(-1, 8)
        if np.any(np.diff(block[:, 0]) < 0):
            notes.append(f"light curve {curve} was not in time order; sorted")
            block = block[np.argsort(block[:, 0], kind="stable")]
        if np.any(np.diff(block[:, 0]) == 0):
            notes.append(f"light curve {curve} has repeated epochs; all points kept")
        rows.append(np.column_stack([block, np.full(len(block), curve), np.full(len(block), flag)]))
    if any(line.strip() for line in lines[cursor:]):
        raise ObservationError(f"unexpected content after line {cursor}", source)
    data = np.concatenate(rows)
    brightness = data[:, 1]
    if np.any(brightness <= 0):
        raise ObservationError(
            "brightness must be positive",
            source,
            int(np.flatnonzero(brightness <= 0)[0]) + 1,
            "brightness",
        )
    meta = {
        "object": path.stem,
        "frame": "ecliptic J2000",
        "target": "asteroid",
        "time": "JD, light-time corrected (DAMIT)",
        "source_format": "damit",
    }
    if notes:
        meta["notes"] = "; ".join(notes)
    if any("repeated" in note for note in notes):
        meta["duplicate_epochs"] = "allowed"
    return DamitLightcurves(
        mjd=data[:, 0] - 2400000.5,
        magnitudes=-2.5 * np.log10(brightness),
        magnitude_errors=np.full(len(data), float(mag_err)),
        sun_km=data[:, 2:5] * AU_KM,
        observer_km=data[:, 5:8] * AU_KM,
        lightcurve_ids=data[:, 8].astype(int),
        relative=data[:, 9] == 0,
        meta=meta,
        source=source,
    )
