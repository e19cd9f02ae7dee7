"""GPS constellation from almanac elements: YUMA parsing, satellite positions and velocities.

The almanac is a reduced broadcast ephemeris: per satellite the Keplerian elements at the time
of applicability ``toa`` and the node's drift rate (IS-GPS-200, sec. 20.3.3.5.1.2 and
Table 20-IV, "Elements of coordinate systems"). The position of satellite ``s`` at GPS time
``t`` (seconds of the almanac week) is

``tk = t − toa``,  ``M = M0 + n tk`` with ``n = √(μ/A³)``,  ``M = E − e sin E`` (Kepler),
``ν = atan2(√(1 − e²) sin E, cos E − e)``,  ``u = ν + ω``,  ``r = A (1 − e cos E)``,
``Ω = Ω0 + Ω̇ tk``  (node right ascension in the inertial frame defined below),
``x = R3(−Ω) R1(−i) [r cos u, r sin u, 0]``.

**Frame.** Everything in :mod:`filters.gnss` is expressed in the *week-start inertial frame*:
the Earth-fixed (WGS-84) axes frozen at the start of the almanac's GPS week. An Earth-fixed
vector at time ``t`` is ``x_ECEF = R3(Ω̇e t) x_I``; IS-GPS-200's Earth-fixed node longitude
``Ω0 + (Ω̇ − Ω̇e) tk − Ω̇e toa`` is the inertial ``Ω0 + Ω̇ tk`` minus the Earth's rotation
angle ``Ω̇e t`` (see :meth:`Constellation.earth_fixed_positions`). Signal propagation is then a
straight line at ``c`` with no Sagnac correction, and the satellite clock offsets are the
almanac's ``af0 + af1 tk`` (s).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = [
    "EARTH_ROTATION_RATE",
    "GPS_MU",
    "SPEED_OF_LIGHT",
    "Almanac",
    "AlmanacError",
    "Constellation",
    "parse_yuma",
]

GPS_MU = 3.986005e14
"""Earth's gravitational parameter used by the GPS user algorithm (m³/s², IS-GPS-200)."""

EARTH_ROTATION_RATE = 7.2921151467e-5
"""WGS-84 Earth rotation rate Ω̇e (rad/s, IS-GPS-200)."""

SPEED_OF_LIGHT = 299_792_458.0
"""Speed of light in vacuum (m/s)."""

_YUMA_FIELDS = {
    "id": "prn",
    "health": "health",
    "eccentricity": "eccentricity",
    "time of applicability(s)": "toa",
    "orbital inclination(rad)": "inclination",
    "rate of right ascen(r/s)": "node_rate",
    "sqrt(a) (m 1/2)": "sqrt_a",
    "right ascen at week(rad)": "node",
    "argument of perigee(rad)": "perigee",
    "mean anom(rad)": "mean_anomaly",
    "af0(s)": "af0",
    "af1(s/s)": "af1",
    "week": "week",
}


class AlmanacError(ValueError):
    """An almanac that cannot be used; the message names the record and field."""


@dataclass(frozen=True)
class Almanac:
    """Almanac elements of a constellation, one array entry per satellite (SI units).

    Attributes
    ----------
    prn : (n,) int numpy.ndarray
        Satellite identifiers (PRN numbers).
    health : (n,) int numpy.ndarray
        Health words (0 = usable).
    eccentricity, sqrt_a : (n,) numpy.ndarray
        Eccentricity and square root of the semi-major axis (m^½).
    inclination, node, perigee, mean_anomaly : (n,) numpy.ndarray
        Inclination, right ascension of the node at the week start (week-start inertial
        frame), argument of perigee and mean anomaly at ``toa`` (rad).
    node_rate : (n,) numpy.ndarray
        Rate of right ascension Ω̇ (rad/s).
    toa : (n,) numpy.ndarray
        Time of applicability (s of the almanac week).
    af0, af1 : (n,) numpy.ndarray
        Satellite clock offset (s) and drift (s/s) at ``toa``.
    week : int
        GPS week of the almanac (as written in the file, modulo 1024 for YUMA files).
    """

    prn: np.ndarray
    health: np.ndarray
    eccentricity: np.ndarray
    toa: np.ndarray
    inclination: np.ndarray
    node_rate: np.ndarray
    sqrt_a: np.ndarray
    node: np.ndarray
    perigee: np.ndarray
    mean_anomaly: np.ndarray
    af0: np.ndarray
    af1: np.ndarray
    week: int

    def __post_init__(self) -> None:
        n = len(self.prn)
        if n == 0:
            raise AlmanacError("almanac has no satellites")
        if len(np.unique(self.prn)) != n:
            raise AlmanacError(f"almanac repeats PRNs: {sorted(self.prn.tolist())}")
        bad = (self.eccentricity < 0) | (self.eccentricity >= 1) | (self.sqrt_a <= 0)
        if np.any(bad):
            raise AlmanacError(f"PRN {int(self.prn[np.argmax(bad)])}: not an elliptic orbit")

    @property
    def size(self) -> int:
        """Number of satellites."""
        return len(self.prn)

    def healthy(self) -> Almanac:
        """The almanac restricted to satellites whose health word is 0."""
        keep = self.health == 0
        fields = {k: getattr(self, k)[keep] for k in _ARRAY_FIELDS}
        return Almanac(**fields, week=self.week)


_ARRAY_FIELDS = (
    "prn",
    "health",
    "eccentricity",
    "toa",
    "inclination",
    "node_rate",
    "sqrt_a",
    "node",
    "perigee",
    "mean_anomaly",
    "af0",
    "af1",
)


def parse_yuma(text: str, source: str = "almanac") -> Almanac:
    """Parse a YUMA almanac (the format of the U.S. Coast Guard Navigation Center).

    Each record starts with a ``******** Week W almanac for PRN-NN ********`` line followed by
    ``name: value`` lines (ID, Health, Eccentricity, Time of Applicability(s), Orbital
    Inclination(rad), Rate of Right Ascen(r/s), SQRT(A) (m 1/2), Right Ascen at Week(rad),
    Argument of Perigee(rad), Mean Anom(rad), Af0(s), Af1(s/s), week).

    Parameters
    ----------
    text : str
        The file's content.
    source : str
        Name used in error messages (the file name).

    Returns
    -------
    Almanac

    Raises
    ------
    AlmanacError
        Naming the source, record and field of the first problem.
    """
    records: list[dict[str, float]] = []
    current: dict[str, float] | None = None
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line:
            continue
        if line.startswith("*"):
            current = {}
            records.append(current)
            continue
        if current is None or ":" not in line:
            raise AlmanacError(
                f"{source}: line {number}: expected a record header or 'name: value'"
            )
        name, value = line.split(":", 1)
        key = _YUMA_FIELDS.get(re.sub(r"\s+", " ", name.strip().lower()))
        if key is None:
            raise AlmanacError(f"{source}: line {number}: unknown field {name.strip()!r}")
        try:
            current[key] = float(value)
        except ValueError:
            raise AlmanacError(
                f"{source}: line {number}: {name.strip()}: not a number: {value.strip()!r}"
            ) from None
    if not records:
        raise AlmanacError(f"{source}: no almanac records")
    for i, record in enumerate(records, start=1):
        missing = sorted(set(_YUMA_FIELDS.values()) - set(record))
        if missing:
            raise AlmanacError(f"{source}: record {i}: missing field {missing[0]!r}")
    weeks = {int(r["week"]) for r in records}
    if len(weeks) != 1:
        raise AlmanacError(f"{source}: records of several weeks {sorted(weeks)}")
    arrays = {k: np.array([r[k] for r in records]) for k in _ARRAY_FIELDS}
    arrays["prn"] = arrays["prn"].astype(int)
    arrays["health"] = arrays["health"].astype(int)
    try:
        return Almanac(**arrays, week=weeks.pop())
    except AlmanacError as exc:
        raise AlmanacError(f"{source}: {exc}") from None


def _kepler(mean_anomaly: np.ndarray, e: np.ndarray) -> np.ndarray:
    """Eccentric anomaly from Kepler's equation ``M = E − e sin E`` by Newton iterations."""
    big_e = mean_anomaly + e * np.sin(mean_anomaly)
    for _ in range(30):
        step = (big_e - e * np.sin(big_e) - mean_anomaly) / (1.0 - e * np.cos(big_e))
        big_e = big_e - step
        if np.max(np.abs(step)) < 1e-14:
            break
    return big_e


class Constellation:
    """Satellite positions, velocities and clock offsets from an :class:`Almanac`.

    Parameters
    ----------
    almanac : Almanac
        Elements of the satellites (all of them are propagated; use
        :meth:`Almanac.healthy` to drop unusable ones first).

    Examples
    --------
    >>> const = Constellation(almanac)
    >>> r = const.positions([345600.0, 345601.0])          # (2, n_sat, 3) m, inertial
    """

    def __init__(self, almanac: Almanac) -> None:
        self.almanac = almanac
        a = almanac
        self.prn = a.prn
        self.semi_major_axis = a.sqrt_a**2
        self.mean_motion = np.sqrt(GPS_MU / self.semi_major_axis**3)

    @property
    def size(self) -> int:
        """Number of satellites."""
        return self.almanac.size

    def _elements(self, t: Any, index: Any) -> tuple[np.ndarray, ...]:
        a = self.almanac
        idx = slice(None) if index is None else np.asarray(index)
        t = np.asarray(t, dtype=float)
        tk = t - a.toa[idx]
        e = a.eccentricity[idx]
        sma = self.semi_major_axis[idx]
        n = self.mean_motion[idx]
        big_e = _kepler(a.mean_anomaly[idx] + n * tk, e)
        cos_e, sin_e = np.cos(big_e), np.sin(big_e)
        root = np.sqrt(1.0 - e * e)
        u = np.arctan2(root * sin_e, cos_e - e) + a.perigee[idx]
        r = sma * (1.0 - e * cos_e)
        e_dot = n / (1.0 - e * cos_e)
        r_dot = sma * e * sin_e * e_dot
        u_dot = root * e_dot / (1.0 - e * cos_e)
        node = a.node[idx] + a.node_rate[idx] * tk
        return r, u, node, a.inclination[idx], r_dot, u_dot, a.node_rate[idx]

    def positions(self, t: Any, index: Any = None) -> np.ndarray:
        """Satellite positions in the week-start inertial frame.

        Parameters
        ----------
        t : (...) array_like
            GPS times (s of the almanac week); broadcast against the satellites, so pass
            ``t[..., None]`` for a grid of epochs × satellites.
        index : (k,) array_like of int, optional
            Satellites to evaluate (indices into the almanac); all by default.

        Returns
        -------
        (..., 3) numpy.ndarray
            Positions (m).
        """
        r, u, node, inc, *_ = self._elements(t, index)
        return _orbit_to_inertial(r, u, node, inc)

    def velocities(self, t: Any, index: Any = None) -> np.ndarray:
        """Satellite velocities in the week-start inertial frame (m/s); arguments as
        :meth:`positions`."""
        return self.states(t, index)[1]

    def states(self, t: Any, index: Any = None) -> tuple[np.ndarray, np.ndarray]:
        """Positions (m) and velocities (m/s) together; arguments as :meth:`positions`."""
        r, u, node, inc, r_dot, u_dot, node_dot = self._elements(t, index)
        cu, su = np.cos(u), np.sin(u)
        cn, sn = np.cos(node), np.sin(node)
        ci, si = np.cos(inc), np.sin(inc)
        # In-plane position p = r [cos u, sin u] rotated by i about x and by Ω about z.
        px, py = r * cu, r * su
        vx, vy = r_dot * cu - r * u_dot * su, r_dot * su + r * u_dot * cu
        x_dot = vx * cn - vy * ci * sn - node_dot * (px * sn + py * ci * cn)
        y_dot = vx * sn + vy * ci * cn + node_dot * (px * cn - py * ci * sn)
        z_dot = vy * si
        return _orbit_to_inertial(r, u, node, inc), np.stack([x_dot, y_dot, z_dot], axis=-1)

    def clock_offsets(self, t: Any, index: Any = None) -> np.ndarray:
        """Almanac satellite clock offsets ``af0 + af1 (t − toa)`` (s)."""
        a = self.almanac
        idx = slice(None) if index is None else np.asarray(index)
        return a.af0[idx] + a.af1[idx] * (np.asarray(t, dtype=float) - a.toa[idx])

    def earth_fixed_positions(self, t: Any, index: Any = None) -> np.ndarray:
        """Satellite positions in the Earth-fixed frame at ``t`` (m), IS-GPS-200 Table 20-IV."""
        t = np.asarray(t, dtype=float)
        r, u, node, inc, *_ = self._elements(t, index)
        return _orbit_to_inertial(r, u, node - EARTH_ROTATION_RATE * t, inc)


def _orbit_to_inertial(r: np.ndarray, u: np.ndarray, node: np.ndarray, inc: Any) -> np.ndarray:
    cu, su = np.cos(u), np.sin(u)
    cn, sn = np.cos(node), np.sin(node)
    ci, si = np.cos(inc), np.sin(inc)
    return np.stack(
        [r * (cu * cn - su * ci * sn), r * (cu * sn + su * ci * cn), r * su * si], axis=-1
    )
