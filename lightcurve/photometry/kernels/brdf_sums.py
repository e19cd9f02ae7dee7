"""Fused facet sums of ``ρ A (n·L)(n·V) · shadow`` for one material block, per BRDF (numba).

Each kernel sums one material block for a range of rows (epochs, particles or sigma points):
the cosines, the BRDF, the clamps, the area, the optional shadow factor and the sum, with no
(rows × facets) array. They evaluate the cosine forms of :mod:`brdf` (``docs/brdf.md``)
with the same clamps and floors, rearranged only where a factor is constant over a row or
where an algebraic identity removes a division (tested against :mod:`brdf` and
:mod:`lightcurve.photometry.reference` in ``tests/lightcurve/photometry/test_kernels.py``):

* Lambert (Lambert 1760): ``ρ = rd/π``;
* Phong, energy-normalised (Phong 1975; Lewis 1994):
  ``ρ = rd/π + rs (n + 2)/(2π) max(0, 2 NL NV − LV)^n``;
* Cook–Torrance (Cook & Torrance 1981, "A reflectance model for computer graphics"): Beckmann
  ``D``, V-cavity ``G``, Schlick ``F``; ``NL NV/(max(low, ε) max(high, ε)) =
  min(1, NL/ε) min(1, NV/ε)`` for the lit and seen facets;
* Ashikhmin–Shirley (Ashikhmin & Shirley 2000, "An anisotropic Phong BRDF model"), isotropic
  or with the facet tangent frame; ``NL NV/max(NL, NV, ε) = min(NL, NV) min(1, max(NL, NV)/ε)``;
* Lommel–Seeliger + Lambert with the DAMIT phase function (Kaasalainen & Torppa 2001);
* two lobes (:mod:`brdf.two_lobe`): Cook–Torrance's terms for the narrow Beckmann lobe
  plus a broad Trowbridge–Reitz lobe (Trowbridge & Reitz 1975), which has no ``exp`` and is
  summed with the diffuse term.

Every kernel has the signature ``kernel(light, view, facets, cones, first, last, p, shadow,
out, start, stop)`` and adds the block's sum to ``out[r]`` for the rows ``start ≤ r < stop``:
``light``/``view`` are the (R, 3) float64 body-frame unit vectors to the Sun and the observer
(row constants such as ``L·V`` and the Fresnel factor are formed in float64), ``facets`` the
(10, S) table of :func:`lightcurve.photometry.kernels.facet_table` in tile layout (normal, area,
tangent ``u``, bitangent ``v``; :mod:`lightcurve.photometry.kernels.tiles`), ``cones`` the (4, S/8)
cone of each tile, ``first``/``last`` the block's tiles, ``p`` its float64 parameter row
(:func:`lightcurve.photometry.kernels.block_parameters`), ``shadow`` the (R, S) shadow factor or
``None`` (a separate compilation: no multiplication by one), ``out`` float64. Arithmetic is
in the dtype of ``facets``.

Lambert loops over every facet: the tile test and its runs cost about as much as the part
of Lambert's loop they would skip. The other kernels skip the tiles with no facet both lit
and seen (:mod:`lightcurve.photometry.kernels.tiles`; about 35 % of 1280 facets and 28 % of 20 480
are evaluated at random geometry on a convex body): two dot products per tile against its
cone, in the compute dtype over contiguous cone arrays so that the test runs on vectors,
then the runs of visible tiles (together about 0.6 of a Lambert row on 1280 facets; 1.6
with the float64 cones indexed per tile).
Lommel–Seeliger sums each run in one loop. The specular kernels evaluate a row in three
loops: over the runs, everything but the lobe (the diffuse sum, and
per facet the lobe's weight and base), then ``base ← e log₂(base)``, then
``Σ weight · 2^power``. With 16 vector registers and numba's large code model (every
constant reloaded by two instructions when registers run out), one loop holding the whole
formula runs 1.5× slower per facet than the three (measured), and the per-tile form (eight
facets in a fixed-length inner loop) is unrolled by LLVM into scalar code. Each kernel is
compiled (and cached on disk) when a shape first uses its BRDF.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from lightcurve.photometry.kernels.elementary import exp2_normal, log2, log2_normal
from lightcurve.photometry.kernels.tiles import TILE

__all__ = [
    "ANISOTROPIC",
    "ASHIKHMIN_SHIRLEY",
    "COOK_TORRANCE",
    "KINDS",
    "LAMBERT",
    "LOMMEL_SEELIGER",
    "PHONG",
    "ROW_KERNELS",
    "TWO_LOBE",
]

LAMBERT, PHONG, COOK_TORRANCE, ASHIKHMIN_SHIRLEY, ANISOTROPIC, LOMMEL_SEELIGER, TWO_LOBE = range(7)
#: Kernel code of each BRDF registry name (anisotropic Ashikhmin–Shirley gets its own).
KINDS = {
    "lambert": LAMBERT,
    "phong": PHONG,
    "cook-torrance": COOK_TORRANCE,
    "ashikhmin-shirley": ASHIKHMIN_SHIRLEY,
    "lommel-seeliger": LOMMEL_SEELIGER,
    "two-lobe": TWO_LOBE,
}

# Reassociation lets LLVM vectorise the facet sums; the order of a sum then depends on the
# vector width (a relative change of ~1e-16 in float64), never on threads or batch sizes.
_JIT = {
    "fastmath": {"reassoc", "contract", "nsz"},
    "error_model": "numpy",
    "nogil": True,
    "cache": True,
}
# The per-facet formulas, inlined into the kernels, without reassociation: it would turn the
# multiplications by row constants such as 1/|L + V| back into divisions inside the loops.
_FORMULA = {
    "fastmath": {"contract", "nsz"},
    "error_model": "numpy",
    "nogil": True,
    "forceinline": True,
}
_COSINE_FLOOR = 1e-6  # brdf._geometry.COSINE_FLOOR
_INV_COSINE_FLOOR = 1e6
_SUM_SQUARED_FLOOR = 1e-12  # brdf._geometry._SUM_SQUARED_FLOOR
_LOG2_E = 1.4426950408889634
_TILE = np.uint64(TILE)
_TWO = np.uint64(2)


# ------------------------------------------------------------------ shared pieces
@njit(**_FORMULA)
def _directions(light, view, r, t):
    """Row ``r``'s unit vectors in the compute dtype ``t`` and ``L·V`` in float64."""
    lx, ly, lz = light[r, 0], light[r, 1], light[r, 2]
    vx, vy, vz = view[r, 0], view[r, 1], view[r, 2]
    lv = lx * vx + ly * vy + lz * vz
    return t(lx), t(ly), t(lz), t(vx), t(vy), t(vz), lv


@njit(**_FORMULA)
def _half_vector_row(lv):
    """``(1/|L + V|, VH, Fresnel base 1 − VH)`` of a row in float64, as
    ``brdf._geometry.half_vector``."""
    length = math.sqrt(max(2.0 + 2.0 * lv, _SUM_SQUARED_FLOOR))
    vh = 0.5 * length
    return 1.0 / length, vh, 1.0 - vh


@njit(**_FORMULA)
def _schlick(f0, q):
    """``f0 + (1 − f0) q⁵`` (Schlick's Fresnel factor, ``q = 1 − VH``)."""
    q2 = q * q
    return f0 + (1.0 - f0) * (q2 * q2 * q)


@njit(**_FORMULA)
def _cosines(facets, i, lx, ly, lz, vx, vy, vz):
    nl = facets[0, i] * lx + facets[1, i] * ly + facets[2, i] * lz
    nv = facets[0, i] * vx + facets[1, i] * vy + facets[2, i] * vz
    return nl, nv


@njit(**_FORMULA)
def _one_minus_fifth_power(x):
    """``1 − (1 − x/2)⁵`` (the Ashikhmin–Shirley diffuse factor)."""
    t = type(x)
    a = t(1.0) - t(0.5) * x
    a2 = a * a
    return t(1.0) - a2 * a2 * a


@njit(**_JIT)
def _visible_runs(axis_x, axis_y, axis_z, sine, light, view, r, flags, runs):
    """Runs of consecutive tiles that may hold a facet both lit and seen.

    ``axis_*`` and ``sine`` are the cones of a block's tiles in the compute dtype,
    contiguous, so that the test runs on vectors. Fills ``runs[2q], runs[2q + 1]`` with the
    first and last (exclusive) tile of run ``q`` and returns the number of runs.
    """
    t = sine.dtype.type
    lx, ly, lz = t(light[r, 0]), t(light[r, 1]), t(light[r, 2])
    vx, vy, vz = t(view[r, 0]), t(view[r, 1]), t(view[r, 2])
    count = len(sine)
    for k in range(count):
        al = axis_x[k] * lx + axis_y[k] * ly + axis_z[k] * lz
        av = axis_x[k] * vx + axis_y[k] * vy + axis_z[k] * vz
        flags[k] = np.uint32((al >= -sine[k]) & (av >= -sine[k]))
    edges = np.uint64(0)
    previous = np.uint32(0)
    for k in range(count):  # an edge wherever the flag changes: run starts and stops
        runs[edges] = np.uint32(k)
        edges += np.uint64(flags[k] ^ previous)
        previous = flags[k]
    runs[edges] = np.uint32(count)
    edges += np.uint64(previous)
    return edges // np.uint64(2)


@njit(**_JIT)
def _log_in_place(base, count, exponent):
    """``base[j] ← exponent · log₂ base[j]`` for ``j < count`` (``base`` normal, > 0)."""
    for j in range(count):
        base[j] = exponent * log2_normal(base[j])


@njit(**_JIT)
def _log_in_place_each(base, count, exponents):
    """``base[j] ← exponents[j] · log₂ base[j]`` for ``j < count``."""
    for j in range(count):
        base[j] = exponents[j] * log2_normal(base[j])


@njit(**_JIT)
def _lobe_sum(weight, power, count):
    """``Σ_j weight[j] · 2^power[j]`` over ``j < count``."""
    total = weight.dtype.type(0.0)
    for j in range(count):
        total += weight[j] * exp2_normal(power[j])
    return total


# ------------------------------------------------------------------ per-facet formulas
# Each returns (diffuse term, lobe weight, lobe base or power, exponent) of facet i, already
# masked to zero where the facet is not both lit and seen; the lobe is weight · base^exponent
# (Phong, Ashikhmin–Shirley) or weight · 2^power (Cook–Torrance).
@njit(**_FORMULA)
def _phong_facet(facets, i, c):
    lx, ly, lz, vx, vy, vz = c[0], c[1], c[2], c[3], c[4], c[5]
    lv, diffuse, specular, at_zero = c[6], c[7], c[8], c[10]
    t = type(lx)
    zero, one = t(0.0), t(1.0)
    nl, nv = _cosines(facets, i, lx, ly, lz, vx, vy, vz)
    projected = facets[3, i] * nl * nv
    mirror = t(2.0) * nl * nv - lv
    lit = nl > zero and nv > zero
    weight = specular * projected * (one if mirror > zero else at_zero)  # 0⁰ = 1 as numpy
    return (
        diffuse * projected if lit else zero,
        weight if lit else zero,
        mirror if mirror > zero else one,
        zero,
    )


@njit(**_FORMULA)
def _microfacet_parts(facets, i, c):
    """Cosines, ``NH``, ``1/NH²``, the V-cavity ``G`` and ``NL NV/(max(low, ε) max(high, ε))``
    of a microfacet facet (unmasked)."""
    lx, ly, lz, vx, vy, vz = c[0], c[1], c[2], c[3], c[4], c[5]
    inv_length, two_over_vh = c[6], c[10]
    t = type(lx)
    one, floor, inv_floor = t(1.0), t(_COSINE_FLOOR), t(_INV_COSINE_FLOOR)
    nl, nv = _cosines(facets, i, lx, ly, lz, vx, vy, vz)
    nh = (nl + nv) * inv_length
    nh = floor if nh < floor else (one if nh > one else nh)
    inv_nh2 = one / (nh * nh)
    low = nl if nl < nv else nv
    low = floor if low < floor else low
    masking = nh * low * two_over_vh
    masking = one if masking > one else masking
    ratio_l = nl * inv_floor
    ratio_v = nv * inv_floor
    ratio = (one if ratio_l > one else ratio_l) * (one if ratio_v > one else ratio_v)
    return nl, nv, nh, inv_nh2, masking, ratio


@njit(**_FORMULA)
def _cook_torrance_facet(facets, i, c):
    diffuse, specular, power_scale = c[7], c[8], c[9]
    zero, one = type(c[0])(0.0), type(c[0])(1.0)
    nl, nv, _, inv_nh2, masking, ratio = _microfacet_parts(facets, i, c)
    lit = nl > zero and nv > zero
    area = facets[3, i]
    weight = area * specular * masking * ratio * (inv_nh2 * inv_nh2)
    return (
        area * diffuse * nl * nv if lit else zero,
        weight if lit else zero,
        (one - inv_nh2) * power_scale,
        zero,
    )


@njit(**_FORMULA)
def _two_lobe_facet(facets, i, c):
    """Cook–Torrance's terms with the Beckmann (narrow) lobe, plus the Trowbridge–Reitz
    (broad) lobe, a rational function of ``NH``, in the diffuse term."""
    diffuse, specular, power_scale, broad, alpha2 = c[7], c[8], c[9], c[11], c[12]
    zero, one = type(c[0])(0.0), type(c[0])(1.0)
    nl, nv, nh, inv_nh2, masking, ratio = _microfacet_parts(facets, i, c)
    lit = nl > zero and nv > zero
    area = facets[3, i]
    shadowing = masking * ratio
    nh2 = nh * nh
    denominator = (one - nh2) + alpha2 * nh2
    weight = area * specular * shadowing * (inv_nh2 * inv_nh2)
    flat = area * (diffuse * nl * nv + broad * shadowing / (denominator * denominator))
    return flat if lit else zero, weight if lit else zero, (one - inv_nh2) * power_scale, zero


@njit(**_FORMULA)
def _ashikhmin_shirley_weights(facets, i, nl, nv, inv_length, diffuse, specular):
    """Diffuse term, lobe weight and ``NH`` of an Ashikhmin–Shirley facet (unmasked)."""
    t = type(nl)
    one, floor, inv_floor = t(1.0), t(_COSINE_FLOOR), t(_INV_COSINE_FLOOR)
    nh = (nl + nv) * inv_length
    nh = floor if nh < floor else (one if nh > one else nh)
    low = nl if nl < nv else nv
    high = nl if nl > nv else nv
    scale = high * inv_floor
    scale = one if scale > one else scale
    area = facets[3, i]
    fresnel_free = _one_minus_fifth_power(nl) * _one_minus_fifth_power(nv)
    return area * (diffuse * nl * nv) * fresnel_free, area * specular * low * scale, nh


@njit(**_FORMULA)
def _ashikhmin_shirley_facet(facets, i, c):
    lx, ly, lz, vx, vy, vz = c[0], c[1], c[2], c[3], c[4], c[5]
    inv_length, diffuse, specular, exponent = c[6], c[7], c[8], c[9]
    t = type(lx)
    zero = t(0.0)
    nl, nv = _cosines(facets, i, lx, ly, lz, vx, vy, vz)
    d, w, nh = _ashikhmin_shirley_weights(facets, i, nl, nv, inv_length, diffuse, specular)
    lit = nl > zero and nv > zero
    return d if lit else zero, w if lit else zero, nh, exponent


@njit(**_FORMULA)
def _anisotropic_facet(facets, i, c):
    lx, ly, lz, vx, vy, vz = c[0], c[1], c[2], c[3], c[4], c[5]
    inv_length, diffuse, specular, exp_u, exp_v = c[6], c[7], c[8], c[9], c[10]
    hx, hy, hz = c[11], c[12], c[13]
    t = type(lx)
    zero, tiny = t(0.0), t(1e-30)
    nl, nv = _cosines(facets, i, lx, ly, lz, vx, vy, vz)
    d, w, nh = _ashikhmin_shirley_weights(facets, i, nl, nv, inv_length, diffuse, specular)
    # H·u, H·v with H = (L + V)/√max(2 + 2 LV, 1e-30), as the eager renderer forms them.
    hu = facets[4, i] * hx + facets[5, i] * hy + facets[6, i] * hz
    hv = facets[7, i] * hx + facets[8, i] * hy + facets[9, i] * hz
    hu2 = hu * hu
    hv2 = hv * hv
    norm = hu2 + hv2
    norm = tiny if norm < tiny else norm
    lit = nl > zero and nv > zero
    return d if lit else zero, w if lit else zero, nh, (exp_u * hu2 + exp_v * hv2) / norm


@njit(**_FORMULA)
def _row_constants(kind, p, light, view, r, t):
    """Per-row constants of a specular BRDF in the compute dtype ``t``: a 14-tuple
    ``(Lx, Ly, Lz, Vx, Vy, Vz, c6, …, c13)`` whose tail each facet formula reads by index
    (formed in float64)."""
    lx, ly, lz, vx, vy, vz, lv = _directions(light, view, r, t)
    zero = t(0.0)
    if kind == PHONG:  # LV, rd/π, rs (n + 2)/2π, n, 0⁰
        at_zero = 1.0 if p[2] == 0.0 else 0.0
        return (
            lx, ly, lz, vx, vy, vz, t(lv), t(p[0]), t(p[1]), t(p[2]), t(at_zero),
            zero, zero, zero,
        )  # fmt: skip
    inv_length, vh, q = _half_vector_row(lv)
    if kind in (COOK_TORRANCE, TWO_LOBE):
        # 1/|L+V|, rd/π, rs F/(4π m²), log₂e/m², 2/VH; two lobes: rb α² F/4π, α²
        specular = p[1] * _schlick(p[3], q)
        broad = p[4] * _schlick(p[6], q) if kind == TWO_LOBE else 0.0
        return (
            lx, ly, lz, vx, vy, vz, t(inv_length), t(p[0]), t(specular), t(p[2] * _LOG2_E),
            t(2.0 / vh), t(broad), t(p[5]), zero,
        )  # fmt: skip
    # Ashikhmin–Shirley: 1/|L+V|, diffuse, √((nu+1)(nv+1))/8π F/VH, nu, nv, H/√max(2+2LV, 1e-30)
    specular = p[1] * _schlick(p[2], q) / vh
    inv_half_norm = 1.0 / math.sqrt(max(2.0 + 2.0 * lv, 1e-30))
    hx = (light[r, 0] + view[r, 0]) * inv_half_norm
    hy = (light[r, 1] + view[r, 1]) * inv_half_norm
    hz = (light[r, 2] + view[r, 2]) * inv_half_norm
    return (
        lx, ly, lz, vx, vy, vz, t(inv_length), t(p[0]), t(specular), t(p[3]), t(p[4]),
        t(hx), t(hy), t(hz),
    )  # fmt: skip


# ------------------------------------------------------------------ kernels
@njit(**_JIT)
def lambert_rows(light, view, facets, cones, first, last, p, shadow, out, start, stop):
    t = facets.dtype.type
    zero = t(0.0)
    lo, hi = first * TILE, last * TILE
    nx, ny, nz, area = facets[0, lo:hi], facets[1, lo:hi], facets[2, lo:hi], facets[3, lo:hi]
    for r in range(start, stop):
        lx, ly, lz, vx, vy, vz, _ = _directions(light, view, r, t)
        total = zero
        if shadow is None:
            for i in range(hi - lo):
                nl = nx[i] * lx + ny[i] * ly + nz[i] * lz
                nv = nx[i] * vx + ny[i] * vy + nz[i] * vz
                term = area[i] * nl * nv
                total += term if (nl > zero and nv > zero) else zero
        else:
            factor = shadow[r, lo:hi]
            for i in range(hi - lo):
                nl = nx[i] * lx + ny[i] * ly + nz[i] * lz
                nv = nx[i] * vx + ny[i] * vy + nz[i] * vz
                term = area[i] * nl * nv * factor[i]
                total += term if (nl > zero and nv > zero) else zero
        out[r] += p[0] * total


@njit(**_FORMULA)
def _lommel_seeliger_term(nx, ny, nz, area, lx, ly, lz, vx, vy, vz, lambert_weight):
    t = type(nx)
    zero, floor = t(0.0), t(_COSINE_FLOOR)
    nl = nx * lx + ny * ly + nz * lz
    nv = nx * vx + ny * vy + nz * vz
    both = nl + nv
    both = floor if both < floor else both
    term = (t(1.0) / both + lambert_weight) * area * nl * nv
    return term if (nl > zero and nv > zero) else zero


@njit(**_JIT)
def lommel_seeliger_rows(light, view, facets, cones, first, last, p, shadow, out, start, stop):
    t = facets.dtype.type
    nx, ny, nz, area = facets[0], facets[1], facets[2], facets[3]
    weight = t(p[1])
    flags = np.empty(last - first, dtype=np.uint32)
    runs = np.empty(last - first + 2, dtype=np.uint32)
    offset = np.uint64(first) * _TILE
    axis_x, axis_y, axis_z = cones[0, first:last], cones[1, first:last], cones[2, first:last]
    sine = cones[3, first:last]
    for r in range(start, stop):
        lx, ly, lz, vx, vy, vz, lv = _directions(light, view, r, t)
        # The DAMIT phase function, once per row: f = max(0, a exp(−α/d) + k α + 1).
        alpha = math.acos(min(max(lv, -1.0), 1.0))
        phase = p[2] * math.exp(-alpha / p[3]) + p[4] * alpha + 1.0
        total = t(0.0)
        for q in range(_visible_runs(axis_x, axis_y, axis_z, sine, light, view, r, flags, runs)):
            lo = offset + np.uint64(runs[_TWO * q]) * _TILE
            hi = offset + np.uint64(runs[_TWO * q + np.uint64(1)]) * _TILE
            if shadow is None:
                for i in range(lo, hi):
                    total += _lommel_seeliger_term(
                        nx[i], ny[i], nz[i], area[i], lx, ly, lz, vx, vy, vz, weight
                    )
            else:
                for i in range(lo, hi):
                    total += shadow[r, i] * _lommel_seeliger_term(
                        nx[i], ny[i], nz[i], area[i], lx, ly, lz, vx, vy, vz, weight
                    )
        out[r] += p[0] * max(phase, 0.0) * total


@njit(**(_JIT | {"forceinline": True, "cache": False}))
def _specular_rows(kind, light, view, facets, cones, first, last, p, shadow, out, start, stop):
    """The specular kernels' row loop (inlined into each with a constant ``kind``)."""
    t = facets.dtype.type
    zero = t(0.0)
    tiles = last - first
    flags = np.empty(tiles, dtype=np.uint32)
    runs = np.empty(tiles + 2, dtype=np.uint32)
    weight = np.empty(tiles * TILE, dtype=t)
    base = np.empty(tiles * TILE, dtype=t)
    exponents = np.empty(tiles * TILE if kind == ANISOTROPIC else 0, dtype=t)
    offset = np.uint64(first) * _TILE
    axis_x, axis_y, axis_z = cones[0, first:last], cones[1, first:last], cones[2, first:last]
    sine = cones[3, first:last]
    for r in range(start, stop):
        c = _row_constants(kind, p, light, view, r, t)
        diffuse = zero
        count = np.uint64(0)
        for q in range(_visible_runs(axis_x, axis_y, axis_z, sine, light, view, r, flags, runs)):
            lo = offset + np.uint64(runs[_TWO * q]) * _TILE
            size = np.uint64(runs[_TWO * q + np.uint64(1)]) * _TILE - (lo - offset)
            for j in range(size):
                i = lo + j
                if kind == PHONG:
                    d, w, b, e = _phong_facet(facets, i, c)
                elif kind == COOK_TORRANCE:
                    d, w, b, e = _cook_torrance_facet(facets, i, c)
                elif kind == TWO_LOBE:
                    d, w, b, e = _two_lobe_facet(facets, i, c)
                elif kind == ASHIKHMIN_SHIRLEY:
                    d, w, b, e = _ashikhmin_shirley_facet(facets, i, c)
                else:
                    d, w, b, e = _anisotropic_facet(facets, i, c)
                if shadow is not None:
                    d *= shadow[r, i]
                    w *= shadow[r, i]
                diffuse += d
                weight[count + j] = w
                base[count + j] = b
                if kind == ANISOTROPIC:
                    exponents[count + j] = e
            count += size
        if kind == PHONG:
            for j in range(count):  # the mirror cosine may be subnormal
                base[j] = c[9] * log2(base[j])
        elif kind == ASHIKHMIN_SHIRLEY:
            _log_in_place(base, count, c[9])
        elif kind == ANISOTROPIC:
            _log_in_place_each(base, count, exponents)
        out[r] += diffuse + _lobe_sum(weight, base, count)


@njit(**_JIT)
def phong_rows(light, view, facets, cones, first, last, p, shadow, out, start, stop):
    _specular_rows(PHONG, light, view, facets, cones, first, last, p, shadow, out, start, stop)


@njit(**_JIT)
def cook_torrance_rows(light, view, facets, cones, first, last, p, shadow, out, start, stop):
    _specular_rows(
        COOK_TORRANCE, light, view, facets, cones, first, last, p, shadow, out, start, stop
    )


@njit(**_JIT)
def ashikhmin_shirley_rows(light, view, facets, cones, first, last, p, shadow, out, start, stop):
    _specular_rows(
        ASHIKHMIN_SHIRLEY, light, view, facets, cones, first, last, p, shadow, out, start, stop
    )


@njit(**_JIT)
def ashikhmin_shirley_anisotropic_rows(
    light, view, facets, cones, first, last, p, shadow, out, start, stop
):
    _specular_rows(
        ANISOTROPIC, light, view, facets, cones, first, last, p, shadow, out, start, stop
    )


@njit(**_JIT)
def two_lobe_rows(light, view, facets, cones, first, last, p, shadow, out, start, stop):
    _specular_rows(TWO_LOBE, light, view, facets, cones, first, last, p, shadow, out, start, stop)


#: Kernel of each BRDF code (signature in the module docstring).
ROW_KERNELS = {
    LAMBERT: lambert_rows,
    PHONG: phong_rows,
    COOK_TORRANCE: cook_torrance_rows,
    ASHIKHMIN_SHIRLEY: ashikhmin_shirley_rows,
    ANISOTROPIC: ashikhmin_shirley_anisotropic_rows,
    LOMMEL_SEELIGER: lommel_seeliger_rows,
    TWO_LOBE: two_lobe_rows,
}
