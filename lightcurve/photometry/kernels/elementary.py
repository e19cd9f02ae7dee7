"""Exponentials and logarithms that LLVM vectorises, for the numba rendering kernels.

Numba compiles ``math.exp``/``math.log`` to calls into the C math library, which keep a loop
scalar (the PyPI builds of llvmlite carry no vector math library). The specular lobes need
``x**y = 2^(y log₂ x)`` for every facet and epoch, so these functions are written with
arithmetic and bit operations only (the bit operations as LLVM IR: numba would widen 32-bit
integer arithmetic to 64 bits); the kernels' facet loops then run on AVX/NEON vectors.

Algorithms (Cephes: Moshier 1989, *Methods and Programs for Mathematical Functions*; fdlibm:
Sun Microsystems 1993):

* float32 ``log``/``log2``: ``x = 2^k m``, ``m ∈ [√½, √2)``, ``ln(1 + f) = f − f²/2 + f³ P(f)``
  with Cephes' degree-8 ``P`` (``logf.c``, ``log2f.c``), evaluated by Estrin's scheme;
  no division.
* float64 ``log``/``log2``: fdlibm ``e_log.c``/``e_log2.c`` (``ln m = 2 atanh s``,
  ``s = f/(2 + f)``, one division).
* ``exp2``: ``2^y = 2^k 2^r``, ``k = round(y)``, ``|r| ≤ ½``, ``2^r`` by a polynomial (Cephes'
  degree 6 in float32; a degree-11 Chebyshev fit in float64); ``exp``: Cody–Waite reduction
  ``x = k ln 2 + r`` (``ln 2`` in two parts), ``e^r`` by a polynomial (Cephes' degree 7 in
  float32; a degree-11 Chebyshev fit in float64). No division.

One source serves both dtypes: the per-dtype algorithms (the polynomials and the ``log`` of
``2^k (1 + f)``) and limits form a ``_Precision`` record, from which ``_functions`` compiles
the six functions once per dtype; ``overload`` picks the set by the argument's type.

Accuracy (measured against numpy in extended precision,
``tests/lightcurve/photometry/test_kernels.py``): at most 1.3 ulp in float32 and float64,
subnormal inputs and results included. Domains: ``log``/``log2`` take finite ``x > 0``;
``exp``/``exp2`` return 0 below the subnormal range and ``inf`` above the largest finite number.

The kernels use two cheaper forms on their own domains: :func:`log2_normal` (normal
``x > 0``: no subnormal rescaling) and :func:`exp2_normal` (``y ≤ 127`` in float32,
``y ≤ 1023`` in float64; 0 where ``2^y`` is below the smallest normal number, 2⁻¹²⁶ ≈
1.2·10⁻³⁸ in float32 and 2⁻¹⁰²² in float64 — a specular lobe that small changes no sum that
holds a normal-sized term, while subnormal arithmetic costs x86 cores ~100 cycles per
operation).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core.registry import CPUDispatcher as Dispatcher
from numba.extending import intrinsic, overload

__all__ = ["exp", "exp2", "exp2_normal", "log", "log2", "log2_normal"]

# No reassociation here: the range reductions and the hi/lo sums rely on the order of their
# operations. The kernels that inline these functions keep these flags on these operations.
_FLAGS = {"contract"}
_JIT = {"fastmath": _FLAGS, "error_model": "numpy", "nogil": True}


class _Layout(NamedTuple):
    """Bits of a float32 or float64 as LLVM sees them."""

    float_type: ir.Type
    int_type: ir.IntType
    shift: int  # mantissa bits
    offset: int  # the bits of √½
    mask: int  # mantissa mask
    bias: int  # exponent bias

    @classmethod
    def of(cls, float_type: types.Float) -> _Layout:
        if float_type == types.float32:
            return cls(ir.FloatType(), ir.IntType(32), 23, 0x3F3504F3, 0x007FFFFF, 127)
        return cls(ir.DoubleType(), ir.IntType(64), 52, 0x3FE6A09E667F3BCD, (1 << 52) - 1, 1023)


def _bitwise(build):
    """An intrinsic ``f(x)`` of a float32/float64 ``x``, same type out, whose LLVM IR is
    ``build(builder, layout, x)``."""

    def typer(typingctx, x):
        def codegen(context, builder, sig, args):
            return build(builder, _Layout.of(sig.args[0]), args[0])

        return x(x), codegen

    typer.__name__ = typer.__qualname__ = build.__name__
    typer.__doc__ = build.__doc__
    return intrinsic(typer)


def _constant(layout: _Layout, value: int) -> ir.Constant:
    return ir.Constant(layout.int_type, value)


@_bitwise
def _exponent(builder, layout, x):
    """``k`` (as a float) of a normal ``x > 0`` written ``2^k m`` with ``m ∈ [√½, √2)``."""
    bits = builder.sub(builder.bitcast(x, layout.int_type), _constant(layout, layout.offset))
    k = builder.ashr(bits, _constant(layout, layout.shift))
    if layout.int_type.width == 64:  # AVX2 converts int32, not int64, vectors to double
        k = builder.trunc(k, ir.IntType(32))
    return builder.sitofp(k, layout.float_type)


@_bitwise
def _mantissa(builder, layout, x):
    """``m ∈ [√½, √2)`` of a normal ``x > 0`` written ``2^k m``."""
    bits = builder.sub(builder.bitcast(x, layout.int_type), _constant(layout, layout.offset))
    m = builder.and_(bits, _constant(layout, layout.mask))
    return builder.bitcast(builder.add(m, _constant(layout, layout.offset)), layout.float_type)


@_bitwise
def _power_of_two(builder, layout, k):
    """``2^k`` for an integral float ``k`` in the normal exponent range."""
    ki = builder.fptosi(k, ir.IntType(32))
    if layout.int_type.width == 64:
        ki = builder.sext(ki, layout.int_type)
    biased = builder.add(ki, _constant(layout, layout.bias))
    return builder.bitcast(builder.shl(biased, _constant(layout, layout.shift)), layout.float_type)


@_bitwise
def _truncate(builder, layout, x):
    """A float64 with the low 32 bits of its significand cleared."""
    bits = builder.and_(builder.bitcast(x, layout.int_type), _constant(layout, -(1 << 32)))
    return builder.bitcast(bits, layout.float_type)


# ------------------------------------------------------------------ float32 algorithms
@njit(**_JIT)
def _log1p_tail32(f):
    """``ln(1 + f) − f`` for ``1 + f ∈ [√½, √2)`` (Cephes ``logf``), Estrin's scheme."""
    t = np.float32
    z = f * f
    z2 = z * z
    p01 = t(3.3333331174e-1) + t(-2.4999993993e-1) * f
    p23 = t(2.0000714765e-1) + t(-1.6668057665e-1) * f
    p45 = t(1.4249322787e-1) + t(-1.2420140846e-1) * f
    p67 = t(1.1676998740e-1) + t(-1.1514610310e-1) * f
    p = (p01 + p23 * z) + z2 * ((p45 + p67 * z) + z2 * t(7.0376836292e-2))
    return f * z * p - t(0.5) * z


@njit(**_JIT)
def _log_from_split32(k, f):
    """``k ln 2 + ln(1 + f)`` (Cephes ``logf``; ``ln 2`` in two parts)."""
    t = np.float32
    y = _log1p_tail32(f)
    return (f + (y + k * t(-2.12194440e-4))) + k * t(0.693359375)


@njit(**_JIT)
def _log2_from_split32(k, f):
    """``k + log₂(1 + f)``: ``(f + y) log₂e`` summed as ``y a + f a + y + f`` with
    ``a = log₂e − 1`` (Cephes ``log2f``), ``y = ln(1 + f) − f``."""
    y = _log1p_tail32(f)
    a = np.float32(0.44269504088896340736)
    return (((y * a + f * a) + y) + f) + k


@njit(**_JIT)
def _exp2_poly32(r):
    """``2^r`` for ``|r| ≤ ½`` (Cephes ``exp2f``), Estrin's scheme."""
    t = np.float32
    r2 = r * r
    p01 = t(6.931472028550421e-1) + t(2.402264791363012e-1) * r
    p23 = t(5.550332471162809e-2) + t(9.618437357674640e-3) * r
    p45 = t(1.339887440266574e-3) + t(1.535336188319500e-4) * r
    return t(1.0) + r * (p01 + r2 * (p23 + r2 * p45))


@njit(**_JIT)
def _exp_tail32(r):
    """``(e^r − 1 − r)/r²`` for ``|r| ≤ ln2/2`` (Cephes ``expf``), Estrin's scheme."""
    t = np.float32
    r2 = r * r
    return (t(5.0000001201e-1) + t(1.6666665459e-1) * r) + r2 * (
        (t(4.1665795894e-2) + t(8.3334519073e-3) * r)
        + r2 * (t(1.3981999507e-3) + t(1.9875691500e-4) * r)
    )


# ------------------------------------------------------------------ float64 algorithms
@njit(**_JIT)
def _log1p_parts64(f):
    """``(s (f²/2 + R), f²/2)`` of fdlibm's ``k_log1p``: ``ln(1 + f) = f − f²/2 + s(f²/2 + R)``."""
    t = np.float64
    s = f / (t(2.0) + f)
    z = s * s
    w = z * z
    t1 = w * (
        t(3.999999999940941908e-01)
        + w * (t(2.222219843214978396e-01) + w * t(1.531383769920937332e-01))
    )
    t2 = z * (
        t(6.666666666666735130e-01)
        + w
        * (
            t(2.857142874366239149e-01)
            + w * (t(1.818357216161805012e-01) + w * t(1.479819860511658591e-01))
        )
    )
    half_f2 = t(0.5) * f * f
    return s * (half_f2 + t1 + t2), half_f2


@njit(**_JIT)
def _log_from_split64(k, f):
    """fdlibm ``e_log.c``: ``k ln 2 + ln(1 + f)`` with ``ln 2`` in two parts."""
    t = np.float64
    r, half_f2 = _log1p_parts64(f)
    return k * t(6.93147180369123816490e-01) - (
        (half_f2 - (r + k * t(1.90821492927058770002e-10))) - f
    )


@njit(**_JIT)
def _log2_from_split64(k, f):
    """fdlibm ``e_log2.c``: ``f − f²/2`` split into a 21-bit head and a tail."""
    t = np.float64
    r, half_f2 = _log1p_parts64(f)
    hi = _truncate(f - half_f2)
    lo = ((f - hi) - half_f2) + r
    inv_ln2_hi, inv_ln2_lo = t(1.44269504072144627571e00), t(1.67517131648865118353e-10)
    val_hi = hi * inv_ln2_hi
    val_lo = (lo + hi) * inv_ln2_lo + lo * inv_ln2_hi
    w = k + val_hi
    return (val_lo + ((k - w) + val_hi)) + w


@njit(**_JIT)
def _estrin64(r, c):
    """``Σ_j c[j] r^j`` for the 11 coefficients ``c`` by Estrin's scheme."""
    r2 = r * r
    r4 = r2 * r2
    p01 = c[0] + c[1] * r
    p23 = c[2] + c[3] * r
    p45 = c[4] + c[5] * r
    p67 = c[6] + c[7] * r
    p89 = c[8] + c[9] * r
    return (p01 + r2 * p23) + r4 * ((p45 + r2 * p67) + r4 * (p89 + r2 * c[10]))


# (2^r − 1)/r and (e^r − 1 − r)/r² on |r| ≤ ½ and |r| ≤ ln2/2: degree-11 Chebyshev fits of
# 2^r and e^r (relative error 2·10⁻¹⁷).
_EXP2_COEFFICIENTS64 = (
    0.6931471805599453, 0.24022650695910158, 0.055504108664821625, 0.009618129107587256,
    0.001333355814640647, 0.00015403530463724353, 1.5252733841556773e-05,
    1.3215432535912375e-06, 1.0178057087733941e-07, 7.074194297288521e-09,
    4.4558179083360645e-10,
)  # fmt: skip
_EXP_COEFFICIENTS64 = (
    0.5000000000000019, 0.1666666666666668, 0.0416666666664881, 0.008333333333319601,
    0.0013888888952314775, 0.00019841269890047113, 2.4801485482328494e-05,
    2.755724091857897e-06, 2.763263963904103e-07, 2.5110037605963777e-08, 0.0,
)  # fmt: skip


@njit(**_JIT)
def _exp2_poly64(r):
    """``2^r`` for ``|r| ≤ ½``."""
    return 1.0 + r * _estrin64(r, _EXP2_COEFFICIENTS64)


@njit(**_JIT)
def _exp_tail64(r):
    """``(e^r − 1 − r)/r²`` for ``|r| ≤ ln2/2``."""
    return _estrin64(r, _EXP_COEFFICIENTS64)


# ------------------------------------------------------------------ one source for both
@njit(**_JIT)
def _scale(p, kf):
    """``p 2^k`` for an integral ``k`` down to one below the subnormal range, by two normal
    factors (subnormal and overflowing results rounded once)."""
    half = np.floor(kf * type(kf)(0.5))
    return p * _power_of_two(half) * _power_of_two(kf - half)


class _Precision(NamedTuple):
    """What differs between float32 and float64: the algorithms and the range limits."""

    t: type  # np.float32 or np.float64
    subnormal_shift: int  # 24 or 54: a subnormal times 2^this is normal
    log_from_split: Dispatcher  # k ln 2 + ln(1 + f)
    log2_from_split: Dispatcher  # k + log₂(1 + f)
    exp2_poly: Dispatcher  # 2^r, |r| ≤ ½
    exp_tail: Dispatcher  # (e^r − 1 − r)/r², |r| ≤ ln2/2
    exp2_limits: tuple[float, float]  # 2^y is 0 below and inf above
    exp_limits: tuple[float, float]  # e^x is 0 below and inf above
    ln2_parts: tuple[float, float]  # ln 2 = hi + lo, hi with trailing zero bits


def _functions(precision: _Precision) -> dict:
    """``log``, ``log2``, ``log2_normal``, ``exp``, ``exp2``, ``exp2_normal`` of one dtype."""
    t, shift = precision.t, precision.subnormal_shift
    log_from_split, log2_from_split = precision.log_from_split, precision.log2_from_split
    exp2_poly, exp_tail = precision.exp2_poly, precision.exp_tail
    zero, one, half = t(0.0), t(1.0), t(0.5)
    smallest_normal = t(np.finfo(t).tiny)
    rescale, rescale_exponent = t(2.0**shift), t(shift)
    exp2_low, exp2_high = (t(v) for v in precision.exp2_limits)
    exp_low, exp_high = (t(v) for v in precision.exp_limits)
    normal_low = t(np.finfo(t).minexp)
    log2_e = t(1.4426950408889634)
    ln2_hi, ln2_lo = (t(v) for v in precision.ln2_parts)

    @njit(**_JIT)
    def split(x):
        """``(k, f)`` with ``x = 2^k (1 + f)``, ``1 + f ∈ [√½, √2)``, subnormal ``x`` too."""
        tiny = x < smallest_normal
        x = x * rescale if tiny else x  # subnormals become normal
        return _exponent(x) - (rescale_exponent if tiny else zero), _mantissa(x) - one

    @njit(**_JIT)
    def log(x):
        k, f = split(x)
        return log_from_split(k, f)

    @njit(**_JIT)
    def log2(x):
        k, f = split(x)
        return log2_from_split(k, f)

    @njit(**_JIT)
    def log2_normal(x):
        return log2_from_split(_exponent(x), _mantissa(x) - one)

    @njit(**_JIT)
    def exp2(y):
        y = exp2_low if y < exp2_low else (exp2_high if y > exp2_high else y)
        kf = np.floor(y + half)
        return _scale(exp2_poly(y - kf), kf)

    @njit(**_JIT)
    def exp2_normal(y):
        under = y < normal_low
        y = normal_low if under else y
        kf = np.floor(y + half)
        p = exp2_poly(y - kf) * _power_of_two(kf)
        return zero if under else p

    @njit(**_JIT)
    def exp(x):
        x = exp_low if x < exp_low else (exp_high if x > exp_high else x)
        kf = np.floor(x * log2_e + half)
        r = (x - kf * ln2_hi) - kf * ln2_lo
        r2 = r * r
        return _scale((exp_tail(r) * r2 + r) + one, kf)

    return {
        "log": log,
        "log2": log2,
        "log2_normal": log2_normal,
        "exp": exp,
        "exp2": exp2,
        "exp2_normal": exp2_normal,
    }


# Per dtype: subnormal shift; ln, log₂ from (k, f); 2^r; (e^r − 1 − r)/r²; the ranges of 2^y
# and e^x; ln 2 in two parts.
_SINGLE = _functions(_Precision(
    np.float32, 24, _log_from_split32, _log2_from_split32, _exp2_poly32, _exp_tail32,
    (-151.0, 129.0), (-104.0, 89.0), (0.693359375, -2.12194440e-4),
))  # fmt: skip
_DOUBLE = _functions(_Precision(
    np.float64, 54, _log_from_split64, _log2_from_split64, _exp2_poly64, _exp_tail64,
    (-1076.0, 1025.0), (-746.0, 710.0), (6.93147180369123816490e-01, 1.90821492927058770002e-10),
))  # fmt: skip


# ------------------------------------------------------------------ public entry points
def log(x):
    """Natural logarithm of a float32/float64 scalar ``x > 0`` (numba only)."""
    raise NotImplementedError(
        "lightcurve.photometry.kernels.elementary functions run inside numba only"
    )


def log2(x):
    """Base-2 logarithm of a float32/float64 scalar ``x > 0`` (numba only)."""
    raise NotImplementedError(
        "lightcurve.photometry.kernels.elementary functions run inside numba only"
    )


def log2_normal(x):
    """Base-2 logarithm of a normal float32/float64 ``x > 0`` (numba only)."""
    raise NotImplementedError(
        "lightcurve.photometry.kernels.elementary functions run inside numba only"
    )


def exp(x):
    """Exponential of a float32/float64 scalar (numba only)."""
    raise NotImplementedError(
        "lightcurve.photometry.kernels.elementary functions run inside numba only"
    )


def exp2(x):
    """``2^x`` of a float32/float64 scalar (numba only)."""
    raise NotImplementedError(
        "lightcurve.photometry.kernels.elementary functions run inside numba only"
    )


def exp2_normal(x):
    """``2^x`` for ``x`` up to the largest exponent, 0 where the result is not normal
    (numba only)."""
    raise NotImplementedError(
        "lightcurve.photometry.kernels.elementary functions run inside numba only"
    )


def _register(function, single, double):
    def typer(x):
        if x == types.float32:
            return lambda x: single(x)
        if x == types.float64:
            return lambda x: double(x)
        return None

    overload(function, jit_options={"fastmath": _FLAGS, "error_model": "numpy"})(typer)


for _function in (log, log2, log2_normal, exp, exp2, exp2_normal):
    _register(_function, _SINGLE[_function.__name__], _DOUBLE[_function.__name__])
