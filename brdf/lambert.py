"""Lambertian (perfectly diffuse) reflectance.

``ρ = rd/π`` for ``n·L > 0`` and ``n·V > 0``, else 0 (Lambert 1760; the diffuse model of
Gou et al. 2016, sec. 3.2). ``rd`` is the directional-hemispherical albedo.
"""

from __future__ import annotations

from typing import Any

from brdf._array import prepare
from brdf._geometry import cosines, visibility

__all__ = ["lambert", "lambert_from_cosines"]

_INV_PI = 0.3183098861837907


def lambert_from_cosines(nl: Any, nv: Any, lv: Any, /, rd: Any) -> Any:
    """Lambert BRDF from the cosines ``n·L``, ``n·V`` and ``L·V``.

    Parameters
    ----------
    nl, nv : (..., F) arrays
        ``n·L`` and ``n·V``.
    lv : array
        ``L·V`` (broadcastable, e.g. ``(..., 1)``); unused by this model, kept for the common
        signature of the cosine forms.
    rd : float or array
        Diffuse albedo in [0, 1]; broadcasts against the leading dimensions.

    Returns
    -------
    array
        ρ in sr⁻¹, zero where ``nl ≤ 0`` or ``nv ≤ 0``.
    """
    xp, (nl, nv), (rd,) = prepare((nl, nv), (rd,))
    visible, _ = visibility(xp, nl, nv)
    return (rd * _INV_PI) * visible


def lambert(normal: Any, light: Any, view: Any, rd: Any) -> Any:
    """Lambert BRDF of unit direction vectors.

    Parameters
    ----------
    normal, light, view : (..., 3) arrays
        Unit facet normal and unit vectors to the Sun and to the observer (any common frame).
    rd : float or array
        Diffuse albedo in [0, 1].

    Returns
    -------
    (...) array
        ρ in sr⁻¹, zero where ``n·L ≤ 0`` or ``n·V ≤ 0``.
    """
    xp, (normal, light, view), _ = prepare((normal, light, view))
    return lambert_from_cosines(*cosines(xp, normal, light, view), rd=rd)
