"""LAMBDA integer ambiguity estimation: decorrelation, search, ratio test, success rate.

Given float ambiguities ``â`` with covariance ``Q``, the integer least-squares (ILS) estimate is

``ǎ = argmin_{a ∈ ℤⁿ} (â − a)ᵀ Q⁻¹ (â − a)``.

The least-squares ambiguity decorrelation adjustment (Teunissen 1995, *The least-squares
ambiguity decorrelation adjustment: a method for fast GPS integer ambiguity estimation*,
J. Geodesy 70) solves it in two steps:

1. **Decorrelation.** With ``Q = Lᵀ D L`` (``L`` unit lower triangular, ``D`` diagonal —
   the conditional variances), integer Gauss transformations and symmetric permutations build
   a unimodular integer matrix ``Z`` (``|det Z| = 1``, so ``Z`` maps ℤⁿ onto ℤⁿ) with
   ``z = Zᵀ a``, ``Q_z = Zᵀ Q Z`` nearly diagonal and its conditional variances in
   decreasing-to-increasing order (De Jonge & Tiberius 1996, *The LAMBDA method for integer
   ambiguity estimation: implementation aspects*, LGR series 12, sec. 3). We use the
   "reduction" of Chang, Yang & Zhou (2005, *MLAMBDA: a modified LAMBDA method for integer
   least-squares estimation*, J. Geodesy 79, sec. 3), which applies the Gauss
   transformations only where needed and restarts after each permutation.
2. **Search.** A depth-first enumeration of the integer points in the shrinking ellipsoid
   ``(ẑ − z)ᵀ Q_z⁻¹ (ẑ − z) ≤ χ²``, level by level with the conditional estimates
   ``ẑ_{k|k+1…n}`` and the Schnorr–Euchner zig-zag order (Chang et al. 2005, sec. 4); it
   keeps the ``p`` best points, and ``χ²`` shrinks to the worst kept one.

**Validation.** The ratio test accepts the best candidate when
``‖â − ǎ₂‖²_Q / ‖â − ǎ₁‖²_Q ≥ c`` (Euler & Schaffrin 1991; Verhagen & Teunissen 2013,
*The ratio test for future GNSS ambiguity resolution*, GPS Solutions 17). The success rate of
integer bootstrapping on the decorrelated ambiguities,

``P_B = ∏ᵢ [2 Φ(1 / (2 √dᵢ)) − 1]``,

with ``dᵢ`` the conditional variances of ``Q_z``, is a sharp lower bound of the ILS success
rate (Teunissen 1999, *An optimality property of the integer least-squares estimator*,
J. Geodesy 73).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.special import erf

__all__ = [
    "IntegerEstimate",
    "bootstrapped_success_rate",
    "decorrelate",
    "integer_search",
    "lambda_method",
    "ldl",
]


def ldl(q: Any) -> tuple[np.ndarray, np.ndarray]:
    """Factor ``Q = Lᵀ diag(D) L`` with ``L`` unit lower triangular (De Jonge & Tiberius 1996).

    The factorisation runs from the last row up, so ``D[i]`` is the variance of ``aᵢ``
    conditioned on ``a_{i+1} … a_n``.

    Parameters
    ----------
    q : (n, n) array_like
        Symmetric positive definite covariance.

    Returns
    -------
    L : (n, n) numpy.ndarray
    D : (n,) numpy.ndarray

    Raises
    ------
    numpy.linalg.LinAlgError
        ``Q`` is not positive definite.
    """
    a = np.array(q, dtype=float)
    n = a.shape[0]
    if a.shape != (n, n):
        raise ValueError(f"covariance must be square, got {a.shape}")
    lo = np.zeros((n, n))
    d = np.zeros(n)
    for i in range(n - 1, -1, -1):
        d[i] = a[i, i]
        if not d[i] > 0:
            raise np.linalg.LinAlgError("ambiguity covariance is not positive definite")
        row = a[i, : i + 1] / np.sqrt(d[i])
        a[:i, :i] -= np.outer(row[:i], row[:i])
        lo[i, : i + 1] = row / row[i]
    return lo, d


# The reduction and the search work on nested Python lists: for the handful of ambiguities of
# one epoch (n ≤ ~15) scalar list arithmetic is several times faster than numpy indexing.


def _gauss(lo: list[list[float]], z: list[list[float]], i: int, j: int) -> None:
    """Integer Gauss transformation making ``|L[i][j]| ≤ ½`` (in place)."""
    mu = round(lo[i][j])
    if mu:
        for r in range(i, len(lo)):
            lo[r][j] -= mu * lo[r][i]
        for row in z:
            row[j] -= mu * row[i]


def _permute(lo: list[list[float]], d: list[float], j: int, delta: float, z) -> None:
    """Swap ambiguities ``j`` and ``j + 1`` and update ``L``, ``D`` and ``Z`` (in place)."""
    eta = d[j] / delta
    lam = d[j + 1] * lo[j + 1][j] / delta
    d[j] = eta * d[j + 1]
    d[j + 1] = delta
    l10 = lo[j + 1][j]
    for c in range(j):
        a0, a1 = lo[j][c], lo[j + 1][c]
        lo[j][c] = a1 - l10 * a0
        lo[j + 1][c] = eta * a0 + lam * a1
    lo[j + 1][j] = lam
    for row in lo[j + 2 :]:
        row[j], row[j + 1] = row[j + 1], row[j]
    for row in z:
        row[j], row[j + 1] = row[j + 1], row[j]


def decorrelate(q: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """LAMBDA decorrelation (MLAMBDA reduction) of an ambiguity covariance.

    Parameters
    ----------
    q : (n, n) array_like
        Float-ambiguity covariance (cycles²).

    Returns
    -------
    Z : (n, n) numpy.ndarray
        Unimodular integer matrix; the decorrelated ambiguities are ``z = Zᵀ a``.
    L, D : numpy.ndarray
        ``Zᵀ Q Z = Lᵀ diag(D) L``.
    """
    lo_arr, d_arr = ldl(q)
    lo, d = lo_arr.tolist(), d_arr.tolist()
    n = len(d)
    z = np.eye(n).tolist()
    j = k = n - 2
    while j >= 0:
        if j <= k:
            for i in range(j + 1, n):
                _gauss(lo, z, i, j)
        delta = d[j] + lo[j + 1][j] ** 2 * d[j + 1]
        if delta + 1e-6 < d[j + 1]:
            _permute(lo, d, j, delta, z)
            k = j
            j = n - 2
        else:
            j -= 1
    return np.array(z), np.array(lo), np.array(d)


def integer_search(
    z_float: Any, lo: Any, d: Any, candidates: int = 2, max_steps: int = 1_000_000
) -> tuple[np.ndarray, np.ndarray]:
    """The ``candidates`` integer vectors closest to ``ẑ`` in the metric ``(Lᵀ D L)⁻¹``.

    Depth-first search with a shrinking ellipsoid (Chang, Yang & Zhou 2005, sec. 4).

    Parameters
    ----------
    z_float : (n,) array_like
        Float (decorrelated) ambiguities ``ẑ``.
    lo, d : numpy.ndarray
        ``Q_z = Lᵀ diag(D) L`` from :func:`decorrelate`.
    candidates : int
        Number of best integer vectors to return (``≥ 1``).
    max_steps : int
        Guard against runaway searches.

    Returns
    -------
    integers : (candidates, n) numpy.ndarray
        Best first.
    squared_norms : (candidates,) numpy.ndarray
        ``(ẑ − z)ᵀ Q_z⁻¹ (ẑ − z)`` of each.
    """
    zs = [float(v) for v in np.asarray(z_float, dtype=float)]
    lo = np.asarray(lo, dtype=float).tolist()
    d = [float(v) for v in np.asarray(d, dtype=float)]
    n = len(zs)
    if candidates < 1:
        raise ValueError("candidates must be >= 1")
    s_mat = [[0.0] * n for _ in range(n)]
    dist = [0.0] * n
    zb = [0.0] * n
    z = [0.0] * n
    step = [0.0] * n
    found: list[list[float]] = [[0.0] * n for _ in range(candidates)]
    norms = [math.inf] * candidates
    count = 0
    worst = 0
    max_dist = math.inf

    k = n - 1
    zb[k] = zs[k]
    z[k] = float(round(zb[k]))
    y = zb[k] - z[k]
    step[k] = -1.0 if y <= 0 else 1.0
    for _ in range(max_steps):
        new_dist = dist[k] + y * y / d[k]
        if new_dist < max_dist:
            if k != 0:
                k -= 1
                dist[k] = new_dist
                shift = z[k + 1] - zb[k + 1]
                above, row, lk1 = s_mat[k + 1], s_mat[k], lo[k + 1]
                for c in range(k + 1):
                    row[c] = above[c] + shift * lk1[c]
                zb[k] = zs[k] + row[k]
                z[k] = float(round(zb[k]))
                y = zb[k] - z[k]
                step[k] = -1.0 if y <= 0 else 1.0
            else:
                if count < candidates:
                    if count == 0 or new_dist > norms[worst]:
                        worst = count
                    found[count] = z.copy()
                    norms[count] = new_dist
                    count += 1
                else:
                    if new_dist < norms[worst]:
                        found[worst] = z.copy()
                        norms[worst] = new_dist
                        worst = max(range(candidates), key=norms.__getitem__)
                    max_dist = norms[worst]
                z[0] += step[0]
                y = zb[0] - z[0]
                step[0] = -step[0] - (-1.0 if step[0] <= 0 else 1.0)
        else:
            if k == n - 1:
                break
            k += 1
            z[k] += step[k]
            y = zb[k] - z[k]
            step[k] = -step[k] - (-1.0 if step[k] <= 0 else 1.0)
    else:
        raise RuntimeError(f"integer search did not finish in {max_steps} steps")
    order = np.argsort(norms, kind="stable")
    return np.array(found)[order], np.array(norms)[order]


def bootstrapped_success_rate(conditional_variances: Any) -> float:
    """Integer-bootstrapping success rate ``∏ [2Φ(1/(2√dᵢ)) − 1]`` (Teunissen 1998).

    Evaluated on the decorrelated conditional variances it is a lower bound of the ILS
    success rate (Teunissen 1999).

    Parameters
    ----------
    conditional_variances : (n,) array_like
        ``D`` of ``Q_z = Lᵀ D L`` (cycles²).

    Returns
    -------
    float
    """
    d = np.asarray(conditional_variances, dtype=float)
    return float(np.prod(erf(1.0 / (2.0 * np.sqrt(2.0 * d)))))


@dataclass(frozen=True)
class IntegerEstimate:
    """Result of :func:`lambda_method`.

    Attributes
    ----------
    candidates : (p, n) numpy.ndarray
        The ``p`` best integer vectors (original ambiguities), best first.
    squared_norms : (p,) numpy.ndarray
        ``(â − ǎᵢ)ᵀ Q⁻¹ (â − ǎᵢ)``.
    z_transform : (n, n) numpy.ndarray
        The unimodular decorrelating matrix ``Z`` (``z = Zᵀ a``).
    conditional_variances : (n,) numpy.ndarray
        ``D`` of the decorrelated covariance ``Zᵀ Q Z = Lᵀ D L``.
    """

    candidates: np.ndarray
    squared_norms: np.ndarray
    z_transform: np.ndarray
    conditional_variances: np.ndarray

    @property
    def best(self) -> np.ndarray:
        """The ILS estimate ``ǎ``."""
        return self.candidates[0]

    @property
    def ratio(self) -> float:
        """``‖â − ǎ₂‖² / ‖â − ǎ₁‖²`` (``inf`` when ``â`` is an integer vector)."""
        if len(self.squared_norms) < 2:
            raise ValueError("the ratio needs two candidates")
        best, second = self.squared_norms[:2]
        return float(second / best) if best > 0 else float("inf")

    @property
    def success_rate(self) -> float:
        """Bootstrapped success rate of the decorrelated problem (a lower bound of ILS's)."""
        return bootstrapped_success_rate(self.conditional_variances)

    def accepted(self, ratio_threshold: float, min_success_rate: float = 0.0) -> bool:
        """Ratio test ``ratio ≥ c`` and success-rate bound ``P_B ≥ min_success_rate``."""
        return self.ratio >= ratio_threshold and self.success_rate >= min_success_rate


def lambda_method(a_float: Any, q: Any, candidates: int = 2) -> IntegerEstimate:
    """Integer least-squares ambiguities by LAMBDA (decorrelation, then search).

    Parameters
    ----------
    a_float : (n,) array_like
        Float ambiguities (cycles).
    q : (n, n) array_like
        Their covariance (cycles²), symmetric positive definite.
    candidates : int
        Number of best integer vectors to return (2 for the ratio test).

    Returns
    -------
    IntegerEstimate
    """
    a = np.asarray(a_float, dtype=float)
    q = np.asarray(q, dtype=float)
    if q.shape != (len(a), len(a)):
        raise ValueError(f"covariance {q.shape} does not match {len(a)} ambiguities")
    # Search around the nearest integers: the fractional parts keep the search well scaled.
    shift = np.rint(a)
    z_mat, lo, d = decorrelate(0.5 * (q + q.T))
    z_float = z_mat.T @ (a - shift)
    found, norms = integer_search(z_float, lo, d, candidates)
    original = np.rint(np.linalg.solve(z_mat.T, found.T).T) + shift
    return IntegerEstimate(original, norms, z_mat, d)
