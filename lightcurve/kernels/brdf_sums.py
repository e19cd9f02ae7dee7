"""Fused facet sums of ``ρ A (n·L)(n·V) · shadow`` for one material block, per BRDF (numba).

Each function sums one contiguous block of facets sharing a material for one row (epoch or
particle): the cosines, the BRDF, the clamps, the area, the optional shadow factor and the
sum are one loop, with no temporary arrays. They evaluate the cosine forms of
:mod:`brdf` (``docs/brdf.md``) with the same clamps and floors, rearranged only where a
factor is constant over the block or the row (tested against :mod:`brdf` and
:mod:`lightcurve.reference` in ``tests/lightcurve/test_kernels.py``):

* Lambert (Lambert 1760): ``ρ = rd/π``;
* Phong, energy-normalised (Phong 1975; Lewis 1994):
  ``ρ = rd/π + rs (n + 2)/(2π) max(0, 2 NL NV − LV)^n``;
* Cook–Torrance (Cook & Torrance 1981, "A reflectance model for computer graphics"): Beckmann
  ``D``, V-cavity ``G``, Schlick ``F``;
* Ashikhmin–Shirley (Ashikhmin & Shirley 2000, "An anisotropic Phong BRDF model"), isotropic
  or with the facet tangent frame;
* Lommel–Seeliger + Lambert with the DAMIT phase function (Kaasalainen & Torppa 2001).

One function per BRDF, ``<brdf>_rows(light, view, facets, start, stop, p, shadow, out)``,
adds the block's sum to ``out[r]`` for every row ``r``: ``light``/``view`` are the (R, 3)
body-frame unit vectors to the Sun and the observer, ``facets`` the (10, K) table of
:func:`lightcurve.kernels.facet_table` (normal, area, tangent ``u``, bitangent ``v``),
``start``/``stop`` the block, ``p`` its parameter row (:func:`lightcurve.kernels.block_parameters`),
``shadow`` the (R, K) shadow factor, or one (1, K) row for every row (ones when there is none:
a multiplication by a cached 1 costs less than a branch, which would keep the loop from being
vectorised). Arithmetic is in the dtype of ``facets``. The BRDFs with specular lobes skip
tiles of facets none of which is both lit and seen (the renderer orders facets by
direction). Each function is compiled (and cached) when a shape first uses its BRDF.
"""

from __future__ import annotations

import math

from numba import njit

from lightcurve.kernels.elementary import exp, log

__all__ = [
    "ANISOTROPIC",
    "ASHIKHMIN_SHIRLEY",
    "COOK_TORRANCE",
    "KINDS",
    "LAMBERT",
    "LOMMEL_SEELIGER",
    "PHONG",
    "ROW_KERNELS",
]

LAMBERT, PHONG, COOK_TORRANCE, ASHIKHMIN_SHIRLEY, ANISOTROPIC, LOMMEL_SEELIGER = range(6)
#: Kernel code of each BRDF registry name (anisotropic Ashikhmin–Shirley gets its own).
KINDS = {
    "lambert": LAMBERT,
    "phong": PHONG,
    "cook-torrance": COOK_TORRANCE,
    "ashikhmin-shirley": ASHIKHMIN_SHIRLEY,
    "lommel-seeliger": LOMMEL_SEELIGER,
}

# Reassociation lets LLVM vectorise the facet sums; the order of a sum then depends on the
# vector width (a relative change of ~1e-16 in float64), never on threads or batch sizes.
_JIT = {
    "fastmath": {"reassoc", "contract", "nsz"},
    "error_model": "numpy",
    "nogil": True,
    "cache": True,
}
_COSINE_FLOOR = 1e-6  # brdf._geometry.COSINE_FLOOR
# Facets per tile of the BRDFs with specular lobes: tiles with no facet both lit and seen are
# skipped. The renderer orders facets by direction within a material, so at a random geometry
# 40 % of a convex body's tiles are evaluated (25 % of its facets are lit and seen). Lambert
# and Lommel–Seeliger cost less per facet than the test and loop over every facet.
_TILE = 16
_SUM_SQUARED_FLOOR = 1e-12  # brdf._geometry._SUM_SQUARED_FLOOR


@njit(**_JIT)
def _row(light, view, shadow, r):
    """The unit vectors of row ``r`` and its shadow factors (one shared row when broadcast)."""
    factor = shadow[r] if shadow.shape[0] == light.shape[0] else shadow[0]
    return light[r, 0], light[r, 1], light[r, 2], view[r, 0], view[r, 1], view[r, 2], factor


@njit(**_JIT)
def _tile_visible(facets, first, last, lx, ly, lz, vx, vy, vz):
    """Whether any facet of ``first:last`` is both lit and seen (``n·L > 0``, ``n·V > 0``)."""
    zero = facets.dtype.type(0.0)
    count = 0
    for i in range(first, last):
        nl = facets[0, i] * lx + facets[1, i] * ly + facets[2, i] * lz
        nv = facets[0, i] * vx + facets[1, i] * vy + facets[2, i] * vz
        count += 1 if (nl > zero and nv > zero) else 0
    return count > 0


@njit(**_JIT)
def _half_vector_row(t, lv):
    """``(1/|L + V|, VH)`` of a row, as ``brdf._geometry.half_vector``."""
    length = math.sqrt(max(t(2.0) + t(2.0) * lv, t(_SUM_SQUARED_FLOOR)))
    return t(1.0) / length, t(0.5) * length


@njit(**_JIT)
def lambert_rows(light, view, facets, start, stop, p, shadow, out):
    t = facets.dtype.type
    for r in range(light.shape[0]):
        lx, ly, lz, vx, vy, vz, factor = _row(light, view, shadow, r)
        zero = t(0.0)
        total = zero
        for i in range(start, stop):
            nl = facets[0, i] * lx + facets[1, i] * ly + facets[2, i] * lz
            nv = facets[0, i] * vx + facets[1, i] * vy + facets[2, i] * vz
            term = facets[3, i] * nl * nv * factor[i]
            total += term if (nl > zero and nv > zero) else zero
        out[r] += p[0] * total


@njit(**_JIT)
def phong_rows(light, view, facets, start, stop, p, shadow, out):
    t = facets.dtype.type
    for r in range(light.shape[0]):
        lx, ly, lz, vx, vy, vz, factor = _row(light, view, shadow, r)
        zero, one = t(0.0), t(1.0)
        lv = lx * vx + ly * vy + lz * vz
        diffuse, specular, exponent = p[0], p[1], p[2]
        at_zero = one if exponent == zero else zero  # 0⁰ = 1, as numpy and torch
        total = zero
        for first in range(start, stop, _TILE):
            last = min(first + _TILE, stop)
            if not _tile_visible(facets, first, last, lx, ly, lz, vx, vy, vz):
                continue
            for i in range(first, last):
                nl = facets[0, i] * lx + facets[1, i] * ly + facets[2, i] * lz
                nv = facets[0, i] * vx + facets[1, i] * vy + facets[2, i] * vz
                mirror = t(2.0) * nl * nv - lv
                lit = mirror > zero
                lobe = exp(exponent * log(mirror if lit else one))
                rho = diffuse + specular * (lobe if lit else at_zero)
                term = rho * facets[3, i] * nl * nv * factor[i]
                total += term if (nl > zero and nv > zero) else zero
        out[r] += total


@njit(**_JIT)
def cook_torrance_rows(light, view, facets, start, stop, p, shadow, out):
    t = facets.dtype.type
    for r in range(light.shape[0]):
        lx, ly, lz, vx, vy, vz, factor = _row(light, view, shadow, r)
        zero, one, floor = t(0.0), t(1.0), t(_COSINE_FLOOR)
        inv_length, vh = _half_vector_row(t, lx * vx + ly * vy + lz * vz)
        q = one - vh
        q2 = q * q
        fresnel = p[3] + (one - p[3]) * (q2 * q2 * q)
        diffuse, specular, inv_m2 = p[0], p[1] * fresnel, p[2]
        two_over_vh = t(2.0) / vh
        total = zero
        for first in range(start, stop, _TILE):
            last = min(first + _TILE, stop)
            if not _tile_visible(facets, first, last, lx, ly, lz, vx, vy, vz):
                continue
            for i in range(first, last):
                nl = facets[0, i] * lx + facets[1, i] * ly + facets[2, i] * lz
                nv = facets[0, i] * vx + facets[1, i] * vy + facets[2, i] * vz
                nh = (nl + nv) * inv_length
                nh = floor if nh < floor else (one if nh > one else nh)
                inv_nh2 = one / (nh * nh)
                distribution = exp((one - inv_nh2) * inv_m2) * (inv_nh2 * inv_nh2)
                low = nl if nl < nv else nv
                low = floor if low < floor else low
                high = nl if nl > nv else nv
                high = floor if high < floor else high
                masking = nh * low * two_over_vh
                masking = one if masking > one else masking
                rho = diffuse + specular * (distribution * masking / (low * high))
                term = rho * facets[3, i] * nl * nv * factor[i]
                total += term if (nl > zero and nv > zero) else zero
        out[r] += total


@njit(**_JIT)
def ashikhmin_shirley_rows(light, view, facets, start, stop, p, shadow, out):
    t = facets.dtype.type
    for r in range(light.shape[0]):
        lx, ly, lz, vx, vy, vz, factor = _row(light, view, shadow, r)
        zero, one, half, floor = t(0.0), t(1.0), t(0.5), t(_COSINE_FLOOR)
        inv_length, vh = _half_vector_row(t, lx * vx + ly * vy + lz * vz)
        q = one - vh
        q2 = q * q
        fresnel = p[2] + (one - p[2]) * (q2 * q2 * q)
        diffuse, specular, exponent = p[0], p[1] * fresnel / vh, p[3]
        total = zero
        for first in range(start, stop, _TILE):
            last = min(first + _TILE, stop)
            if not _tile_visible(facets, first, last, lx, ly, lz, vx, vy, vz):
                continue
            for i in range(first, last):
                nl = facets[0, i] * lx + facets[1, i] * ly + facets[2, i] * lz
                nv = facets[0, i] * vx + facets[1, i] * vy + facets[2, i] * vz
                nh = (nl + nv) * inv_length
                nh = floor if nh < floor else (one if nh > one else nh)
                high = nl if nl > nv else nv
                high = floor if high < floor else high
                a = one - half * nl
                a2 = a * a
                b = one - half * nv
                b2 = b * b
                rho = (
                    diffuse * ((one - a2 * a2 * a) * (one - b2 * b2 * b))
                    + specular * exp(exponent * log(nh)) / high
                )
                term = rho * facets[3, i] * nl * nv * factor[i]
                total += term if (nl > zero and nv > zero) else zero
        out[r] += total


@njit(**_JIT)
def ashikhmin_shirley_anisotropic_rows(light, view, facets, start, stop, p, shadow, out):
    t = facets.dtype.type
    for r in range(light.shape[0]):
        lx, ly, lz, vx, vy, vz, factor = _row(light, view, shadow, r)
        zero, one, half, floor = t(0.0), t(1.0), t(0.5), t(_COSINE_FLOOR)
        lv = lx * vx + ly * vy + lz * vz
        inv_length, vh = _half_vector_row(t, lv)
        # H·u, H·v as the eager renderer forms them: (u·L + u·V)/√max(2 + 2 LV, 1e-30).
        inv_half_norm = one / math.sqrt(max(t(2.0) + t(2.0) * lv, t(1e-30)))
        hx, hy, hz = lx + vx, ly + vy, lz + vz
        q = one - vh
        q2 = q * q
        fresnel = p[2] + (one - p[2]) * (q2 * q2 * q)
        diffuse, specular, exp_u, exp_v = p[0], p[1] * fresnel / vh, p[3], p[4]
        total = zero
        for first in range(start, stop, _TILE):
            last = min(first + _TILE, stop)
            if not _tile_visible(facets, first, last, lx, ly, lz, vx, vy, vz):
                continue
            for i in range(first, last):
                nl = facets[0, i] * lx + facets[1, i] * ly + facets[2, i] * lz
                nv = facets[0, i] * vx + facets[1, i] * vy + facets[2, i] * vz
                hu = (facets[4, i] * hx + facets[5, i] * hy + facets[6, i] * hz) * inv_half_norm
                hv = (facets[7, i] * hx + facets[8, i] * hy + facets[9, i] * hz) * inv_half_norm
                hu2 = hu * hu
                hv2 = hv * hv
                weight = hu2 + hv2
                weight = t(1e-30) if weight < t(1e-30) else weight
                exponent = (exp_u * hu2 + exp_v * hv2) / weight
                nh = (nl + nv) * inv_length
                nh = floor if nh < floor else (one if nh > one else nh)
                high = nl if nl > nv else nv
                high = floor if high < floor else high
                a = one - half * nl
                a2 = a * a
                b = one - half * nv
                b2 = b * b
                rho = (
                    diffuse * ((one - a2 * a2 * a) * (one - b2 * b2 * b))
                    + specular * exp(exponent * log(nh)) / high
                )
                term = rho * facets[3, i] * nl * nv * factor[i]
                total += term if (nl > zero and nv > zero) else zero
        out[r] += total


@njit(**_JIT)
def lommel_seeliger_rows(light, view, facets, start, stop, p, shadow, out):
    t = facets.dtype.type
    for r in range(light.shape[0]):
        lx, ly, lz, vx, vy, vz, factor = _row(light, view, shadow, r)
        zero, one, floor = t(0.0), t(1.0), t(_COSINE_FLOOR)
        lv = lx * vx + ly * vy + lz * vz
        # The DAMIT phase function, once per row: f = max(0, a exp(−α/d) + k α + 1).
        alpha = math.acos(min(max(lv, -one), one))
        phase = p[2] * math.exp(-alpha / p[3]) + p[4] * alpha + one
        scale = p[0] * (phase if phase > zero else zero)
        lambert_weight = p[1]
        total = zero
        for i in range(start, stop):
            nl = facets[0, i] * lx + facets[1, i] * ly + facets[2, i] * lz
            nv = facets[0, i] * vx + facets[1, i] * vy + facets[2, i] * vz
            both = nl + nv
            both = floor if both < floor else both
            term = (one / both + lambert_weight) * facets[3, i] * nl * nv * factor[i]
            total += term if (nl > zero and nv > zero) else zero
        out[r] += scale * total


#: Row kernel of each BRDF code: ``kernel(light, view, facets, start, stop, p, shadow, out)``.
ROW_KERNELS = {
    LAMBERT: lambert_rows,
    PHONG: phong_rows,
    COOK_TORRANCE: cook_torrance_rows,
    ASHIKHMIN_SHIRLEY: ashikhmin_shirley_rows,
    ANISOTROPIC: ashikhmin_shirley_anisotropic_rows,
    LOMMEL_SEELIGER: lommel_seeliger_rows,
}
