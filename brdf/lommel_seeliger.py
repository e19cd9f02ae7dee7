"""Lommel–Seeliger + Lambert scattering with the DAMIT phase function, for asteroids.

The light-curve inversion software of Kaasalainen & Ďurech (DAMIT, convexinv) models the
brightness of a facet as ``f(α)·S`` with the scattering law
``S = NL·NV/(NL + NV) + c·NL·NV`` (Lommel–Seeliger plus ``c`` times Lambert) and the
three-parameter phase function ``f(α) = a·exp(−α/d) + k·α + 1`` (α the solar phase angle,
``cos α = L·V``; α and ``d`` in radians).

Since a facet contributes ``ρ·NL·NV`` to the flux (``docs/brdf.md``), the law is exposed as the
BRDF ::

    ρ = w/(4π) · f(α) · (1/(NL + NV) + c)      for NL > 0 and NV > 0, else 0.

Normalisation: with ``c = 0`` and ``f ≡ 1`` this is the Lommel–Seeliger single-scattering BRDF
``ϖ/(4π (μ0 + μ))`` of an isotropic scatterer, so ``w`` is the single-scattering albedo ϖ
(Hapke 2012, *Theory of Reflectance and Emittance Spectroscopy*, eq. 9.5 with ``p = 1``).
``f`` is clamped at 0: with DAMIT's usual ``k < 0`` the linear term would turn it negative at
large phase angles (e.g. beyond 114° for ``a = 0.5, d = 0.1, k = −0.5``). The model is
reciprocal (symmetric in NL, NV and α).
"""

from __future__ import annotations

from typing import Any

from brdf._array import prepare
from brdf._geometry import COSINE_FLOOR, cosines, visibility

__all__ = ["lommel_seeliger", "lommel_seeliger_from_cosines", "phase_function"]

_INV_4PI = 1.0 / (4.0 * 3.141592653589793)


def phase_function(lv: Any, a: Any, d: Any, k: Any) -> Any:
    """DAMIT phase function ``f(α) = max(0, a·exp(−α/d) + k·α + 1)``, ``α = arccos(L·V)``.

    Parameters
    ----------
    lv : array
        ``L·V`` (cosine of the phase angle).
    a : float or array
        Amplitude of the opposition effect (≥ 0).
    d : float or array
        Width of the opposition effect (rad, > 0).
    k : float or array
        Slope of the linear part (rad⁻¹).

    Returns
    -------
    array
        Dimensionless, ≥ 0.
    """
    xp, (lv,), (a, d, k) = prepare((lv,), (a, d, k))
    alpha = xp.acos(xp.clip(lv, -1.0, 1.0))
    return xp.clip(a * xp.exp(-alpha / d) + k * alpha + 1.0, 0.0, None)


def lommel_seeliger_from_cosines(
    nl: Any, nv: Any, lv: Any, /, *, w: Any, c: Any, a: Any, d: Any, k: Any
) -> Any:
    """Lommel–Seeliger BRDF from the cosines ``n·L``, ``n·V`` and ``L·V``.

    Parameters
    ----------
    nl, nv : (..., F) arrays
        ``n·L`` and ``n·V``.
    lv : array
        ``L·V``, broadcastable (e.g. ``(..., 1)`` per epoch).
    w : float or array
        Single-scattering albedo (≥ 0).
    c : float or array
        Weight of the Lambert term (≥ 0).
    a, d, k : float or array
        Phase-function parameters (see `phase_function`).

    Returns
    -------
    array
        ρ in sr⁻¹, zero where ``nl ≤ 0`` or ``nv ≤ 0``.
    """
    xp, (nl, nv, lv), (w, c, a, d, k) = prepare((nl, nv, lv), (w, c, a, d, k))
    visible, _ = visibility(xp, nl, nv)
    scale = (w * _INV_4PI) * phase_function(lv, a, d, k)
    return scale * (1.0 / xp.clip(nl + nv, COSINE_FLOOR, None) + c) * visible


def lommel_seeliger(
    normal: Any, light: Any, view: Any, *, w: Any, c: Any, a: Any, d: Any, k: Any
) -> Any:
    """Lommel–Seeliger BRDF of unit direction vectors.

    Parameters
    ----------
    normal, light, view : (..., 3) arrays
        Unit facet normal and unit vectors to the Sun and to the observer (any common frame).
    w, c, a, d, k : float or array
        See `lommel_seeliger_from_cosines`.

    Returns
    -------
    (...) array
        ρ in sr⁻¹.
    """
    xp, (normal, light, view), _ = prepare((normal, light, view))
    return lommel_seeliger_from_cosines(*cosines(xp, normal, light, view), w=w, c=c, a=a, d=d, k=k)
