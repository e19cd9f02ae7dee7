"""Earthshine: sunlight reflected by the Earth onto an Earth-orbiting object.

Seen from an object at geocentric distance ``r``, the Earth fills a cap of directions of
angular radius ``ρ = asin(R/r)`` about the nadir. A point of the Earth's surface with
outward normal ``m`` reflects the Sun's irradiance ``E☉`` with the radiance of a Lambertian
surface of albedo ``A``, ``L = A E☉ max(0, m·ŝ)/π``. The irradiance it brings to a surface
element of normal ``n`` is ``∫_cap L(d) max(0, n·d) dΩ``, and a facet lit from direction
``d`` reflects it through the same BRDF as sunlight. So the object's earthshine is its
sunlit flux summed over the cap's directions with weights ``w_k = L(d_k) ΔΩ_k / E☉``
(Fankhauser, Tyson & Askari 2023 model the same source, with an Earth BRDF from aircraft
data, for Starlink satellites).

The quadrature follows the integrand's kinks: on each ring of the cap (polar angle ``θ`` from the
nadir) the lit arc is ``cos(φ − φ₀) ≥ −a/b`` (``m·ŝ`` is ``a + b cos(φ − φ₀)`` along the
ring), so the azimuth nodes are Gauss–Legendre nodes on the lit arc alone, where the
integrand is smooth; the polar nodes are Gauss–Legendre in ``cos θ``. The terminator's
kinks are then at the ends of the polar pieces, found on a 257-point grid. For a flat
plate facing the nadir, against an independent integral over the visible Earth's surface
(altitudes 300–36 000 km, Sun elevations −60° to 90° seen from the object), the default
3 × 8 × 16 = 384 directions are within 0.15 % and 3 × 4 × 8 = 96 within 1.0 %
(``tests/lightcurve/photometry/test_earthshine.py``). :func:`earthshine_flux` uses the latter
by default: 1 % of the earthshine is at most 0.3 % of the object's flux (a Lambertian Earth of
albedo 0.29 filling a hemisphere), and the cost is 96 renderings per epoch, not 384.

When it applies
---------------
The Earth's irradiance on a surface facing the nadir is at most ``A (R/r)²`` of the Sun's
(the whole visible cap lit, the view factor of a sphere). It reaches 1 % of the Sun's (about
0.01 mag) below the altitude ``R (√(A/0.01) − 1)`` = :data:`EARTHSHINE_ALTITUDE_KM` (27 970 km
for ``A`` = 0.29): there ``earthshine="auto"`` (:func:`earthshine_applies`) adds it; in GEO it
is at most 0.66 % of the Sun's and is left out unless asked for.

References
----------
Fankhauser, F., Tyson, J. A., & Askari, J. (2023). Satellite optical brightness.
*The Astronomical Journal* 166, 59.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from lightcurve.io.observations import OBJECT_POSITION_COLUMNS
from lightcurve.photometry.articulated import ArticulatedRenderer
from lightcurve.sky.geometry import AU_M
from lightcurve.sky.shadow_earth import EARTH_RADIUS_KM

__all__ = [
    "EARTHSHINE_ALTITUDE_KM",
    "EARTHSHINE_MODES",
    "EARTH_ALBEDO",
    "earth_cap_quadrature",
    "earthshine_applies",
    "earthshine_flux",
    "known_positions",
    "sun_and_earth_flux",
]

#: Bond albedo of the Earth (global annual mean, Stephens et al. 2015, *Rev. Geophys.* 53,
#: 141: 0.29), the default of the Lambertian Earth.
EARTH_ALBEDO = 0.29

#: Earth radius (m), the WGS84 equatorial radius used by the Earth-shadow model.
EARTH_RADIUS_M = EARTH_RADIUS_KM * 1e3

#: Altitude (km) below which the Earth's light can reach 1 % of the Sun's on a surface
#: facing the nadir, ``R (√(A / 0.01) − 1)`` with the default albedo: where ``"auto"`` adds it.
EARTHSHINE_ALTITUDE_KM = round(EARTH_RADIUS_KM * (math.sqrt(EARTH_ALBEDO / 0.01) - 1.0), -1)

#: ``earthshine`` choices: add it below :data:`EARTHSHINE_ALTITUDE_KM`, always, never.
EARTHSHINE_MODES = ("auto", "on", "off")


def earthshine_applies(mode: str, position: Any | None, where: str = "earthshine") -> bool:
    """Whether earthshine is added, by ``mode`` and the object's geocentric positions.

    Parameters
    ----------
    mode : {"auto", "on", "off"}
        ``"auto"``: when positions are known and the object is below
        :data:`EARTHSHINE_ALTITUDE_KM` at any epoch (a whole file is rendered alike).
    position : (E, 3) array or None
        Geocentric positions (m); None when the observations carry none (an object not in
        Earth orbit, or a file without the ``obj_*`` columns).
    where : str
        Named in the error of ``"on"`` without positions.

    Raises
    ------
    ValueError
        An unknown mode, or ``"on"`` without positions.
    """
    if mode not in EARTHSHINE_MODES:
        raise ValueError(f"{where} must be one of {', '.join(EARTHSHINE_MODES)}, got {mode!r}")
    if mode == "off":
        return False
    if position is None:
        if mode == "on":
            raise ValueError(
                f"{where} on needs the object's geocentric position: the obj_x obj_y obj_z "
                "columns that `lightcurve geometry` and `lightcurve import` write"
            )
        return False
    if mode == "on":
        return True
    altitude_km = np.linalg.norm(np.asarray(position, float), axis=-1) / 1e3 - EARTH_RADIUS_KM
    return bool(np.any(altitude_km < EARTHSHINE_ALTITUDE_KM))


def earth_cap_quadrature(
    position: Any,
    sun: Any,
    *,
    albedo: float = EARTH_ALBEDO,
    n_polar: int = 8,
    n_azimuth: int = 16,
) -> tuple[np.ndarray, np.ndarray]:
    """Directions and weights of the sunlit Earth seen from an object.

    Parameters
    ----------
    position : (..., 3) array
        Geocentric position of the object (m, any inertial frame), outside the Earth.
    sun : (..., 3) array
        Object → Sun vectors in the same frame (any length; the Sun's direction from the
        Earth's surface is taken as the object's, a 4·10⁻⁵ rad parallax at most).
    albedo : float
        Lambertian albedo of the Earth.
    n_polar, n_azimuth : int
        Gauss–Legendre nodes in ``cos θ`` on each of the cap's three pieces (split where
        the rings start to be lit and where they are lit all round) and in azimuth over
        each ring's lit arc.

    Returns
    -------
    directions : (..., K, 3) numpy.ndarray
        Unit vectors from the object towards the Earth's surface, ``K = 3 n_polar
        n_azimuth``.
    weights : (..., K) numpy.ndarray
        ``L(d_k) ΔΩ_k / E☉``: the irradiance on a surface of normal ``n`` is
        ``E☉ Σ_k w_k max(0, n·d_k)``; zero for nodes of a ring with no lit arc.
    """
    if not 0.0 <= albedo <= 1.0:
        raise ValueError(f"albedo must be in [0, 1], got {albedo}")
    if n_polar < 1 or n_azimuth < 1:
        raise ValueError("n_polar and n_azimuth must be positive")
    position = np.asarray(position, dtype=float)
    sun = np.asarray(sun, dtype=float)
    position, sun = np.broadcast_arrays(position, sun)
    r = np.linalg.norm(position, axis=-1)
    if not np.all(r > EARTH_RADIUS_M):
        raise ValueError("position: every object must be outside the Earth (|position| > R)")
    nadir = -position / r[..., None]
    s = sun / np.linalg.norm(sun, axis=-1)[..., None]
    sn = np.sum(s * nadir, axis=-1)
    across = s - sn[..., None] * nadir
    b0 = np.linalg.norm(across, axis=-1)
    e1 = np.where(b0[..., None] > 1e-12, across / np.maximum(b0, 1e-300)[..., None], 0.0)
    # the Sun along the nadir axis: any perpendicular serves (the rings are then uniform)
    fallback = np.cross(nadir, np.where(np.abs(nadir[..., :1]) < 0.9, [1.0, 0, 0], [0, 1.0, 0]))
    e1 = np.where(
        b0[..., None] > 1e-12, e1, fallback / np.linalg.norm(fallback, axis=-1)[..., None]
    )
    e2 = np.cross(nadir, e1)

    # polar nodes: Gauss–Legendre in u = cos θ on three pieces of [cos ρ, 1], split where
    # a ring starts to be lit and where it is lit all round (the integrand's kinks)
    cos_rho = np.sqrt(1.0 - (EARTH_RADIUS_M / r) ** 2)
    grid = cos_rho[..., None] + (1.0 - cos_rho[..., None]) * np.linspace(0.0, 1.0, 257)
    kinks = [_first_root(grid, f) for f in _ring_extremes(grid, r, sn, b0)]
    knots = np.stack([cos_rho, np.minimum(*kinks), np.maximum(*kinks), np.ones_like(r)], -1)
    x, wx = np.polynomial.legendre.leggauss(n_polar)
    half = 0.5 * np.diff(knots, axis=-1)[..., None]  # (..., 3, 1)
    u = (knots[..., :-1, None] + half * (x + 1.0)).reshape(*r.shape, -1)  # (..., 3P)
    du = (half * wx).reshape(*r.shape, -1)
    a, b, sin_t, _ = _ring(u, r, sn, b0)
    with np.errstate(divide="ignore", invalid="ignore"):
        edge = np.where(b > 0.0, -a / b, np.where(a > 0.0, -np.inf, np.inf))
    delta = np.arccos(np.clip(edge, -1.0, 1.0))  # half-width of the lit arc (rad)

    # azimuth nodes: Gauss–Legendre on [−Δ, Δ]
    y, wy = np.polynomial.legendre.leggauss(n_azimuth)
    phi = delta[..., None] * y  # (..., P, A)
    dphi = delta[..., None] * wy
    cos_m_s = (a[..., None] + b[..., None] * np.cos(phi)) / EARTH_RADIUS_M
    weights = albedo / math.pi * np.clip(cos_m_s, 0.0, None) * du[..., None] * dphi
    ring = sin_t[..., None, None] * (
        np.cos(phi)[..., None] * e1[..., None, None, :]
        + np.sin(phi)[..., None] * e2[..., None, None, :]
    )
    directions = u[..., None, None] * nadir[..., None, None, :] + ring
    shape = weights.shape[:-2]
    return directions.reshape(*shape, -1, 3), weights.reshape(*shape, -1)


def _ring(
    u: np.ndarray, r: np.ndarray, sn: np.ndarray, b0: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """On the ring ``cos θ = u (..., n)`` of directions from an object at distance
    ``r (...)``: ``a, b`` with ``R (m·ŝ) = a + b cos(φ − φ₀)`` at the surface point hit,
    ``sin θ`` and the range ``t`` to that point (m). ``sn = ŝ·n̂`` (nadir) and ``b0`` the
    Sun's component across the nadir."""
    rr = r[..., None]
    sin_t = np.sqrt(np.clip(1.0 - u * u, 0.0, None))
    t = rr * u - np.sqrt(np.clip(EARTH_RADIUS_M**2 - (rr * sin_t) ** 2, 0.0, None))
    return sn[..., None] * (t * u - rr), t * sin_t * b0[..., None], sin_t, t


def _ring_extremes(
    u: np.ndarray, r: np.ndarray, sn: np.ndarray, b0: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``R max(m·ŝ)`` and ``R min(m·ŝ)`` around each ring ``u``: where they change sign a
    ring starts to be lit and becomes lit all round."""
    a, b, _, _ = _ring(u, r, sn, b0)
    return a + b, a - b


def _first_root(u: np.ndarray, f: np.ndarray) -> np.ndarray:
    """The first sign change of ``f`` along the last axis of the grid ``u``, linearly
    interpolated; ``u[..., 0]`` where there is none."""
    change = np.signbit(f[..., 1:]) != np.signbit(f[..., :-1])
    i = np.argmax(change, axis=-1)[..., None]
    u0, u1 = np.take_along_axis(u, i, -1)[..., 0], np.take_along_axis(u, i + 1, -1)[..., 0]
    f0, f1 = np.take_along_axis(f, i, -1)[..., 0], np.take_along_axis(f, i + 1, -1)[..., 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        root = np.where(f1 != f0, u0 + (u1 - u0) * f0 / (f0 - f1), u0)
    return np.where(change.any(axis=-1), root, u[..., 0])


def earthshine_flux(
    renderer: Any,
    q: Any,
    observer: Any,
    position: Any,
    sun: Any,
    *,
    albedo: float = EARTH_ALBEDO,
    n_polar: int = 4,
    n_azimuth: int = 8,
    columns: Mapping[str, Any] | None = None,
) -> np.ndarray:
    """Flux ratio ``F_obs / F☉`` of the object lit by the Earth alone.

    The object's renderer is evaluated with each quadrature direction of
    :func:`earth_cap_quadrature` as the light at the Sun's irradiance and the results are
    summed with the weights: every facet's BRDF and the renderer's shadow mode apply to
    the Earth's light as to the Sun's. The joints of an articulated shape stay where the
    Sun puts them (a Sun-tracking array does not turn to the Earth).

    Parameters
    ----------
    renderer : Renderer or ArticulatedRenderer
        :class:`~lightcurve.photometry.render.Renderer`, or
        :class:`~lightcurve.photometry.articulated.ArticulatedRenderer`.
    q : (E, 4) array
        Attitudes (inertial → body).
    observer : (E, 3) array
        Object → observer vectors (m, inertial).
    position : (E, 3) array
        Geocentric positions of the object (m, inertial).
    sun : (E, 3) array
        Object → Sun vectors (m, inertial).
    albedo, n_polar, n_azimuth
        See :func:`earth_cap_quadrature` (the default 96 directions: within 1 %).
    columns : mapping, optional
        Observation-file columns of an articulated shape's ``scheduled`` joints, ``(E,)`` each.

    Returns
    -------
    (E,) numpy.ndarray
        Add it to the sunlit flux ratio for the total.
    """

    directions, weights = earth_cap_quadrature(
        position, sun, albedo=albedo, n_polar=n_polar, n_azimuth=n_azimuth
    )
    lit = np.asarray(weights > 0.0)
    flux = np.zeros(np.shape(weights))
    rows, nodes = np.nonzero(lit)
    if len(rows):
        pose = {}
        if isinstance(renderer, ArticulatedRenderer):
            pose["joint_sun"] = np.asarray(sun, dtype=float)[rows]
            if columns is not None:
                pose["columns"] = {k: np.asarray(v, float)[rows] for k, v in columns.items()}
        # one light per lit node at 1 AU: the renderer's (1 AU / r)² scale is then 1
        flux[rows, nodes] = renderer.flux(
            np.asarray(q, dtype=float)[rows],
            directions[rows, nodes] * AU_M,
            np.asarray(observer, dtype=float)[rows],
            **pose,
        )
    return np.sum(weights * flux, axis=-1)


def known_positions(observations: Any) -> np.ndarray | None:
    """The object's geocentric positions (m) of an observation table with the ``obj_*``
    columns, else None."""
    if all(c in observations.table for c in OBJECT_POSITION_COLUMNS):
        return observations.object_positions
    return None


def sun_and_earth_flux(
    renderer: Any,
    q: Any,
    sun: Any,
    observer: Any,
    position: Any | None = None,
    *,
    columns: Mapping[str, Any] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Flux ratios of the object lit by the Sun and by the Earth.

    Parameters
    ----------
    renderer : Renderer or ArticulatedRenderer
    q : (E, 4) array
        Attitudes (inertial → body).
    sun, observer : (E, 3) array
        Object → Sun and object → observer vectors (m, inertial).
    position : (E, 3) array or None
        Geocentric positions of the object (m, inertial) to render the Earth's light from
        (:func:`earthshine_flux`); None for none (zeros).
    columns : mapping, optional
        Columns of an articulated shape's ``scheduled`` joints.

    Returns
    -------
    sunlit, earthlit : (E,) numpy.ndarray
    """
    pose = {} if columns is None else {"columns": columns}
    sunlit = np.asarray(renderer.flux(q, sun, observer, **pose), dtype=float)
    if position is None:
        return sunlit, np.zeros_like(sunlit)
    return sunlit, earthshine_flux(renderer, q, observer, position, sun, columns=columns)
