"""Gaussian estimation algebra shared by the EKFs and UKFs of this package.

Small functions over numpy arrays: the Kalman gain, the Joseph-form covariance update, the
normalised estimation/innovation errors (squared Mahalanobis distances) and their chi-square
consistency bands, and the discretisation of continuous process noise. The filters
(``navigation``, ``planning``, ``ukf``, ``mmae``) call these rather than re-deriving them.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy import stats

__all__ = [
    "chi2_band",
    "discrete_process_noise",
    "joseph_update",
    "kalman_gain",
    "mahalanobis_squared",
]


def _t(a: np.ndarray) -> np.ndarray:
    return np.swapaxes(a, -1, -2)


def kalman_gain(p: np.ndarray, h: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Kalman gain ``K = P Hᵀ S⁻¹`` and innovation covariance ``S = H P Hᵀ + R``.

    Broadcasts over leading (batch) dimensions, e.g. Monte Carlo runs.

    Parameters
    ----------
    p : (..., n, n) array
        Prior covariance.
    h : (..., m, n) array
        Measurement Jacobian.
    r : (..., m, m) array
        Measurement noise covariance.

    Returns
    -------
    gain : (..., n, m) numpy.ndarray
    innovation_covariance : (..., m, m) numpy.ndarray
    """
    s = h @ p @ _t(h) + r
    s = 0.5 * (s + _t(s))
    gain = _t(np.linalg.solve(s, h @ p))  # S symmetric: K = (S⁻¹ H P)ᵀ
    return gain, s


def joseph_update(p: np.ndarray, gain: np.ndarray, h: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Joseph-form covariance update ``(I − K H) P (I − K H)ᵀ + K R Kᵀ``.

    Stays symmetric positive semi-definite for any gain, unlike ``(I − K H) P``. Broadcasts
    over leading dimensions.

    Parameters
    ----------
    p : (..., n, n) array
    gain : (..., n, m) array
    h : (..., m, n) array
    r : (..., m, m) array

    Returns
    -------
    (..., n, n) numpy.ndarray
    """
    i_kh = np.eye(p.shape[-1]) - gain @ h
    out = i_kh @ p @ _t(i_kh) + gain @ r @ _t(gain)
    return 0.5 * (out + _t(out))


def mahalanobis_squared(error: Any, covariance: Any) -> np.ndarray:
    """Squared Mahalanobis distance ``eᵀ P⁻¹ e`` (NEES for state errors, NIS for innovations).

    Parameters
    ----------
    error : (..., n) array
    covariance : (..., n, n) array

    Returns
    -------
    (...) numpy.ndarray
    """
    e = np.asarray(error, dtype=float)
    c = np.asarray(covariance, dtype=float)
    solved = np.linalg.solve(c, e[..., None])[..., 0]
    return np.sum(e * solved, axis=-1)


def chi2_band(dof: int, runs: int = 1, confidence: float = 0.95) -> tuple[float, float]:
    """Two-sided chi-square acceptance band for the mean of ``runs`` NEES/NIS samples.

    The sum of ``runs`` independent ``χ²(dof)`` values is ``χ²(runs·dof)``; the band for the
    average is that distribution's quantiles divided by ``runs`` (Bar-Shalom et al. 2001,
    sec. 5.4).

    Parameters
    ----------
    dof : int
        Degrees of freedom of one sample (state or measurement dimension).
    runs : int
        Number of independent samples averaged.
    confidence : float
        Two-sided probability mass inside the band.

    Returns
    -------
    (lower, upper) : tuple of float
    """
    tail = 0.5 * (1 - confidence)
    total = dof * runs
    return (
        float(stats.chi2.ppf(tail, total) / runs),
        float(stats.chi2.ppf(1 - tail, total) / runs),
    )


def discrete_process_noise(
    a: np.ndarray, q: np.ndarray, dt: float
) -> tuple[np.ndarray, np.ndarray]:
    """Discretise ``ẋ = A x + w``, ``E[w wᵀ] = Q δ(t)`` exactly (Van Loan 1978).

    Broadcasts over leading dimensions (one system per Monte Carlo run, say); the matrix
    exponential is the attitude core's batched :func:`~filters.attitude.transition_matrix`.

    Parameters
    ----------
    a : (..., n, n) array
        Continuous system matrix.
    q : (..., n, n) array
        Continuous process-noise spectral density.
    dt : float
        Step (s).

    Returns
    -------
    phi : (..., n, n) numpy.ndarray
        ``exp(A Δt)``.
    q_discrete : (..., n, n) numpy.ndarray
        ``∫₀^Δt exp(A s) Q exp(A s)ᵀ ds``.
    """
    from filters.attitude.jacobians import transition_matrix

    a, q = np.broadcast_arrays(np.asarray(a, float), np.asarray(q, float))
    n = a.shape[-1]
    block = np.zeros((*a.shape[:-2], 2 * n, 2 * n))
    block[..., :n, :n] = -a
    block[..., :n, n:] = q
    block[..., n:, n:] = _t(a)
    e = transition_matrix(block, dt)
    phi = _t(e[..., n:, n:])
    q_d = phi @ e[..., :n, n:]
    return phi, 0.5 * (q_d + _t(q_d))
