"""Two-line element sets (TLEs): reading, checking, choosing and propagating with SGP4.

A TLE file holds records of two 69-column lines (the NORAD format, Hoots & Roehrich 1980,
"Spacetrack Report No. 3"; Vallado et al. 2006, "Revisiting Spacetrack Report #3", AIAA
2006-6753), each optionally preceded by a name line (three-line format, with or without the
``0 `` prefix); blank lines and ``#`` comment lines are skipped. A file may hold several
objects and, per object, a history of element sets at different epochs.

Every record is checked before SGP4 sees it, and a problem is reported with the file and the
line: line length, line numbers ``1``/``2``, the fixed blank columns, the checksum (digits
plus one per minus sign, modulo 10), each numeric field (epoch, mean-motion derivatives,
drag term, angles, eccentricity, mean motion) and the satellite number of both lines.
Propagation uses the ``sgp4`` package (Vallado's reference implementation, WGS-72 constants)
and gives positions in the TEME frame (see :mod:`lightcurve.sky.frames`); the TLE epoch is UTC.
For each requested epoch the object's element set nearest in time is used; epochs farther
than a stated number of days from it raise a :class:`TLEAgeWarning` (SGP4's error grows by
roughly 1–3 km per day from the epoch for low orbits).
"""

from __future__ import annotations

import re
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "DEFAULT_MAX_AGE_DAYS",
    "TLE",
    "SGP4Error",
    "TEMEState",
    "TLEAgeWarning",
    "TLEError",
    "decode_norad",
    "parse_tles",
    "propagate_teme",
    "read_tles",
    "select_object",
]

#: Default age (days between an epoch and its TLE's epoch) above which a warning is issued.
DEFAULT_MAX_AGE_DAYS = 3.0
LINE_LENGTH = 69
_ALPHA5 = "ABCDEFGHJKLMNPQRSTUVWXYZ"  # letters of Alpha-5 catalogue numbers (no I, no O)


class TLEError(ValueError):
    """A malformed TLE record; the message names the file and the line."""

    def __init__(self, message: str, source: str | None = None, line: int | None = None):
        self.source, self.line = source, line
        where = [str(source)] if source else []
        if line is not None:
            where.append(f"line {line}")
        super().__init__(f"{', '.join(where)}: {message}" if where else message)


class SGP4Error(ValueError):
    """SGP4 could not propagate an element set; the message has the SGP4 error code.

    Attributes
    ----------
    code : int
        SGP4 error code (1 eccentricity out of range, 2 negative mean motion, 3 perturbed
        eccentricity out of range, 4 negative semi-latus rectum, 6 decayed).
    """

    def __init__(self, message: str, code: int):
        self.code = code
        super().__init__(message)


class TLEAgeWarning(UserWarning):
    """Epochs far from the epoch of the TLE used for them."""


def checksum(line: str) -> int:
    """TLE checksum of the first 68 columns: digits summed, ``-`` counts 1, modulo 10."""
    return sum(int(c) if c.isdigit() else c == "-" for c in line[:68]) % 10


def decode_norad(text: str) -> int:
    """Catalogue number from 5 columns, digits or Alpha-5 (``A0001`` = 100001).

    Raises
    ------
    ValueError
        If the text is neither.
    """
    text = text.strip()
    if re.fullmatch(r"\d{1,9}", text):
        return int(text)
    if re.fullmatch(r"[A-Z]\d{4}", text) and text[0] in _ALPHA5:
        return (10 + _ALPHA5.index(text[0])) * 10_000 + int(text[1:])
    raise ValueError(f"{text!r} is not a catalogue number (digits or Alpha-5)")


@dataclass(frozen=True)
class TLE:
    """One element set.

    Attributes
    ----------
    line1, line2 : str
        The two 69-column lines.
    name : str or None
        The name line of a three-line record.
    source : str or None
        File the record was read from.
    line_number : int
        Line of ``line1`` in the file (1-based).
    norad : int
        Catalogue number.
    epoch_mjd : float
        Epoch (UTC MJD).
    """

    line1: str
    line2: str
    name: str | None = None
    source: str | None = None
    line_number: int = 1
    norad: int = field(init=False)
    epoch_mjd: float = field(init=False)

    def __post_init__(self) -> None:
        satrec = self.satrec
        object.__setattr__(self, "norad", decode_norad(self.line1[2:7]))
        epoch = (satrec.jdsatepoch - 2_400_000.5) + satrec.jdsatepochF
        object.__setattr__(self, "epoch_mjd", float(epoch))

    @cached_property
    def satrec(self) -> Any:
        """The ``sgp4.api.Satrec`` of this element set (WGS-72)."""
        from sgp4.api import WGS72, Satrec

        try:
            return Satrec.twoline2rv(self.line1, self.line2, WGS72)
        except (ValueError, RuntimeError) as exc:
            raise TLEError(
                f"sgp4 cannot read this record ({exc})", self.source, self.line_number
            ) from None

    @property
    def label(self) -> str:
        """``NAME (norad)`` or the number alone."""
        return f"{self.name} ({self.norad})" if self.name else str(self.norad)

    @property
    def where(self) -> str:
        """``file, lines n–n+1`` for messages."""
        lines = f"lines {self.line_number}-{self.line_number + 1}"
        return f"{self.source}, {lines}" if self.source else lines

    @property
    def mean_motion_rev_per_day(self) -> float:
        """Mean motion (revolutions per day) as written in line 2."""
        return float(self.line2[52:63])


# --------------------------------------------------------------------------- parsing


def _field(
    line: str,
    columns: tuple[int, int],
    what: str,
    source: str | None,
    number: int,
    pattern: str,
) -> str:
    text = line[columns[0] - 1 : columns[1]]
    if not re.fullmatch(pattern, text):
        raise TLEError(
            f"{what} {text!r} (columns {columns[0]}-{columns[1]}) is malformed", source, number
        )
    return text


_DECIMAL = r" *[-+]?\d*\.\d+"  # right-aligned decimal number
_EXPONENT = r" *[-+ ]?\d{5}[-+]\d"  # assumed-decimal mantissa and exponent: ' 12345-3'
_ANGLE = r" *[+]?\d{1,3}\.\d+"


def _check_line1(line: str, source: str | None, number: int) -> None:
    _field(line, (3, 7), "satellite number", source, number, r"\d{5}|[A-HJ-NP-Z]\d{4}")
    _field(line, (8, 8), "classification", source, number, r"[UCS ]")
    _field(line, (19, 20), "epoch year", source, number, r"\d\d")
    day = float(_field(line, (21, 32), "epoch day", source, number, r" *\d{1,3}\.\d+"))
    if not 1.0 <= day < 367.0:
        raise TLEError(f"epoch day {day} (columns 21-32) is not in [1, 367)", source, number)
    _field(line, (34, 43), "first derivative of the mean motion", source, number, _DECIMAL)
    _field(line, (45, 52), "second derivative of the mean motion", source, number, _EXPONENT)
    _field(line, (54, 61), "drag term (B*)", source, number, _EXPONENT)
    _field(line, (63, 63), "ephemeris type", source, number, r"[\d ]")
    _field(line, (65, 68), "element set number", source, number, r" *\d*")
    for column in (9, 18, 33, 44, 53, 62, 64):
        _blank(line, column, source, number)


def _check_line2(line: str, source: str | None, number: int) -> None:
    _field(line, (3, 7), "satellite number", source, number, r"\d{5}|[A-HJ-NP-Z]\d{4}")
    bounds = {
        "inclination": ((9, 16), 0.0, 180.0),
        "right ascension of the ascending node": ((18, 25), 0.0, 360.0),
        "argument of perigee": ((35, 42), 0.0, 360.0),
        "mean anomaly": ((44, 51), 0.0, 360.0),
    }
    for what, (columns, low, high) in bounds.items():
        value = float(_field(line, columns, what, source, number, _ANGLE))
        if not low <= value <= high:
            raise TLEError(
                f"{what} {value} deg (columns {columns[0]}-{columns[1]}) is outside "
                f"[{low:g}, {high:g}]",
                source,
                number,
            )
    _field(line, (27, 33), "eccentricity", source, number, r"\d{7}")
    motion = float(_field(line, (53, 63), "mean motion", source, number, r" *[+]?\d*\.\d+"))
    if not motion > 0:
        raise TLEError(f"mean motion {motion} rev/day (columns 53-63) must be > 0", source, number)
    _field(line, (64, 68), "revolution number", source, number, r" *\d*")
    for column in (8, 17, 26, 34, 43, 52):
        _blank(line, column, source, number)


def _blank(line: str, column: int, source: str | None, number: int) -> None:
    if line[column - 1] != " ":
        raise TLEError(
            f"column {column} must be blank, found {line[column - 1]!r} (fields shifted?)",
            source,
            number,
        )


def _check_line(
    line: str, expected: str, source: str | None, number: int, verify_checksum: bool
) -> None:
    if not line.isascii():
        raise TLEError("non-ASCII characters in a TLE line", source, number)
    if len(line) != LINE_LENGTH:
        raise TLEError(
            f"line {expected} of a TLE has {LINE_LENGTH} characters, this one has {len(line)}",
            source,
            number,
        )
    if line[0] != expected or line[1] != " ":
        raise TLEError(
            f"expected TLE line {expected} ('{expected} …'), got {line[:20]!r}", source, number
        )
    if verify_checksum:
        if not line[68].isdigit():
            raise TLEError(f"checksum column 69 holds {line[68]!r}, not a digit", source, number)
        if checksum(line) != int(line[68]):
            raise TLEError(
                f"checksum mismatch: the line's digits give {checksum(line)}, column 69 says "
                f"{line[68]} (corrupted line?)",
                source,
                number,
            )
    (_check_line1 if expected == "1" else _check_line2)(line, source, number)


def parse_tles(text: str, source: str | None = None, verify_checksum: bool = True) -> list[TLE]:
    """Parse two- and three-line element sets.

    Parameters
    ----------
    text : str
        File content.
    source : str, optional
        File name for messages.
    verify_checksum : bool
        Check column 69 of every line (some old sets have none).

    Returns
    -------
    list of TLE
        In file order.

    Raises
    ------
    TLEError
        Naming the line of the first malformed record.
    """
    lines = text.splitlines()
    records: list[TLE] = []
    name: str | None = None
    index = 0
    while index < len(lines):
        raw = lines[index].rstrip()
        number = index + 1
        index += 1
        if not raw.strip() or raw.lstrip().startswith("#"):
            continue
        if raw.startswith("2 ") or raw == "2":
            raise TLEError("TLE line 2 without a line 1 before it", source, number)
        if not raw.startswith("1 "):
            if name is not None:
                raise TLEError(
                    f"two name lines in a row ({name!r}, then {raw.strip()!r}): a TLE line 1 "
                    "was expected",
                    source,
                    number,
                )
            name = raw[2:].strip() if raw.startswith("0 ") else raw.strip()
            continue
        _check_line(raw, "1", source, number, verify_checksum)
        if index >= len(lines) or not lines[index].strip():
            raise TLEError("TLE line 1 is not followed by its line 2", source, number)
        second = lines[index].rstrip()
        _check_line(second, "2", source, number + 1, verify_checksum)
        index += 1
        if second[2:7] != raw[2:7]:
            raise TLEError(
                f"satellite number {second[2:7]!r} differs from line {number}'s {raw[2:7]!r}",
                source,
                number + 1,
            )
        records.append(TLE(raw, second, name, source, number))
        name = None
    if name is not None:
        raise TLEError(f"name line {name!r} is not followed by a TLE", source, len(lines))
    if not records:
        raise TLEError("no TLE records found", source)
    return records


def read_tles(path: str | Path, verify_checksum: bool = True) -> list[TLE]:
    """Read a TLE file (see :func:`parse_tles`).

    Raises
    ------
    FileNotFoundError
        If there is no such file.
    TLEError
        Naming the line of a malformed record.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such TLE file")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise TLEError(f"not a UTF-8 text file ({exc.reason})", str(path)) from None
    return parse_tles(text, str(path), verify_checksum)


def select_object(tles: Sequence[TLE], norad: int | str | None = None) -> list[TLE]:
    """The element sets of one object, sorted by epoch.

    Parameters
    ----------
    tles : sequence of TLE
    norad : int or str, optional
        Catalogue number (digits or Alpha-5); required when ``tles`` hold several objects.

    Returns
    -------
    list of TLE
        Sorted by epoch; of several sets with the same epoch the last one in the file wins.

    Raises
    ------
    ValueError
        If the object is missing or ambiguous.
    """
    objects: dict[int, str] = {}
    for tle in tles:
        objects.setdefault(tle.norad, tle.label)
    source = tles[0].source if tles else None
    prefix = f"{source}: " if source else ""
    if norad is None:
        if len(objects) != 1:
            listing = ", ".join(list(objects.values())[:10]) + (", …" if len(objects) > 10 else "")
            raise ValueError(
                f"{prefix}{len(objects)} objects ({listing}): choose one by its NORAD "
                "number (--norad)"
            )
        norad = next(iter(objects))
    number = norad if isinstance(norad, int) else decode_norad(str(norad))
    if number not in objects:
        raise ValueError(
            f"{prefix}no element set for NORAD {number}; the file has "
            + ", ".join(list(objects.values())[:10])
            + (", …" if len(objects) > 10 else "")
        )
    by_epoch = {tle.epoch_mjd: tle for tle in tles if tle.norad == number}
    return [by_epoch[epoch] for epoch in sorted(by_epoch)]


# --------------------------------------------------------------------------- propagation


@dataclass(frozen=True)
class TEMEState:
    """SGP4 states in the TEME frame.

    Attributes
    ----------
    position_km, velocity_km_s : (n, 3) numpy.ndarray
    tle_index : (n,) numpy.ndarray
        Index (into the TLE list) of the element set used per epoch.
    age_days : (n,) numpy.ndarray
        Epoch minus the TLE's epoch (days).
    """

    position_km: np.ndarray
    velocity_km_s: np.ndarray
    tle_index: np.ndarray
    age_days: np.ndarray


def nearest_tle(epochs_mjd: np.ndarray, mjd: np.ndarray) -> np.ndarray:
    """Index of the epoch in the sorted ``epochs_mjd`` nearest to each ``mjd``."""
    upper = np.clip(np.searchsorted(epochs_mjd, mjd), 1, max(len(epochs_mjd) - 1, 1))
    lower = upper - 1
    if len(epochs_mjd) == 1:
        return np.zeros(len(mjd), dtype=int)
    later = np.abs(epochs_mjd[upper] - mjd) < np.abs(mjd - epochs_mjd[lower])
    return np.where(later, upper, lower)


def propagate_teme(
    tles: Sequence[TLE], mjd: np.ndarray, max_age_days: float | None = DEFAULT_MAX_AGE_DAYS
) -> TEMEState:
    """SGP4 positions and velocities (TEME) of one object at UTC epochs.

    Parameters
    ----------
    tles : sequence of TLE
        Element sets of ONE object (see :func:`select_object`), sorted by epoch.
    mjd : (n,) array
        UTC Modified Julian Dates.
    max_age_days : float or None
        Warn (:class:`TLEAgeWarning`) when an epoch is farther than this from its TLE's epoch.

    Returns
    -------
    TEMEState

    Raises
    ------
    SGP4Error
        With the SGP4 error code and its meaning, the TLE's file and lines, and the first
        failing epoch.
    """
    from sgp4.api import SGP4_ERRORS

    if not tles:
        raise ValueError("no element sets to propagate")
    if len({tle.norad for tle in tles}) != 1:
        raise ValueError("propagate_teme takes the element sets of one object")
    mjd = np.atleast_1d(np.asarray(mjd, dtype=float))
    epochs = np.array([tle.epoch_mjd for tle in tles])
    if np.any(np.diff(epochs) < 0):
        raise ValueError("element sets must be sorted by epoch (use select_object)")
    index = nearest_tle(epochs, mjd)
    position = np.empty((len(mjd), 3))
    velocity = np.empty((len(mjd), 3))
    whole = np.floor(mjd)
    jd, fraction = whole + 2_400_000.5, mjd - whole
    for k in np.unique(index):
        rows = np.flatnonzero(index == k)
        error, r, v = tles[k].satrec.sgp4_array(jd[rows], fraction[rows])
        failed = np.flatnonzero(error)
        if failed.size:
            code = int(error[failed[0]])
            first = float(mjd[rows[failed[0]]])
            raise SGP4Error(
                f"{tles[k].where} ({tles[k].label}): SGP4 error {code} "
                f"({SGP4_ERRORS.get(code, 'unknown error')}) at MJD {first:.6f}, "
                f"{(first - epochs[k]):+.3f} days from the TLE epoch "
                f"({failed.size} of {rows.size} epochs failed)",
                code,
            )
        position[rows], velocity[rows] = r, v
    age = mjd - epochs[index]
    if max_age_days is not None and np.any(np.abs(age) > max_age_days):
        stale = np.abs(age) > max_age_days
        warnings.warn(
            f"{int(stale.sum())} of {len(mjd)} epochs are more than {max_age_days:g} days "
            f"from the epoch of their TLE (up to {np.abs(age).max():.1f} days): SGP4 errors "
            "grow by roughly 1-3 km per day for low orbits",
            TLEAgeWarning,
            stacklevel=2,
        )
    return TEMEState(position, velocity, index, age)
