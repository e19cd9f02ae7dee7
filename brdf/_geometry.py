"""Scattering geometry shared by the BRDF kernels: cosines, visibility and the half vector.

Notation (``docs/brdf.md``): ``n`` facet normal, ``L`` unit vector to the Sun, ``V`` unit
vector to the observer, ``H = (L + V)/|L + V|``. The cosine form of every model needs only
``nl = n·L``, ``nv = n·V`` and ``lv = L·V``; the half-vector quantities follow from them:

* ``|L + V| = √(2 + 2 lv)``, ``VH = LH = |L + V|/2`` (a function of the epoch only),
* ``NH = (nl + nv)/|L + V|``,
* ``R·V = 2 nl nv − lv`` with ``R = 2 nl n − L`` the mirror direction of ``L``.

The helpers clamp the quantities to finite, safe values at the geometries every model masks to
zero (``nl ≤ 0`` or ``nv ≤ 0``) so that forward values and autograd gradients stay finite
there; the kernels multiply by the visibility mask at the end.
"""

from __future__ import annotations

from types import ModuleType
from typing import Any

__all__ = ["COSINE_FLOOR", "cosines", "half_vector", "tangent_cosines", "visibility"]

# Cosines are clamped from below at this value (≈ 6·10⁻⁵ degrees from the horizon) where a
# model divides by them; masked geometries are then finite in float32 as well as float64.
COSINE_FLOOR = 1e-6
# |L + V|² is clamped from below at this value (L = −V, which only occurs on masked geometries).
_SUM_SQUARED_FLOOR = 1e-12


def _dot(xp: ModuleType, a: Any, b: Any) -> Any:
    return xp.sum(a * b, axis=-1)


def cosines(xp: ModuleType, normal: Any, light: Any, view: Any) -> tuple[Any, Any, Any]:
    """Cosines ``(n·L, n·V, L·V)`` of unit direction arrays.

    Parameters
    ----------
    xp : module
        Array namespace.
    normal, light, view : (..., 3) arrays
        Unit facet normal and unit vectors to the Sun and the observer (same frame).

    Returns
    -------
    nl, nv, lv : (...) arrays
        Broadcast over the leading dimensions.
    """
    return _dot(xp, normal, light), _dot(xp, normal, view), _dot(xp, light, view)


def tangent_cosines(
    xp: ModuleType, normal: Any, tangent: Any, light: Any, view: Any
) -> tuple[Any, Any]:
    """Half-vector cosines ``(H·u, H·v)`` in the facet tangent frame.

    ``u`` is ``tangent`` projected on the facet plane and normalised, ``v = n × u``.

    Parameters
    ----------
    xp : module
        Array namespace.
    normal, tangent, light, view : (..., 3) arrays
        Unit normal, material reference direction (not parallel to the normal), unit vectors
        to the Sun and the observer.

    Returns
    -------
    hu, hv : (...) arrays
    """
    u = tangent - _dot(xp, tangent, normal)[..., None] * normal
    u = u / xp.sqrt(_dot(xp, u, u))[..., None]
    v = xp.linalg.cross(*xp.broadcast_arrays(normal, u))
    half = light + view
    half = half / xp.sqrt(xp.clip(_dot(xp, half, half), _SUM_SQUARED_FLOOR, None))[..., None]
    return _dot(xp, half, u), _dot(xp, half, v)


def visibility(xp: ModuleType, nl: Any, nv: Any) -> tuple[Any, Any]:
    """Visibility mask and the smaller cosine.

    Returns
    -------
    visible : array
        1.0 where ``nl > 0`` and ``nv > 0``, else 0.0, in the dtype of the cosines.
    low : array
        ``min(nl, nv)``.
    """
    low = xp.minimum(nl, nv)
    return xp.astype(low > 0, low.dtype), low


def half_vector(xp: ModuleType, nl: Any, nv: Any, lv: Any) -> tuple[Any, Any]:
    """``(VH, NH)`` from the cosines.

    Parameters
    ----------
    xp : module
        Array namespace.
    nl, nv : arrays
        ``n·L`` and ``n·V`` (e.g. facets × epochs).
    lv : array
        ``L·V`` (broadcastable, e.g. one per epoch).

    Returns
    -------
    vh : array
        ``V·H = √(2 + 2 lv)/2``, shape of ``lv``.
    nh : array
        ``N·H = (nl + nv)/|L + V|`` clamped to ``[COSINE_FLOOR, 1]`` (rounding can push it past
        1; below the floor every lobe has underflowed anyway).
    """
    length = xp.sqrt(xp.clip(2.0 + 2.0 * lv, _SUM_SQUARED_FLOOR, None))
    nh = xp.clip((nl + nv) * (1.0 / length), COSINE_FLOOR, 1.0)
    return 0.5 * length, nh
