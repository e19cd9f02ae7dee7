"""Exponential and logarithm that LLVM vectorises, for the numba rendering kernels.

Numba compiles ``math.exp``/``math.log`` to calls into the C math library, which keep a loop
scalar (the PyPI builds of llvmlite carry no vector math library). The specular lobes need
``x**y = exp(y ln x)`` for every facet and epoch, so these functions are written with
arithmetic and bit operations only; the kernels' facet loops then run on AVX/NEON vectors.

The algorithms are those of fdlibm (Sun Microsystems 1993, ``e_log.c``, ``e_exp.c``; the
float32 forms ``ef_log.c``, ``ef_exp.c`` of Cygnus/newlib): ``ln x = k ln 2 + ln m``
with ``m ∈ [√½, √2)``, ``ln m = 2 atanh s``, ``s = (m − 1)/(m + 1)`` by a Remez polynomial;
``exp x = 2^k exp r``, ``|r| ≤ ln 2/2`` by a Remez rational form. They are accurate to
about 1 ulp (tested against numpy in ``tests/lightcurve/test_kernels.py``).

Domains: ``log`` takes finite ``x > 0`` (subnormals included); ``exp`` returns 0 below
−708 (float64) or −87 (float32), where the true value is below the smallest normal number,
and saturates above 709 (88).
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic, overload

__all__ = ["exp", "log"]

# No reassociation here: the range reductions rely on the order of their operations.
_FLAGS = {"contract"}
_JIT = {"fastmath": _FLAGS, "error_model": "numpy", "nogil": True}


@intrinsic
def _int_bits(typingctx, x):
    """The IEEE bits of a float as an integer of the same width."""
    width = 64 if x == types.float64 else 32
    signature = (types.int64 if width == 64 else types.int32)(x)

    def codegen(context, builder, sig, args):
        return builder.bitcast(args[0], ir.IntType(width))

    return signature, codegen


@intrinsic
def _double_from_bits(typingctx, x):
    """The float64 whose IEEE bits are the integer ``x``."""

    def codegen(context, builder, sig, args):
        return builder.bitcast(args[0], ir.DoubleType())

    return types.float64(x), codegen


@intrinsic
def _single_from_bits(typingctx, x):
    """The float32 whose IEEE bits are the low 32 bits of the integer ``x``."""

    def codegen(context, builder, sig, args):
        value = args[0]
        if value.type.width != 32:
            value = builder.trunc(value, ir.IntType(32))
        return builder.bitcast(value, ir.FloatType())

    return types.float32(x), codegen


@njit(**_JIT)
def _log64(x):
    t = np.float64
    tiny = x < t(2.2250738585072014e-308)
    x = x * t(4503599627370496.0) if tiny else x  # 2⁵²: subnormals become normal
    bits = _int_bits(x) - np.int64(0x3FE6A09E667F3BCD)  # offset: m ∈ [√½, √2)
    k = (bits >> np.int64(52)) - (np.int64(52) if tiny else np.int64(0))
    m = _double_from_bits((bits & np.int64(0x000FFFFFFFFFFFFF)) + np.int64(0x3FE6A09E667F3BCD))
    f = m - t(1.0)
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
    kf = t(np.int32(k))  # via int32: AVX2 converts int32, not int64, vectors to double
    return kf * t(6.93147180369123816490e-01) - (
        (half_f2 - (s * (half_f2 + t1 + t2) + kf * t(1.90821492927058770002e-10))) - f
    )


@njit(**_JIT)
def _log32(x):
    t = np.float32
    tiny = x < t(1.17549435e-38)
    x = x * t(16777216.0) if tiny else x  # 2²⁴
    bits = _int_bits(x) - np.int32(0x3F3504F3)
    k = (bits >> np.int32(23)) - (np.int32(24) if tiny else np.int32(0))
    m = _single_from_bits((bits & np.int32(0x007FFFFF)) + np.int32(0x3F3504F3))
    f = m - t(1.0)
    s = f / (t(2.0) + f)
    z = s * s
    w = z * z
    t1 = w * (t(0.40000972152) + w * t(0.24279078841))
    t2 = z * (t(0.66666662693) + w * t(0.28498786688))
    half_f2 = t(0.5) * f * f
    kf = t(k)
    return kf * t(6.9313812256e-01) - (
        (half_f2 - (s * (half_f2 + t1 + t2) + kf * t(9.0580006145e-06))) - f
    )


@njit(**_JIT)
def _exp64(x):
    t = np.float64
    under = x < t(-708.0)
    x = t(-708.0) if under else (t(709.0) if x > t(709.0) else x)
    kf = np.floor(x * t(1.4426950408889634) + t(0.5))
    r = (x - kf * t(6.93147180369123816490e-01)) - kf * t(1.90821492927058770002e-10)
    r2 = r * r
    c = r - r2 * (
        t(1.66666666666666019037e-01)
        + r2
        * (
            t(-2.77777777770155933842e-03)
            + r2
            * (
                t(6.61375632143793436117e-05)
                + r2 * (t(-1.65339022054652515390e-06) + r2 * t(4.13813679705723846039e-08))
            )
        )
    )
    y = t(1.0) - ((r * c) / (c - t(2.0)) - r)
    # 2^k by its bits, through int32 (AVX2 has no double → int64 vector conversion).
    scale = _double_from_bits((np.int64(np.int32(kf)) + np.int64(1023)) << np.int64(52))
    return t(0.0) if under else y * scale


@njit(**_JIT)
def _exp32(x):
    t = np.float32
    under = x < t(-87.0)
    x = t(-87.0) if under else (t(88.0) if x > t(88.0) else x)
    kf = np.floor(x * t(1.44269504) + t(0.5))
    r = (x - kf * t(6.9314575195e-01)) - kf * t(1.4286067653e-06)
    r2 = r * r
    c = r - r2 * (t(1.6666625440e-1) + r2 * t(-2.7667332906e-3))
    y = t(1.0) - ((r * c) / (c - t(2.0)) - r)
    scale = _single_from_bits((np.int32(kf) + np.int32(127)) << np.int32(23))
    return t(0.0) if under else y * scale


def log(x):
    """Natural logarithm of a float32/float64 scalar ``x > 0`` (numba only)."""
    raise NotImplementedError("lightcurve.kernels.elementary.log runs inside numba only")


def exp(x):
    """Exponential of a float32/float64 scalar (numba only)."""
    raise NotImplementedError("lightcurve.kernels.elementary.exp runs inside numba only")


@overload(log, jit_options={"fastmath": _FLAGS, "error_model": "numpy"})
def _log_overload(x):
    if x == types.float32:
        return lambda x: _log32(x)
    return lambda x: _log64(x)


@overload(exp, jit_options={"fastmath": _FLAGS, "error_model": "numpy"})
def _exp_overload(x):
    if x == types.float32:
        return lambda x: _exp32(x)
    return lambda x: _exp64(x)
