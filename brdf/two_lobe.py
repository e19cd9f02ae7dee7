"""Diffuse term plus two microfacet lobes: a broad glossy lobe and a narrow mirror (glint) lobe.

Flat spacecraft surfaces such as cover-glassed solar arrays reflect in two ways at once
(Fankhauser, Askari & Tyson 2023, "Satellite optical brightness", their lab BRDFs): a glossy
lobe some degrees wide, with power-law tails, and a mirror spike narrower than a degree
holding most of the peak. One microfacet lobe cannot follow both. This model adds two
(Cook & Torrance 1981; Walter et al. 2007, "Microfacet models for refraction through rough
surfaces"):

``ρ = rd/π + G/(4 NL NV) · [rb F(fb) D_TR(ab) + rn F(fn) D_B(mn)]`` for ``NL > 0`` and
``NV > 0``, else 0, with

* ``D_TR`` the Trowbridge–Reitz (GGX) distribution of roughness ``ab`` (broad lobe, power-law
  tails; Trowbridge & Reitz 1975), ``D_B`` the Beckmann distribution of RMS slope ``mn``
  (narrow lobe, Gaussian core),
* ``F(f) = f + (1 − f)(1 − VH)⁵`` Schlick's Fresnel factor, one reflectance at normal
  incidence per lobe (a cover glass's first-surface reflection and the cells beneath it
  differ),
* ``G = min(1, 2 NH NL/VH, 2 NH NV/VH)`` the V-cavity masking–shadowing, shared.

Energy: both distributions are normalised (``∫ D NH dω_H = 1``) and the V-cavity term obeys
``∫ D G₁(L, H) (L·H)/(N·L) dω_H = 1`` with ``G ≤ G₁`` (Heitz 2014, "Understanding the
masking-shadowing function in microfacet-based BRDFs"), so each lobe's directional albedo is
at most its weight (times ``F ≤ 1``): ``rd + rb + rn ≤ 1`` keeps the albedo ≤ 1 for every
incidence (checked by quadrature in the tests). Every factor is symmetric in ``L`` and ``V``
(reciprocal). With ``rb = rn = 0`` it is Lambert's; with one weight 0 it is one Cook–Torrance
lobe (Beckmann) or its GGX variant.
"""

from __future__ import annotations

from typing import Any

from brdf._array import prepare
from brdf._geometry import COSINE_FLOOR, cosines, half_vector, visibility
from brdf._microfacet import beckmann_shape, schlick, trowbridge_reitz_shape, v_cavity

__all__ = ["two_lobe", "two_lobe_from_cosines"]

_INV_PI = 0.3183098861837907


def two_lobe_from_cosines(
    nl: Any,
    nv: Any,
    lv: Any,
    /,
    *,
    rd: Any,
    rb: Any,
    ab: Any,
    fb: Any,
    rn: Any,
    mn: Any,
    fn: Any,
) -> Any:
    """Two-lobe BRDF from the cosines ``n·L``, ``n·V`` and ``L·V``.

    Parameters
    ----------
    nl, nv : (..., F) arrays
        ``n·L`` and ``n·V``.
    lv : array
        ``L·V``, broadcastable (e.g. ``(..., 1)`` per epoch).
    rd : float or array
        Diffuse weight (Lambert albedo), in [0, 1].
    rb, rn : float or array
        Weights of the broad and the narrow lobe, in [0, 1] (``rd + rb + rn ≤ 1``).
    ab : float or array
        Trowbridge–Reitz (GGX) roughness of the broad lobe (> 0).
    mn : float or array
        Beckmann RMS facet slope of the narrow lobe (> 0).
    fb, fn : float or array
        Fresnel reflectance at normal incidence of each lobe, in [0, 1].

    Returns
    -------
    array
        ρ in sr⁻¹, zero where ``nl ≤ 0`` or ``nv ≤ 0``.
    """
    xp, (nl, nv, lv), (rd, rb, ab, fb, rn, mn, fn) = prepare(
        (nl, nv, lv), (rd, rb, ab, fb, rn, mn, fn)
    )
    visible, low = visibility(xp, nl, nv)
    vh, nh = half_vector(xp, nl, nv, lv)
    nh2 = nh * nh
    inv_m2 = 1.0 / (mn * mn)
    broad = (rb * schlick(fb, vh)) * trowbridge_reitz_shape(nh2, ab * ab)
    narrow = (rn * inv_m2 * schlick(fn, vh)) * beckmann_shape(xp, 1.0 / nh2, inv_m2)
    low = xp.clip(low, COSINE_FLOOR, None)
    masking = v_cavity(xp, nh, low, vh)
    specular = (broad + narrow) * masking / (low * xp.clip(xp.maximum(nl, nv), COSINE_FLOOR, None))
    return (rd * _INV_PI + (0.25 * _INV_PI) * specular) * visible


def two_lobe(
    normal: Any,
    light: Any,
    view: Any,
    *,
    rd: Any,
    rb: Any,
    ab: Any,
    fb: Any,
    rn: Any,
    mn: Any,
    fn: Any,
) -> Any:
    """Two-lobe BRDF of unit direction vectors.

    Parameters
    ----------
    normal, light, view : (..., 3) arrays
        Unit facet normal and unit vectors to the Sun and to the observer (any common frame).
    rd, rb, ab, fb, rn, mn, fn : float or array
        See `two_lobe_from_cosines`.

    Returns
    -------
    (...) array
        ρ in sr⁻¹.
    """
    xp, (normal, light, view), _ = prepare((normal, light, view))
    return two_lobe_from_cosines(
        *cosines(xp, normal, light, view), rd=rd, rb=rb, ab=ab, fb=fb, rn=rn, mn=mn, fn=fn
    )
