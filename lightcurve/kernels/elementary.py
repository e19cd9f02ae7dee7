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

Accuracy (measured against numpy in extended precision, ``tests/lightcurve/test_kernels.py``):
at most 1.3 ulp in float32 and float64, subnormal inputs and results included. Domains:
``log``/``log2`` take finite ``x > 0``; ``exp``/``exp2`` return 0 below the subnormal range
and ``inf`` above the largest finite number.

The kernels use two cheaper forms on their own domains: :func:`log2_normal` (normal
``x > 0``: no subnormal rescaling) and :func:`exp2_normal` (``y ≤ 127`` in float32,
``y ≤ 1023`` in float64; 0 where ``2^y`` is below the smallest normal number, 2⁻¹²⁶ ≈
1.2·10⁻³⁸ in float32 and 2⁻¹⁰²² in float64 — a specular lobe that small changes no sum that
holds a normal-sized term, while subnormal arithmetic costs x86 cores ~100 cycles per
operation).
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic, overload

__all__ = ["exp", "exp2", "exp2_normal", "log", "log2", "log2_normal"]

# No reassociation here: the range reductions and the hi/lo sums rely on the order of their
# operations. The kernels that inline these functions keep these flags on these operations.
_FLAGS = {"contract"}
_JIT = {"fastmath": _FLAGS, "error_model": "numpy", "nogil": True}


def _layout(float_type: types.Float) -> tuple:
    """LLVM float and integer types, mantissa bits, the bits of √½, mantissa mask, bias."""
    if float_type == types.float32:
        return ir.FloatType(), ir.IntType(32), 23, 0x3F3504F3, 0x007FFFFF, 127
    return ir.DoubleType(), ir.IntType(64), 52, 0x3FE6A09E667F3BCD, 0x000FFFFFFFFFFFFF, 1023


@intrinsic
def _exponent(typingctx, x):
    """``k`` (as a float) of a normal ``x > 0`` written ``2^k m`` with ``m ∈ [√½, √2)``."""

    def codegen(context, builder, sig, args):
        _, int_type, shift, offset, _, _ = _layout(sig.args[0])
        bits = builder.sub(builder.bitcast(args[0], int_type), ir.Constant(int_type, offset))
        k = builder.ashr(bits, ir.Constant(int_type, shift))
        if int_type.width == 64:  # AVX2 converts int32, not int64, vectors to double
            k = builder.trunc(k, ir.IntType(32))
        return builder.sitofp(k, _layout(sig.args[0])[0])

    return x(x), codegen


@intrinsic
def _mantissa(typingctx, x):
    """``m ∈ [√½, √2)`` of a normal ``x > 0`` written ``2^k m``."""

    def codegen(context, builder, sig, args):
        float_type, int_type, _, offset, mask, _ = _layout(sig.args[0])
        bits = builder.sub(builder.bitcast(args[0], int_type), ir.Constant(int_type, offset))
        m = builder.add(
            builder.and_(bits, ir.Constant(int_type, mask)), ir.Constant(int_type, offset)
        )
        return builder.bitcast(m, float_type)

    return x(x), codegen


@intrinsic
def _power_of_two(typingctx, k):
    """``2^k`` for an integral float ``k`` in the normal exponent range."""

    def codegen(context, builder, sig, args):
        float_type, int_type, shift, _, _, bias = _layout(sig.args[0])
        ki = builder.fptosi(args[0], ir.IntType(32))
        if int_type.width == 64:
            ki = builder.sext(ki, int_type)
        bits = builder.shl(
            builder.add(ki, ir.Constant(int_type, bias)), ir.Constant(int_type, shift)
        )
        return builder.bitcast(bits, float_type)

    return k(k), codegen


@intrinsic
def _truncate(typingctx, x):
    """A float64 with the low 32 bits of its significand cleared."""

    def codegen(context, builder, sig, args):
        int_type = ir.IntType(64)
        bits = builder.and_(builder.bitcast(args[0], int_type), ir.Constant(int_type, -(1 << 32)))
        return builder.bitcast(bits, ir.DoubleType())

    return x(x), codegen


# ------------------------------------------------------------------ float32
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
def _split32(x):
    """``(k, f)`` with ``x = 2^k (1 + f)``, ``1 + f ∈ [√½, √2)``, subnormal ``x`` too."""
    t = np.float32
    tiny = x < t(1.17549435e-38)
    x = x * t(16777216.0) if tiny else x  # 2²⁴: subnormals become normal
    return _exponent(x) - (t(24.0) if tiny else t(0.0)), _mantissa(x) - t(1.0)


@njit(**_JIT)
def _log2_from_split32(k, f):
    """``k + log₂(1 + f)``: ``(f + y) log₂e`` summed as ``y a + f a + y + f`` with
    ``a = log₂e − 1`` (Cephes ``log2f``), ``y = ln(1 + f) − f``."""
    y = _log1p_tail32(f)
    a = np.float32(0.44269504088896340736)
    return (((y * a + f * a) + y) + f) + k


@njit(**_JIT)
def _log32(x):
    t = np.float32
    k, f = _split32(x)
    y = _log1p_tail32(f)
    return (f + (y + k * t(-2.12194440e-4))) + k * t(0.693359375)  # ln 2 in two parts


@njit(**_JIT)
def _log2_32(x):
    k, f = _split32(x)
    return _log2_from_split32(k, f)


@njit(**_JIT)
def _log2_normal32(x):
    return _log2_from_split32(_exponent(x), _mantissa(x) - np.float32(1.0))


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
def _scale32(p, kf):
    """``p 2^k`` for integral ``k ∈ [−151, 129]``, by two normal factors (subnormal and
    overflowing results rounded once)."""
    half = np.floor(kf * np.float32(0.5))
    return p * _power_of_two(half) * _power_of_two(kf - half)


@njit(**_JIT)
def _exp2_32(y):
    t = np.float32
    y = t(-151.0) if y < t(-151.0) else (t(129.0) if y > t(129.0) else y)
    kf = np.floor(y + t(0.5))
    return _scale32(_exp2_poly32(y - kf), kf)


@njit(**_JIT)
def _exp2_normal32(y):
    t = np.float32
    under = y < t(-126.0)
    y = t(-126.0) if under else y
    kf = np.floor(y + t(0.5))
    p = _exp2_poly32(y - kf) * _power_of_two(kf)
    return t(0.0) if under else p


@njit(**_JIT)
def _exp32(x):
    t = np.float32
    x = t(-104.0) if x < t(-104.0) else (t(89.0) if x > t(89.0) else x)
    kf = np.floor(x * t(1.44269504088896341) + t(0.5))
    r = (x - kf * t(0.693359375)) - kf * t(-2.12194440e-4)
    r2 = r * r
    p = (t(5.0000001201e-1) + t(1.6666665459e-1) * r) + r2 * (
        (t(4.1665795894e-2) + t(8.3334519073e-3) * r)
        + r2 * (t(1.3981999507e-3) + t(1.9875691500e-4) * r)
    )
    return _scale32((p * r2 + r) + t(1.0), kf)


# ------------------------------------------------------------------ float64
@njit(**_JIT)
def _split64(x):
    t = np.float64
    tiny = x < t(2.2250738585072014e-308)
    x = x * t(18014398509481984.0) if tiny else x  # 2⁵⁴
    return _exponent(x) - (t(54.0) if tiny else t(0.0)), _mantissa(x) - t(1.0)


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
def _log64(x):
    t = np.float64
    k, f = _split64(x)
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
def _log2_64(x):
    k, f = _split64(x)
    return _log2_from_split64(k, f)


@njit(**_JIT)
def _log2_normal64(x):
    return _log2_from_split64(_exponent(x), _mantissa(x) - np.float64(1.0))


@njit(**_JIT)
def _exp2_poly64(r):
    """``2^r`` for ``|r| ≤ ½``: degree-11 Chebyshev fit (relative error 2·10⁻¹⁷), Estrin."""
    t = np.float64
    r2 = r * r
    r4 = r2 * r2
    a = t(0.6931471805599453) + t(0.24022650695910158) * r
    b = t(0.055504108664821625) + t(0.009618129107587256) * r
    c = t(0.001333355814640647) + t(0.00015403530463724353) * r
    d = t(1.5252733841556773e-05) + t(1.3215432535912375e-06) * r
    e = t(1.0178057087733941e-07) + t(7.074194297288521e-09) * r
    return t(1.0) + r * (
        (a + r2 * b) + r4 * ((c + r2 * d) + r4 * (e + r2 * t(4.4558179083360645e-10)))
    )


@njit(**_JIT)
def _scale64(p, kf):
    half = np.floor(kf * np.float64(0.5))
    return p * _power_of_two(half) * _power_of_two(kf - half)


@njit(**_JIT)
def _exp2_64(y):
    t = np.float64
    y = t(-1076.0) if y < t(-1076.0) else (t(1025.0) if y > t(1025.0) else y)
    kf = np.floor(y + t(0.5))
    return _scale64(_exp2_poly64(y - kf), kf)


@njit(**_JIT)
def _exp2_normal64(y):
    t = np.float64
    under = y < t(-1022.0)
    y = t(-1022.0) if under else y
    kf = np.floor(y + t(0.5))
    p = _exp2_poly64(y - kf) * _power_of_two(kf)
    return t(0.0) if under else p


@njit(**_JIT)
def _exp64(x):
    t = np.float64
    x = t(-746.0) if x < t(-746.0) else (t(710.0) if x > t(710.0) else x)
    kf = np.floor(x * t(1.4426950408889634) + t(0.5))
    r = (x - kf * t(6.93147180369123816490e-01)) - kf * t(1.90821492927058770002e-10)
    r2 = r * r
    r4 = r2 * r2
    # e^r = 1 + r + r² q(r): degree-11 Chebyshev fit on |r| ≤ ln2/2 (relative error 2·10⁻¹⁷).
    a = t(0.5000000000000019) + t(0.1666666666666668) * r
    b = t(0.0416666666664881) + t(0.008333333333319601) * r
    c = t(0.0013888888952314775) + t(0.00019841269890047113) * r
    d = t(2.4801485482328494e-05) + t(2.755724091857897e-06) * r
    e = t(2.763263963904103e-07) + t(2.5110037605963777e-08) * r
    q = (a + r2 * b) + r4 * ((c + r2 * d) + r4 * e)
    return _scale64((q * r2 + r) + t(1.0), kf)


# ------------------------------------------------------------------ public entry points
def log(x):
    """Natural logarithm of a float32/float64 scalar ``x > 0`` (numba only)."""
    raise NotImplementedError("lightcurve.kernels.elementary functions run inside numba only")


def log2(x):
    """Base-2 logarithm of a float32/float64 scalar ``x > 0`` (numba only)."""
    raise NotImplementedError("lightcurve.kernels.elementary functions run inside numba only")


def log2_normal(x):
    """Base-2 logarithm of a normal float32/float64 ``x > 0`` (numba only)."""
    raise NotImplementedError("lightcurve.kernels.elementary functions run inside numba only")


def exp(x):
    """Exponential of a float32/float64 scalar (numba only)."""
    raise NotImplementedError("lightcurve.kernels.elementary functions run inside numba only")


def exp2(x):
    """``2^x`` of a float32/float64 scalar (numba only)."""
    raise NotImplementedError("lightcurve.kernels.elementary functions run inside numba only")


def exp2_normal(x):
    """``2^x`` for ``x`` up to the largest exponent, 0 where the result is not normal
    (numba only)."""
    raise NotImplementedError("lightcurve.kernels.elementary functions run inside numba only")


def _register(function, single, double):
    def typer(x):
        if x == types.float32:
            return lambda x: single(x)
        if x == types.float64:
            return lambda x: double(x)
        return None

    overload(function, jit_options={"fastmath": _FLAGS, "error_model": "numpy"})(typer)


for _function, _single, _double in (
    (log, _log32, _log64),
    (log2, _log2_32, _log2_64),
    (log2_normal, _log2_normal32, _log2_normal64),
    (exp, _exp32, _exp64),
    (exp2, _exp2_32, _exp2_64),
    (exp2_normal, _exp2_normal32, _exp2_normal64),
):
    _register(_function, _single, _double)
