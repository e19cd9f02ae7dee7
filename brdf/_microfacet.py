"""Microfacet factors shared by Cook–Torrance and the two-lobe model.

A microfacet lobe is ``w D(NH) G F(VH) / (4 NL NV)`` (Cook & Torrance 1981, "A reflectance
model for computer graphics"; Walter et al. 2007, "Microfacet models for refraction through
rough surfaces"). The factors here take the clamped cosines of `brdf._geometry`:

* Schlick's Fresnel approximation ``F = f0 + (1 − f0)(1 − VH)⁵`` (Schlick 1994, "An
  inexpensive BRDF model for physically-based rendering");
* the V-cavity masking–shadowing ``G = min(1, 2 NH min(NL, NV)/VH)`` (Cook & Torrance 1981);
* the Beckmann distribution ``D = exp(−tan²θ_H/m²)/(π m² NH⁴)`` (Beckmann & Spizzichino 1963)
  and the Trowbridge–Reitz (GGX) distribution ``D = α²/(π ((1 − NH²) + α² NH²)²)``
  (Trowbridge & Reitz 1975; Walter et al. 2007). Both are normalised, ``∫ D NH dω_H = 1``
  over the hemisphere; GGX has power-law tails (``D ∝ tan⁻⁴θ_H``), Beckmann Gaussian ones.
"""

from __future__ import annotations

from types import ModuleType
from typing import Any

__all__ = ["beckmann_shape", "schlick", "trowbridge_reitz_shape", "v_cavity"]


def schlick(f0: Any, vh: Any) -> Any:
    """Schlick's Fresnel factor ``f0 + (1 − f0)(1 − VH)⁵`` (the fifth power by multiplication)."""
    q = 1.0 - vh
    q2 = q * q
    return f0 + (1.0 - f0) * (q2 * q2 * q)


def v_cavity(xp: ModuleType, nh: Any, low: Any, vh: Any) -> Any:
    """V-cavity masking–shadowing ``min(1, 2 NH low/VH)``, ``low = min(NL, NV)`` (clamped)."""
    return xp.clip(nh * low * (2.0 / vh), None, 1.0)


def beckmann_shape(xp: ModuleType, inv_nh2: Any, inv_m2: Any) -> Any:
    """``π m² D`` of the Beckmann distribution: ``exp((1 − 1/NH²)/m²)/NH⁴``.

    Parameters
    ----------
    inv_nh2 : array
        ``1/NH²``.
    inv_m2 : float or array
        ``1/m²`` (``m`` the RMS facet slope).
    """
    return xp.exp((1.0 - inv_nh2) * inv_m2) * (inv_nh2 * inv_nh2)


def trowbridge_reitz_shape(nh2: Any, alpha2: Any) -> Any:
    """``π D`` of the Trowbridge–Reitz (GGX) distribution: ``α²/((1 − NH²) + α² NH²)²``.

    ``1 − NH²`` is formed first (no cancellation against ``α²`` for small roughness).

    Parameters
    ----------
    nh2 : array
        ``NH²``.
    alpha2 : float or array
        ``α²`` (``α`` the roughness).
    """
    denominator = (1.0 - nh2) + alpha2 * nh2
    return alpha2 / (denominator * denominator)
