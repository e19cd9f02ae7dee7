"""Observation geometry: directions, ranges, phase angle, the phase-angle bisector and
the reciprocity twin of an attitude.

Inputs are object → Sun and object → observer vectors in the inertial frame (metres). The
body-frame directions used by the renderer are ``A(q) û`` (attitude core). The Sun's flux
at the object is the flux at 1 AU scaled by ``(1 AU / r_sun)²``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from filters.attitude import quaternion_multiply, rotate
from filters.attitude.arrays import as_arrays, cross

__all__ = [
    "AU_M",
    "body_directions",
    "lon_lat_deg",
    "phase_angle",
    "phase_angle_bisector",
    "reciprocity_twin",
    "solar_flux_scale",
    "unit_and_range",
]

AU_M = 149_597_870_700.0


def unit_and_range(vectors: Any) -> tuple[Any, Any]:
    """Unit vectors and lengths.

    Parameters
    ----------
    vectors : (..., 3) array
        Non-zero vectors (m).

    Returns
    -------
    unit : (..., 3) array
    length : (...) array
        In the unit of the input.
    """
    xp, (v,) = as_arrays(vectors)
    length = xp.linalg.vector_norm(v, axis=-1)
    return v / length[..., None], length


def phase_angle(sun: Any, observer: Any) -> Any:
    """Sun–object–observer angle α (rad) from object → Sun and object → observer vectors.

    Computed as ``atan2(|s × o|, s · o)``, accurate at every angle.

    Parameters
    ----------
    sun, observer : (..., 3) array

    Returns
    -------
    (...) array
        In ``[0, π]``.
    """
    xp, (s, o) = as_arrays(sun, observer)
    s, _ = unit_and_range(s)
    o, _ = unit_and_range(o)
    return xp.atan2(xp.linalg.vector_norm(cross(s, o), axis=-1), xp.sum(s * o, axis=-1))


def phase_angle_bisector(sun: Any, observer: Any) -> Any:
    """Unit phase-angle bisector ``h = (ŝ + ô)/|ŝ + ô|`` (Gou et al. 2016, sec. 2.2).

    A flat facet produces a specular glint when its normal is along ``h``.

    Parameters
    ----------
    sun, observer : (..., 3) array

    Returns
    -------
    (..., 3) array
        Undefined (NaN) at phase angle π.
    """
    s, _ = unit_and_range(sun)
    o, _ = unit_and_range(observer)
    h, _ = unit_and_range(s + o)
    return h


def reciprocity_twin(q: Any, sun: Any, observer: Any) -> Any:
    """The attitude that sees the Sun where ``q`` sees the observer, and vice versa.

    With ``h`` the phase-angle bisector and ``R_h = 2 h hᵀ − I`` the half-turn about it
    (``R_h ŝ = ô``), the twin ``A(q') = A(q) R_h``, i.e. ``q' = q ⊗ [h, 0]``, has body-frame
    Sun and observer directions ``L' = V`` and ``V' = L``. Every reciprocal BRDF
    (``f(L, V) = f(V, L)``: Lambert, Phong, Cook–Torrance, Ashikhmin–Shirley) and the
    lit-and-visible test of self-shadowing are symmetric in the swap, so the twin renders
    exactly the same brightness, for any shape. Body rates are unchanged (the half-turn
    is fixed in inertial space), so while the Sun and the observer stand still the whole
    light curve of ``(q', ω)`` equals that of ``(q, ω)``: an ambiguity of single-site
    photometry that only the motion of the bisector resolves. From a geostationary orbit
    the bisector turns about 0.13° per minute, so a 10 min arc barely separates the twins
    and a 20 min arc does (the χ² gap grows as the cube of the arc length).

    Parameters
    ----------
    q : (..., 4) array
        Attitudes (inertial → body).
    sun, observer : (..., 3) array
        Object → Sun and object → observer vectors, inertial frame, at the epoch of ``q``.

    Returns
    -------
    (..., 4) array
        The twin attitudes, same kind as ``q``; undefined (NaN) at phase angle π.
    """
    xp, (q, s, o) = as_arrays(q, sun, observer)
    h = phase_angle_bisector(s, o)
    half_turn = xp.concat([h, xp.zeros_like(h[..., :1])], axis=-1)
    return quaternion_multiply(q, half_turn)


def body_directions(q: Any, sun: Any, observer: Any) -> tuple[Any, Any]:
    """Unit Sun and observer directions in the body frame, ``L = A(q) ŝ``, ``V = A(q) ô``.

    Parameters
    ----------
    q : (..., 4) array
        Attitude quaternions (inertial → body).
    sun, observer : (..., 3) array
        Object → Sun and object → observer vectors, inertial frame.

    Returns
    -------
    light, view : (..., 3) array
    """
    s, _ = unit_and_range(sun)
    o, _ = unit_and_range(observer)
    return rotate(q, s), rotate(q, o)


def solar_flux_scale(sun_range: Any) -> Any:
    """Solar flux at the object relative to 1 AU, ``(1 AU / r_sun)²``.

    Parameters
    ----------
    sun_range : array
        Object–Sun distance (m).

    Returns
    -------
    array
    """
    _, (r,) = as_arrays(sun_range)
    return (AU_M / r) ** 2


def lon_lat_deg(v: np.ndarray) -> tuple[float, float]:
    """Longitude in [0, 360) and latitude (deg) of a unit vector."""
    return (
        math.degrees(math.atan2(v[1], v[0])) % 360.0,
        math.degrees(math.asin(float(np.clip(v[2], -1, 1)))),
    )
