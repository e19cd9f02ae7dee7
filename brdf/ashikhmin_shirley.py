"""Anisotropic Phong reflectance of Ashikhmin & Shirley (2000).

As used for space objects by Wetterer & Jah and Linares et al.: ``ρ = ρ_d + ρ_s`` for
``n·L > 0`` and ``n·V > 0``, else 0, with

* ``ρ_d = 28 rd/(23π) (1 − rs) (1 − (1 − NL/2)⁵)(1 − (1 − NV/2)⁵)``,
* ``ρ_s = √((nu + 1)(nv + 1))/(8π) · NH^e / (VH · max(NL, NV)) · F``,
  ``e = (nu (H·u)² + nv (H·v)²)/(1 − NH²)``, ``F = rs + (1 − rs)(1 − VH)⁵``,

where ``u``, ``v`` are the facet tangent directions (the material reference direction projected
on the facet, and ``n × u``). Since ``(H·u)² + (H·v)² = 1 − NH²`` for a unit half vector, the
exponent is evaluated as ``(nu hu² + nv hv²)/(hu² + hv²)``: a weighted mean of ``nu`` and ``nv``
that stays finite at ``H = n``. With ``nu = nv`` it is ``nu`` whatever the tangent frame.
Both terms are symmetric in ``L`` and ``V`` (reciprocal).
"""

from __future__ import annotations

from typing import Any

from brdf._array import prepare
from brdf._geometry import COSINE_FLOOR, cosines, half_vector, tangent_cosines, visibility
from brdf._microfacet import schlick

__all__ = ["ashikhmin_shirley", "ashikhmin_shirley_from_cosines"]

_DIFFUSE = 28.0 / (23.0 * 3.141592653589793)
_INV_8PI = 1.0 / (8.0 * 3.141592653589793)
_TINY = 1e-30


def _one_minus_fifth_power(x: Any) -> Any:
    """``1 − (1 − x/2)⁵`` by multiplications (no ``pow``)."""
    q = 1.0 - 0.5 * x
    q2 = q * q
    return 1.0 - q2 * q2 * q


def ashikhmin_shirley_from_cosines(
    nl: Any,
    nview: Any,
    lv: Any,
    /,
    *,
    rd: Any,
    rs: Any,
    nu: Any,
    nv: Any,
    hu: Any = None,
    hv: Any = None,
) -> Any:
    """Ashikhmin–Shirley BRDF from the cosines ``n·L``, ``n·V``, ``L·V`` (and ``H·u``, ``H·v``).

    Parameters
    ----------
    nl, nview : (..., F) arrays
        ``n·L`` and ``n·V`` (positional: the exponent parameter is also called ``nv``).
    lv : array
        ``L·V``, broadcastable (e.g. ``(..., 1)`` per epoch).
    rd : float or array
        Diffuse albedo in [0, 1].
    rs : float or array
        Specular reflectance at normal incidence (Fresnel ``F(VH = 1)``), in [0, 1].
    nu, nv : float or array
        Phong-like exponents along the tangent directions ``u`` and ``v`` (≥ 0).
    hu, hv : (..., F) arrays, optional
        ``H·u`` and ``H·v``. Without them the lobe is isotropic with exponent ``nu`` (exact
        when ``nu = nv``; `brdf.get` refuses anisotropic parameters without a tangent frame).

    Returns
    -------
    array
        ρ in sr⁻¹, zero where ``nl ≤ 0`` or ``nview ≤ 0``.
    """
    xp, (nl, nview, lv, hu, hv), (rd, rs, nu, nv) = prepare(
        (nl, nview, lv, hu, hv), (rd, rs, nu, nv)
    )
    visible, _ = visibility(xp, nl, nview)
    vh, nh = half_vector(xp, nl, nview, lv)
    if hu is None or hv is None:
        exponent = nu
    else:
        hu2 = hu * hu
        hv2 = hv * hv
        exponent = (nu * hu2 + nv * hv2) / xp.clip(hu2 + hv2, _TINY, None)
    fresnel = schlick(rs, vh)
    specular_weight = ((nu + 1.0) * (nv + 1.0)) ** 0.5 * _INV_8PI * fresnel / vh
    specular = specular_weight * nh**exponent / xp.clip(xp.maximum(nl, nview), COSINE_FLOOR, None)
    diffuse = (_DIFFUSE * rd * (1.0 - rs)) * (
        _one_minus_fifth_power(nl) * _one_minus_fifth_power(nview)
    )
    return (diffuse + specular) * visible


def ashikhmin_shirley(
    normal: Any,
    light: Any,
    view: Any,
    *,
    rd: Any,
    rs: Any,
    nu: Any,
    nv: Any,
    tangent: Any = None,
) -> Any:
    """Ashikhmin–Shirley BRDF of unit direction vectors.

    Parameters
    ----------
    normal, light, view : (..., 3) arrays
        Unit facet normal and unit vectors to the Sun and to the observer (any common frame).
    rd, rs, nu, nv : float or array
        See `ashikhmin_shirley_from_cosines`.
    tangent : (..., 3) array, optional
        Material reference direction (same frame, not parallel to the normal); projected on the
        facet it gives ``u``, and ``v = n × u``. Without it the lobe is isotropic (exponent
        ``nu``).

    Returns
    -------
    (...) array
        ρ in sr⁻¹.
    """
    xp, (normal, light, view, tangent), _ = prepare((normal, light, view, tangent))
    hu = hv = None
    if tangent is not None:
        hu, hv = tangent_cosines(xp, normal, tangent, light, view)
    return ashikhmin_shirley_from_cosines(
        *cosines(xp, normal, light, view), rd=rd, rs=rs, nu=nu, nv=nv, hu=hu, hv=hv
    )
