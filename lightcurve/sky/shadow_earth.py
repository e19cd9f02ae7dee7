"""The Earth's shadow: umbra, penumbra and the visible fraction of the Sun's disc.

Two models (Montenbruck & Gill 2000, "Satellite Orbits", sec. 3.4.2):

``"conical"`` (default)
    The Sun and the Earth are spheres of radii ``R_S`` and ``R_E``. Seen from the object,
    their discs have angular radii ``a = asin(R_S/|s − r|)`` and ``b = asin(R_E/|r|)`` and
    centres ``c = acos(−r·(s − r)/(|r||s − r|))`` apart (``r`` the object's geocentric
    position, ``s`` the Sun's). The object is in the **umbra** when ``c ≤ b − a`` (the Earth
    covers the whole Sun), in the **penumbra** when ``|a − b| < c < a + b``, in an
    **annular** eclipse when ``c < a − b`` (impossible below ~1.4 million km), and sunlit
    otherwise. The sunlit fraction is ``1 − A/(π a²)`` with ``A`` the area of overlap of the
    two discs (planar circles, M&G eq. 3.87):
    ``A = a² acos(x/a) + b² acos((c − x)/b) − c y``, ``x = (c² + a² − b²)/(2c)``,
    ``y = √(a² − x²)``.
``"cylindrical"``
    The Sun at infinity: umbra behind the Earth (``r·ŝ < 0``) within ``R_E`` of the
    shadow axis; no penumbra; the fraction is 0 or 1.

The Earth is a sphere of the WGS84 equatorial radius (6378.137 km), the Sun one of the IAU
2015 nominal radius (695 700 km); atmospheric refraction and the Earth's flattening (which
move LEO shadow crossings by a few seconds) are not modelled.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lightcurve.io.observation_rules import SHADOW_STATES

__all__ = [
    "EARTH_RADIUS_KM",
    "MODELS",
    "SHADOW_STATES",
    "SUN_RADIUS_KM",
    "EarthShadow",
    "ShadowEvent",
    "earth_shadow",
    "shadow_events",
]

EARTH_RADIUS_KM = 6378.137
#: IAU 2015 Resolution B3 nominal solar radius.
SUN_RADIUS_KM = 695_700.0
MODELS = ("conical", "cylindrical")


@dataclass(frozen=True)
class EarthShadow:
    """Shadow state per epoch.

    Attributes
    ----------
    state : (n,) numpy.ndarray of str
        ``"sunlit"``, ``"penumbra"``, ``"umbra"`` or ``"annular"``.
    sunlit_fraction : (n,) numpy.ndarray
        Visible fraction of the Sun's disc, in ``[0, 1]``.
    """

    state: np.ndarray
    sunlit_fraction: np.ndarray

    @property
    def in_umbra(self) -> np.ndarray:
        """Boolean mask of the epochs in the umbra."""
        return self.state == "umbra"


def _disc_geometry(
    position_km: np.ndarray, sun_km: np.ndarray, earth_radius_km: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Angular radii of the Sun (a) and the Earth (b) and their separation (c), radians."""
    r = np.asarray(position_km, dtype=float)
    to_sun = np.asarray(sun_km, dtype=float) - r
    r_norm = np.linalg.norm(r, axis=-1)
    d_norm = np.linalg.norm(to_sun, axis=-1)
    a = np.arcsin(np.clip(SUN_RADIUS_KM / d_norm, -1.0, 1.0))
    b = np.arcsin(np.clip(earth_radius_km / r_norm, -1.0, 1.0))
    cos_c = -np.sum(r * to_sun, axis=-1) / (r_norm * d_norm)
    # Separation by atan2 of the cross and dot products: accurate at small angles.
    sin_c = np.linalg.norm(np.cross(-r, to_sun), axis=-1) / (r_norm * d_norm)
    return a, b, np.arctan2(sin_c, cos_c)


def _boundary_functions(
    position_km: np.ndarray, sun_km: np.ndarray, model: str, earth_radius_km: float
) -> dict[str, np.ndarray]:
    """Continuous functions that are negative inside each shadow region.

    ``conical``: ``umbra = c − (b − a)``, ``penumbra = c − (a + b)`` (penumbra or umbra);
    ``cylindrical``: ``umbra`` = distance from the shadow axis minus ``R_E`` behind the
    Earth, ``|r| − R_E`` in front (continuous at the terminator plane).
    """
    if model == "conical":
        a, b, c = _disc_geometry(position_km, sun_km, earth_radius_km)
        return {"umbra": c - (b - a), "penumbra": c - (a + b)}
    r = np.asarray(position_km, dtype=float)
    s = np.asarray(sun_km, dtype=float)
    s_hat = s / np.linalg.norm(s, axis=-1, keepdims=True)
    along = np.sum(r * s_hat, axis=-1)
    perpendicular = np.linalg.norm(r - along[..., None] * s_hat, axis=-1)
    behind = along < 0
    return {"umbra": np.where(behind, perpendicular, np.linalg.norm(r, axis=-1)) - earth_radius_km}


def earth_shadow(
    position_km: np.ndarray,
    sun_km: np.ndarray,
    model: str = "conical",
    earth_radius_km: float = EARTH_RADIUS_KM,
) -> EarthShadow:
    """Shadow state and sunlit fraction of objects about the Earth.

    Parameters
    ----------
    position_km : (n, 3) array
        Geocentric positions of the object (km, any inertial frame).
    sun_km : (n, 3) array
        Geocentric positions of the Sun, same frame (km).
    model : {"conical", "cylindrical"}
    earth_radius_km : float

    Returns
    -------
    EarthShadow
    """
    if model not in MODELS:
        raise ValueError(f"shadow model must be one of {', '.join(MODELS)}, got {model!r}")
    n = np.shape(position_km)[0]
    state = np.full(n, "sunlit", dtype=object)
    fraction = np.ones(n)
    if model == "cylindrical":
        umbra = _boundary_functions(position_km, sun_km, model, earth_radius_km)["umbra"] < 0
        state[umbra] = "umbra"
        fraction[umbra] = 0.0
        return EarthShadow(state.astype(str), fraction)
    a, b, c = _disc_geometry(position_km, sun_km, earth_radius_km)
    umbra = c <= b - a
    annular = c < a - b
    penumbra = ~umbra & ~annular & (c < a + b)
    state[umbra], state[annular], state[penumbra] = "umbra", "annular", "penumbra"
    fraction[umbra] = 0.0
    fraction[annular] = 1.0 - (b[annular] / a[annular]) ** 2
    ap, bp, cp = a[penumbra], b[penumbra], c[penumbra]
    x = (cp**2 + ap**2 - bp**2) / (2.0 * cp)
    y = np.sqrt(np.clip(ap**2 - x**2, 0.0, None))
    overlap = (
        ap**2 * np.arccos(np.clip(x / ap, -1.0, 1.0))
        + bp**2 * np.arccos(np.clip((cp - x) / bp, -1.0, 1.0))
        - cp * y
    )
    fraction[penumbra] = np.clip(1.0 - overlap / (np.pi * ap**2), 0.0, 1.0)
    return EarthShadow(state.astype(str), fraction)


@dataclass(frozen=True)
class ShadowEvent:
    """A shadow-boundary crossing.

    Attributes
    ----------
    mjd : float
        Time of the crossing (the time scale of the input epochs).
    boundary : str
        ``"umbra"`` or ``"penumbra"`` (the outer edge of the penumbra).
    entering : bool
        True when the object enters the region.
    """

    mjd: float
    boundary: str
    entering: bool

    @property
    def kind(self) -> str:
        """``"umbra entry"``, ``"penumbra exit"``, …"""
        return f"{self.boundary} {'entry' if self.entering else 'exit'}"


def shadow_events(
    mjd: np.ndarray,
    position_km: np.ndarray,
    sun_km: np.ndarray,
    model: str = "conical",
    earth_radius_km: float = EARTH_RADIUS_KM,
) -> list[ShadowEvent]:
    """Shadow entries and exits between samples of a trajectory.

    Each boundary function (negative inside, see :func:`earth_shadow`) is interpolated
    linearly between the two samples around a sign change. The functions are smooth, so the
    timing error falls with the square of the sampling step: for low orbits sampled every
    10 s it is ~0.01 s, far below the few seconds by which the Earth's flattening and
    atmosphere move real crossings.

    Parameters
    ----------
    mjd : (n,) array
        Increasing sample epochs.
    position_km, sun_km : (n, 3) array
        Geocentric object and Sun positions (km, one inertial frame).
    model : {"conical", "cylindrical"}
    earth_radius_km : float

    Returns
    -------
    list of ShadowEvent
        Sorted by time.
    """
    if model not in MODELS:
        raise ValueError(f"shadow model must be one of {', '.join(MODELS)}, got {model!r}")
    mjd = np.asarray(mjd, dtype=float)
    events = []
    for boundary, g in _boundary_functions(position_km, sun_km, model, earth_radius_km).items():
        crossing = np.flatnonzero(np.signbit(g[:-1]) != np.signbit(g[1:]))
        for k in crossing:
            t = mjd[k] + (mjd[k + 1] - mjd[k]) * g[k] / (g[k] - g[k + 1])
            events.append(ShadowEvent(float(t), boundary, bool(g[k + 1] < 0)))
    return sorted(events, key=lambda event: event.mjd)
