"""Cook–Torrance microfacet reflectance (Cook & Torrance 1981).

``ρ = rd/π + rs·D·G·F/(4 (n·L)(n·V))`` for ``n·L > 0`` and ``n·V > 0``, else 0, with

* Beckmann facet distribution ``D = exp(−(1 − NH²)/(NH² m²))/(π m² NH⁴)`` (``m`` the RMS facet
  slope; ``∫ D NH dω_H = 1``),
* V-cavity masking–shadowing ``G = min(1, 2 NH NV/VH, 2 NH NL/VH)``,
* Schlick's Fresnel term ``F = f0 + (1 − f0)(1 − VH)⁵`` (``f0`` the reflectance at normal
  incidence).

Every factor is symmetric in ``L`` and ``V``, so the model is reciprocal; with ``rs = 0`` it is
Lambert's.
"""

from __future__ import annotations

from typing import Any

from brdf._array import prepare
from brdf._geometry import COSINE_FLOOR, cosines, half_vector, visibility
from brdf._microfacet import beckmann_shape, schlick, v_cavity

__all__ = ["cook_torrance", "cook_torrance_from_cosines"]

_INV_PI = 0.3183098861837907


def cook_torrance_from_cosines(
    nl: Any, nv: Any, lv: Any, /, *, rd: Any, rs: Any, m: Any, f0: Any
) -> Any:
    """Cook–Torrance BRDF from the cosines ``n·L``, ``n·V`` and ``L·V``.

    Parameters
    ----------
    nl, nv : (..., F) arrays
        ``n·L`` and ``n·V``.
    lv : array
        ``L·V``, broadcastable (e.g. ``(..., 1)`` per epoch).
    rd, rs : float or array
        Diffuse and specular weights (``rd + rs ≤ 1``).
    m : float or array
        Beckmann RMS facet slope (> 0, dimensionless).
    f0 : float or array
        Fresnel reflectance at normal incidence, in [0, 1].

    Returns
    -------
    array
        ρ in sr⁻¹, zero where ``nl ≤ 0`` or ``nv ≤ 0``.
    """
    xp, (nl, nv, lv), (rd, rs, m, f0) = prepare((nl, nv, lv), (rd, rs, m, f0))
    visible, low = visibility(xp, nl, nv)
    vh, nh = half_vector(xp, nl, nv, lv)
    inv_m2 = 1.0 / (m * m)
    # D = exp(−tan²θ_H / m²)/(π m² cos⁴θ_H), tan²θ_H = 1/NH² − 1.
    distribution = beckmann_shape(xp, 1.0 / (nh * nh), inv_m2)
    low = xp.clip(low, COSINE_FLOOR, None)
    masking = v_cavity(xp, nh, low, vh)
    fresnel = schlick(f0, vh)  # one value per epoch
    specular_weight = (rs * 0.25 * _INV_PI) * inv_m2 * fresnel
    specular = distribution * masking / (low * xp.clip(xp.maximum(nl, nv), COSINE_FLOOR, None))
    return (rd * _INV_PI + specular_weight * specular) * visible


def cook_torrance(normal: Any, light: Any, view: Any, *, rd: Any, rs: Any, m: Any, f0: Any) -> Any:
    """Cook–Torrance BRDF of unit direction vectors.

    Parameters
    ----------
    normal, light, view : (..., 3) arrays
        Unit facet normal and unit vectors to the Sun and to the observer (any common frame).
    rd, rs, m, f0 : float or array
        See `cook_torrance_from_cosines`.

    Returns
    -------
    (...) array
        ρ in sr⁻¹.
    """
    xp, (normal, light, view), _ = prepare((normal, light, view))
    return cook_torrance_from_cosines(*cosines(xp, normal, light, view), rd=rd, rs=rs, m=m, f0=f0)
