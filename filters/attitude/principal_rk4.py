"""Compiled RK4 chains of torque-free motion in principal axes (numba).

The numpy branch of :func:`~filters.attitude.torque_free_trajectory`: every state's chain
of RK4 steps runs in one compiled loop, with the arithmetic of
:func:`filters.attitude.propagation._rk4_principal` in the same order (so the results are
those of the array kernel to the last bit, and those of the attitude core's
:func:`~filters.attitude.rk4_step` to rounding). The array kernel pays numpy's per-call
overhead on every one of the ~100 element-wise operations of a step, which dominated the
global search's propagation; here a step costs ~100 floating-point operations. The kernel
also turns every state back into the body frame as it writes it: done as separate array
passes over the output, that was as costly as the integration itself (a search window of
3 000 states × 90 epochs: 35 ms of CPU before, 24 ms now, the same bits).

Compiled once per machine (``cache=True``); states are independent, so the loop over them
releases the GIL.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

__all__ = ["body_chains"]


@njit(cache=True, nogil=True)
def _rates(q0, q1, q2, q3, w0, w1, w2, p0, p1, p2):
    """``2 q̇`` and ``ω̇`` in principal axes (see ``_rk4_principal``)."""
    d0 = q3 * w0 - (w1 * q2 - w2 * q1)
    d1 = q3 * w1 - (w2 * q0 - w0 * q2)
    d2 = q3 * w2 - (w0 * q1 - w1 * q0)
    d3 = -((w0 * q0 + w1 * q1) + w2 * q2)
    return d0, d1, d2, d3, p0 * (w1 * w2), p1 * (w2 * w0), p2 * (w0 * w1)


@njit(cache=True, nogil=True)
def _step(q0, q1, q2, q3, w0, w1, w2, p0, p1, p2, h):
    """One RK4 step ``h`` (s) and the renormalisation of ``q``."""
    a0, a1, a2, a3, b0, b1, b2 = _rates(q0, q1, q2, q3, w0, w1, w2, p0, p1, p2)
    f, g = 0.25 * h, 0.5 * h
    c0, c1, c2, c3, d0, d1, d2 = _rates(
        q0 + f * a0, q1 + f * a1, q2 + f * a2, q3 + f * a3,
        w0 + g * b0, w1 + g * b1, w2 + g * b2, p0, p1, p2,
    )  # fmt: skip
    e0, e1, e2, e3, k0, k1, k2 = _rates(
        q0 + f * c0, q1 + f * c1, q2 + f * c2, q3 + f * c3,
        w0 + g * d0, w1 + g * d1, w2 + g * d2, p0, p1, p2,
    )  # fmt: skip
    f, g = 0.5 * h, h
    m0, m1, m2, m3, n0, n1, n2 = _rates(
        q0 + f * e0, q1 + f * e1, q2 + f * e2, q3 + f * e3,
        w0 + g * k0, w1 + g * k1, w2 + g * k2, p0, p1, p2,
    )  # fmt: skip
    f, g = h / 12.0, h / 6.0
    q0 = q0 + f * (a0 + 2.0 * (c0 + e0) + m0)
    q1 = q1 + f * (a1 + 2.0 * (c1 + e1) + m1)
    q2 = q2 + f * (a2 + 2.0 * (c2 + e2) + m2)
    q3 = q3 + f * (a3 + 2.0 * (c3 + e3) + m3)
    w0 = w0 + g * (b0 + 2.0 * (d0 + k0) + n0)
    w1 = w1 + g * (b1 + 2.0 * (d1 + k1) + n1)
    w2 = w2 + g * (b2 + 2.0 * (d2 + k2) + n2)
    norm = math.sqrt(((q0 * q0 + q1 * q1) + q2 * q2) + q3 * q3)
    return q0 / norm, q1 / norm, q2 / norm, q3 / norm, w0, w1, w2


@njit(cache=True, nogil=True)
def _run(q, w, p, back, frame, offsets, sequence, bounds, max_step, q_out, w_out):
    per_body = p.shape[1] > 1
    for j in range(q.shape[1]):
        k = j if per_body else 0
        p0, p1, p2 = p[0, k], p[1, k], p[2, k]
        r0, r1, r2, r3 = back[0, k], back[1, k], back[2, k], back[3, k]
        m = frame[:, k]
        for c in range(len(bounds) - 1):
            q0, q1, q2, q3 = q[0, j], q[1, j], q[2, j], q[3, j]
            w0, w1, w2 = w[0, j], w[1, j], w[2, j]
            t = 0.0
            for index in range(bounds[c], bounds[c + 1]):
                i = sequence[index]
                dt = offsets[i] - t
                steps = math.ceil(abs(dt) / max_step)
                for _ in range(steps):
                    q0, q1, q2, q3, w0, w1, w2 = _step(
                        q0, q1, q2, q3, w0, w1, w2, p0, p1, p2, dt / steps
                    )
                t = offsets[i]
                # Back in the body frame, q = r⁻¹ ⊗ q_P and ω = P ω_P, in the operation
                # order of the array kernel (propagation._left_multiply, _mat_vec).
                q_out[0, i, j] = r3 * q0 + r0 * q3 - r1 * q2 + r2 * q1
                q_out[1, i, j] = r3 * q1 + r1 * q3 - r2 * q0 + r0 * q2
                q_out[2, i, j] = r3 * q2 + r2 * q3 - r0 * q1 + r1 * q0
                q_out[3, i, j] = r3 * q3 - r0 * q0 - r1 * q1 - r2 * q2
                w_out[0, i, j] = m[0] * w0 + m[1] * w1 + m[2] * w2
                w_out[1, i, j] = m[3] * w0 + m[4] * w1 + m[5] * w2
                w_out[2, i, j] = m[6] * w0 + m[7] * w1 + m[8] * w2


def body_chains(
    q: np.ndarray,
    w: np.ndarray,
    p: np.ndarray,
    back: np.ndarray,
    frame: np.ndarray,
    offsets: np.ndarray,
    *,
    max_step: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Body-frame states at every offset of states given in principal axes: one RK4 chain
    through the non-negative offsets in increasing order, one backwards through the
    negative ones, each interval in ``ceil(|Δt|/max_step)`` equal steps; every state is
    turned back into the body frame (``q = r⁻¹ ⊗ q_P``, ``ω = P ω_P``) as it is written.

    Parameters
    ----------
    q : (4, M) float array
        Attitudes in principal axes (component-first).
    w : (3, M) float array
        Rates in principal axes (rad/s).
    p : (3, M) or (3, 1) float array
        Inertia ratios (per state or shared).
    back : (4, M) or (4, 1) float array
        ``r⁻¹``, the quaternion of the principal → body frame rotation ``P``.
    frame : (9, M) or (9, 1) float array
        ``P`` row-major (columns: the principal axes in the body frame).
    offsets : (E,) float array
        Times (s) relative to the states.
    max_step : float
        Largest RK4 step (s).

    Returns
    -------
    q : (4, E, M), w : (3, E, M) numpy.ndarray
        Component-first, the layout of the array kernel's output (callers see the
        transposed view, whose strides decide how later array operations round).
    """
    offsets = np.asarray(offsets, dtype=float)
    order = np.argsort(offsets, kind="stable")
    forwards = order[offsets[order] >= 0]
    backwards = order[offsets[order] < 0][::-1]
    q_out = np.empty((4, len(offsets), q.shape[1]))
    w_out = np.empty((3, len(offsets), q.shape[1]))
    _run(
        np.ascontiguousarray(q, dtype=float),
        np.ascontiguousarray(w, dtype=float),
        np.ascontiguousarray(p, dtype=float),
        np.ascontiguousarray(back, dtype=float),
        np.ascontiguousarray(frame, dtype=float),
        offsets,
        np.concatenate([forwards, backwards]).astype(np.int64),
        np.array([0, len(forwards), len(offsets)], dtype=np.int64),
        float(max_step),
        q_out,
        w_out,
    )
    return q_out, w_out
