"""Compiled per-epoch kernels of the convex model (numba, cached on disk).

For problem b and epoch j the kernels turn the Sun and Earth directions into the body frame,
``v_B = R_z(φ0 + ω t_j) · A_pole(λ, β) · v`` (:mod:`lightcurve.analysis.spin`; ``A_pole`` and its
derivatives are given per problem), sum the scattering law over the facets of the Gaussian
sphere and apply the phase function (Kaasalainen & Torppa 2001, eq. 1; Kaasalainen, Torppa &
Muinonen 2001, eqs. 3–4)::

    L_bj = f(α_j) Σ_i A_bi S(μ0_bij, μ_bij),   S = μ μ0 (1/(μ + μ0) + c)   (μ, μ0 > 0),
    f(α) = max(0, a e^{−α/d} + k α + 1)

(the law of :func:`brdf.lommel_seeliger_from_cosines` with ``w = 4π`` and
:func:`brdf.phase_function`). With the Jacobian they also write ``f S_bij`` — the shape
columns are then one matrix product with ``A_bi Y_ik``, since ``∂A_i/∂c_k = A_i Y_ik`` — and
the columns of λ, β, ω, φ0, a, d, k and c in closed form: the facet sums
``Σ_i A_i ∂S/∂μ0 n_i`` and ``Σ_i A_i ∂S/∂μ n_i`` (``∂S/∂μ0 = (μ/(μ + μ0))² + c μ``,
``∂S/∂μ = (μ0/(μ + μ0))² + c μ0``) contracted with the derivatives of the body-frame
directions (``∂v_B/∂φ0 = (v_B,y, −v_B,x, 0)``, ``∂v_B/∂ω = t ∂v_B/∂φ0``, the pole through
``∂A_pole``), ``∂f/∂(a, d, k) = (e^{−α/d}, a e^{−α/d} α/d², α)`` and ``∂L/∂c = f Σ A μ0 μ``.
:func:`normalise` turns brightness and Jacobian into residuals of relative (``L/⟨L⟩`` per
curve) and calibrated (``e^s L``) curves.

All epochs of all problems of a batch run in parallel (``prange``); the facet loop runs in
the dtype of the facet arrays (float32 or float64), everything else in float64. The kernels
are compiled once per machine and dtype (``cache=True``: later processes load the machine
code from ``__pycache__``).

Threads: unless ``NUMBA_THREADING_LAYER`` says otherwise, numba's ``workqueue`` layer runs the
parallel loops. The OpenMP layer's threads spin after each loop and take the CPU from the
numpy work in between (a period scan took twice the CPU time on a busy machine); workqueue
threads sleep. Workqueue does not allow parallel kernels launched from several Python
threads of one process at once: use processes, or set ``NUMBA_THREADING_LAYER=omp`` (or
``tbb``) for that.
"""

from __future__ import annotations

import math
import os

import numba
import numpy as np

if "NUMBA_THREADING_LAYER" not in os.environ:
    numba.config.THREADING_LAYER = "workqueue"

__all__ = ["brightness", "brightness_and_jacobian", "normalise"]

#: Floor of ``μ + μ0`` (where both vanish S is zero anyway), as in :mod:`brdf`.
COSINE_FLOOR = 1e-12
#: Columns written by :func:`brightness_and_jacobian` besides the shape: λ, β, ω, φ0, a, d,
#: k, c (the order of :class:`~lightcurve.analysis.convex.layout.ParameterLayout`).
SPIN_PHASE_COLUMNS = 8

#: Reassociation lets the facet sums vectorise; no finite-math assumptions (a NaN must reach
#: the optimiser, which rejects the step).
_FASTMATH = {"reassoc", "contract", "arcp", "nsz"}
_OPTIONS = {"cache": True, "fastmath": _FASTMATH, "error_model": "numpy"}


@numba.njit(inline="always", **_OPTIONS)
def _turn(matrix, vector, cos, sin):  # pragma: no cover - compiled
    """``R_z(φ) · matrix · vector`` for a (3, 3) matrix (R_z passive)."""
    x = matrix[0, 0] * vector[0] + matrix[0, 1] * vector[1] + matrix[0, 2] * vector[2]
    y = matrix[1, 0] * vector[0] + matrix[1, 1] * vector[1] + matrix[1, 2] * vector[2]
    z = matrix[2, 0] * vector[0] + matrix[2, 1] * vector[1] + matrix[2, 2] * vector[2]
    return cos * x + sin * y, cos * y - sin * x, z


@numba.njit(inline="always", **_OPTIONS)
def _epoch_geometry(task, seconds, sun, earth, poles, scalars, real):  # pragma: no cover
    """Problem b, epoch j and the body-frame geometry of the flat task index ``b N + j``.

    Returns ``b, j, t, cos φ, sin φ`` (``φ = φ0 + ω t``), the x and y components of the
    body-frame Sun and Earth directions in float64 (what the rotation columns need), then,
    in the facet dtype ``real``, the three components of each direction and ``c``.
    """
    epochs = seconds.shape[0]
    b = task // epochs
    j = task - b * epochs
    t = seconds[j]
    phi = scalars[b, 0] + scalars[b, 1] * t
    cos, sin = math.cos(phi), math.sin(phi)
    lx, ly, lz = _turn(poles[b, 0], sun[j], cos, sin)
    vx, vy, vz = _turn(poles[b, 0], earth[j], cos, sin)
    # One flat tuple: numba's parfor analysis rejects nested tuples from an inlined call.
    return (
        *(b, j, t, cos, sin, lx, ly, vx, vy),
        *(real(lx), real(ly), real(lz), real(vx), real(vy), real(vz), real(scalars[b, 5])),
    )


@numba.njit(inline="always", **_OPTIONS)
def _phase(alpha, a, d, k):  # pragma: no cover - compiled
    """``(f, e^{−α/d})`` with f clamped at 0."""
    decay = math.exp(-alpha / d)
    return max(a * decay + k * alpha + 1.0, 0.0), decay


@numba.njit(parallel=True, **_OPTIONS)
def brightness(seconds, sun, earth, alpha, normals, areas, poles, scalars, out):  # pragma: no cover
    """Model brightness ``L_bj``.

    Parameters
    ----------
    seconds : (N,) float64
        Epochs relative to t0 (s).
    sun, earth : (N, 3) float64
        Unit object → Sun and object → observer vectors (inertial).
    alpha : (N,) float64
        Phase angles (rad).
    normals : (3, F) float
        Facet normals, one row per component (float32 or float64: the facet loop's dtype).
    areas : (B, F) float
        Facet areas, same dtype.
    poles : (B, 3, 3, 3) float64
        ``A_pole``, ``∂A_pole/∂λ``, ``∂A_pole/∂β`` per problem (the first only is used here).
    scalars : (B, 6) float64
        ``φ0, ω, a, d, k, c`` per problem.
    out : (B, N) float64
        Written.
    """
    real = normals.dtype.type
    zero, one, floor = real(0.0), real(1.0), real(COSINE_FLOOR)
    for task in numba.prange(out.size):
        b, j, _, _, _, _, _, _, _, sx, sy, sz, ex, ey, ez, c = _epoch_geometry(
            task, seconds, sun, earth, poles, scalars, real
        )
        total = zero
        for i in range(normals.shape[1]):
            mu0 = max(sx * normals[0, i] + sy * normals[1, i] + sz * normals[2, i], zero)
            mu = max(ex * normals[0, i] + ey * normals[1, i] + ez * normals[2, i], zero)
            total += areas[b, i] * (mu0 * mu) * (one / max(mu0 + mu, floor) + c)
        f, _ = _phase(alpha[j], scalars[b, 2], scalars[b, 3], scalars[b, 4])
        out[b, j] = f * total


@numba.njit(parallel=True, **_OPTIONS)
def brightness_and_jacobian(
    seconds, sun, earth, alpha, normals, areas, poles, scalars, out, scatter, columns
):  # pragma: no cover - compiled
    """:func:`brightness`, ``f S`` and the non-shape columns of the Jacobian.

    Parameters
    ----------
    seconds, sun, earth, alpha, normals, areas, poles, scalars, out
        As :func:`brightness`.
    scatter : (B, N, F) float
        Written: ``f(α_j) S_bji`` (zero in shadow or out of view), the dtype of ``normals``.
    columns : (B, N, 8) float64
        Written: ``∂L_bj/∂(λ, β, ω, φ0, a, d, k, c)``.
    """
    real = normals.dtype.type
    zero, one, floor = real(0.0), real(1.0), real(COSINE_FLOOR)
    for task in numba.prange(out.size):
        b, j, t, cos, sin, lx, ly, vx, vy, sx, sy, sz, ex, ey, ez, c = _epoch_geometry(
            task, seconds, sun, earth, poles, scalars, real
        )
        f, decay = _phase(alpha[j], scalars[b, 2], scalars[b, 3], scalars[b, 4])
        total, lambert_total = zero, zero
        gl0, gl1, gl2, gv0, gv1, gv2 = zero, zero, zero, zero, zero, zero
        row = scatter[b, j]
        for i in range(normals.shape[1]):
            nx, ny, nz = normals[0, i], normals[1, i], normals[2, i]
            cos0 = sx * nx + sy * ny + sz * nz
            cos1 = ex * nx + ey * ny + ez * nz
            mu0, mu = max(cos0, zero), max(cos1, zero)
            inverse = one / max(mu0 + mu, floor)
            product = mu0 * mu
            value = product * (inverse + c)
            row[i] = real(f) * value
            area = areas[b, i]
            total += area * value
            lambert_total += area * product
            # ∂S/∂μ0 vanishes in shadow (μ0 clamped), ∂S/∂μ out of view.
            d0 = area * ((mu * inverse) ** 2 + c * mu) if cos0 > zero else zero
            d1 = area * ((mu0 * inverse) ** 2 + c * mu0) if cos1 > zero else zero
            gl0 += d0 * nx
            gl1 += d0 * ny
            gl2 += d0 * nz
            gv0 += d1 * nx
            gv1 += d1 * ny
            gv2 += d1 * nz
        out[b, j] = f * total
        # Pole: the facet sums contracted with R_z(φ) ∂A_pole v.
        for axis in range(2):
            ax, ay, az = _turn(poles[b, axis + 1], sun[j], cos, sin)
            bx, by, bz = _turn(poles[b, axis + 1], earth[j], cos, sin)
            columns[b, j, axis] = f * (
                gl0 * ax + gl1 * ay + gl2 * az + gv0 * bx + gv1 * by + gv2 * bz
            )
        # Rotation: ∂v_B/∂φ = (v_y, −v_x, 0); ω through t.
        turn = f * (gl0 * ly - gl1 * lx + gv0 * vy - gv1 * vx)
        columns[b, j, 2] = turn * t
        columns[b, j, 3] = turn
        a, d = scalars[b, 2], scalars[b, 3]
        positive = 1.0 if f > 0 else 0.0
        columns[b, j, 4] = positive * decay * total
        columns[b, j, 5] = positive * a * decay * alpha[j] / (d * d) * total
        columns[b, j, 6] = positive * alpha[j] * total
        columns[b, j, 7] = f * lambert_total


@numba.njit(parallel=True, **_OPTIONS)
def normalise(
    brightness,
    shape,
    columns,
    curve,
    n_curves,
    relative,
    log_scale,
    observed,
    sigma,
    index,
    residuals,
    jacobian,
):  # pragma: no cover - compiled
    """Residuals ``(y − model)/σ`` and their Jacobian from ``L`` and ``∂L``.

    Relative curves: ``model = L/⟨L⟩_curve``, ``∂model = ∂L/⟨L⟩ − L ⟨∂L⟩/⟨L⟩²``; calibrated
    curves: ``model = e^s L``, ``∂model = e^s ∂L`` and ``∂model/∂s = model``.

    Parameters
    ----------
    brightness : (B, N) float64
    shape : (B, N, K) float
        ``∂L/∂c_k``.
    columns : (B, N, 8) float64
        As written by :func:`brightness_and_jacobian`.
    curve : (N,) int
        Light-curve index of each point.
    n_curves : int
    relative : (N,) bool
    log_scale : (B,) float64
        ``s`` per problem.
    observed, sigma : (N,) float64
    index : (Q,) int
        Parameters (positions in the parameter vector, K + 9 of them) whose columns to write.
    residuals : (B, ≥ N) float64
        Rows 0 … N−1 written.
    jacobian : (B, ≥ N, Q) float64
        Rows 0 … N−1 written: ``∂r/∂p`` for the parameters of ``index``.
    """
    batch, epochs = brightness.shape
    terms = shape.shape[2]
    width = terms + 8
    for b in numba.prange(batch):
        mean = np.zeros(n_curves)
        mean_d = np.zeros((n_curves, width))
        counts = np.zeros(n_curves)
        for j in range(epochs):
            label = curve[j]
            counts[label] += 1.0
            mean[label] += brightness[b, j]
            for k in range(terms):
                mean_d[label, k] += shape[b, j, k]
            for k in range(8):
                mean_d[label, terms + k] += columns[b, j, k]
        for label in range(n_curves):
            mean[label] /= counts[label]
            for k in range(width):
                mean_d[label, k] /= counts[label]
        scale = math.exp(log_scale[b])
        row = np.empty(width + 1)
        for j in range(epochs):
            label = curve[j]
            value = brightness[b, j]
            weight = -1.0 / sigma[j]
            if relative[j]:
                inverse = 1.0 / mean[label]
                ratio = value * inverse * inverse
                model = value * inverse
                for k in range(terms):
                    row[k] = weight * (shape[b, j, k] * inverse - ratio * mean_d[label, k])
                for k in range(8):
                    row[terms + k] = weight * (
                        columns[b, j, k] * inverse - ratio * mean_d[label, terms + k]
                    )
                row[width] = 0.0
            else:
                model = scale * value
                for k in range(terms):
                    row[k] = weight * scale * shape[b, j, k]
                for k in range(8):
                    row[terms + k] = weight * scale * columns[b, j, k]
                row[width] = weight * model
            for q in range(index.shape[0]):
                jacobian[b, j, q] = row[index[q]]
            residuals[b, j] = (observed[j] - model) / sigma[j]
