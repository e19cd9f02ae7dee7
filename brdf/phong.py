"""Energy-normalised Phong reflectance (Phong 1975; Lewis 1994 normalisation).

``ρ = rd/π + rs·(n + 2)/(2π)·max(0, R·V)^n`` for ``n·L > 0`` and ``n·V > 0``, else 0, with
``R = 2 (n·L) n − L`` the mirror direction of the Sun vector, so ``R·V = 2 (n·L)(n·V) − L·V``.
The factor ``(n + 2)/(2π)`` makes the specular albedo at normal incidence equal to ``rs``
(smaller at oblique incidence), so ``rd + rs ≤ 1`` conserves energy. The model is reciprocal
because ``R·V`` is symmetric in ``L`` and ``V``.
"""

from __future__ import annotations

from typing import Any

from brdf._array import prepare
from brdf._geometry import cosines, visibility

__all__ = ["phong", "phong_from_cosines"]

_INV_PI = 0.3183098861837907
_INV_TWO_PI = 0.15915494309189535


def phong_from_cosines(nl: Any, nv: Any, lv: Any, /, rd: Any, rs: Any, n: Any) -> Any:
    """Phong BRDF from the cosines ``n·L``, ``n·V`` and ``L·V``.

    Parameters
    ----------
    nl, nv : (..., F) arrays
        ``n·L`` and ``n·V``.
    lv : array
        ``L·V``, broadcastable (e.g. ``(..., 1)`` per epoch).
    rd, rs : float or array
        Diffuse and specular albedos (``rd + rs ≤ 1``).
    n : float or array
        Specular exponent (≥ 0, dimensionless).

    Returns
    -------
    array
        ρ in sr⁻¹, zero where ``nl ≤ 0`` or ``nv ≤ 0``.
    """
    xp, (nl, nv, lv), (rd, rs, n) = prepare((nl, nv, lv), (rd, rs, n))
    visible, _ = visibility(xp, nl, nv)
    mirror = xp.clip(2.0 * nl * nv - lv, 0.0, None)
    lobe = mirror**n
    return (rd * _INV_PI + (rs * (n + 2.0) * _INV_TWO_PI) * lobe) * visible


def phong(normal: Any, light: Any, view: Any, rd: Any, rs: Any, n: Any) -> Any:
    """Phong BRDF of unit direction vectors.

    Parameters
    ----------
    normal, light, view : (..., 3) arrays
        Unit facet normal and unit vectors to the Sun and to the observer (any common frame).
    rd, rs, n : float or array
        Diffuse albedo, specular albedo and specular exponent (see `phong_from_cosines`).

    Returns
    -------
    (...) array
        ρ in sr⁻¹.
    """
    xp, (normal, light, view), _ = prepare((normal, light, view))
    return phong_from_cosines(*cosines(xp, normal, light, view), rd=rd, rs=rs, n=n)
