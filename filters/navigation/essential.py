"""Two-view geometry: the essential matrix of a frame pair and the relative pose in it.

Matched normalised image points of a rigid body seen from one camera in two frames satisfy
the epipolar constraint ``x₂ᵀ E x₁ = 0`` with ``E = [t_Δ×] R_Δ`` (Deng et al. 2024, eq. 3).
This module holds the two first steps of :mod:`filters.navigation.epipolar`:

1. the Hartley-normalised eight-point estimate of ``E`` (Hartley 1997), batched over RANSAC
   hypotheses; inliers by the Sampson distance with an adaptive number of samples (MSAC
   scoring, with local refits: LO-RANSAC);
2. the decomposition ``E = U diag(1, 1, 0) Vᵀ`` into four ``(R, t)`` candidates and the
   cheirality check (triangulated points in front of both cameras; Hartley & Zisserman
   2004, sec. 9.6).

References
----------
Hartley, R. I. (1997). In defense of the eight-point algorithm. *IEEE Trans. Pattern
Analysis and Machine Intelligence* 19(6), 580–593.
Hartley, R. & Zisserman, A. (2004). *Multiple View Geometry in Computer Vision*, 2nd ed.
Cambridge University Press.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from filters.attitude.arrays import as_arrays

__all__ = [
    "EpipolarError",
    "decompose_essential",
    "eight_point",
    "homogeneous",
    "pose_from_essential",
    "ransac_essential",
    "sampson_error",
]

_MIN_POINTS = 8
_LOCAL_STEPS = 4  # LO-RANSAC refits per improvement


class EpipolarError(ValueError):
    """A frame pair from which no relative pose can be recovered."""


def homogeneous(x: np.ndarray) -> np.ndarray:
    """``[x, 1]``: image points (..., 2) as homogeneous 3-vectors."""
    return np.concatenate([x, np.ones_like(x[..., :1])], axis=-1)


def _normalising_transform(x: np.ndarray) -> np.ndarray:
    """Hartley's similarity: centroid to the origin, mean distance √2."""
    centre = np.mean(x, axis=-2)
    dist = np.mean(np.linalg.norm(x - centre[..., None, :], axis=-1), axis=-1)
    s = math.sqrt(2.0) / np.maximum(dist, 1e-300)
    t = np.zeros((*x.shape[:-2], 3, 3))
    t[..., 0, 0] = t[..., 1, 1] = s
    t[..., :2, 2] = -s[..., None] * centre
    t[..., 2, 2] = 1.0
    return t


def eight_point(x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
    """Normalised eight-point essential matrix, batched.

    Parameters
    ----------
    x1, x2 : (..., N, 2) array_like
        Matched normalised image coordinates (``N ≥ 8``) in the first and second frame.

    Returns
    -------
    (..., 3, 3) numpy.ndarray
        ``E`` with singular values ``(1, 1, 0)`` and ``x₂ᵀ E x₁ ≈ 0``.
    """
    x1 = np.asarray(x1, dtype=float)
    x2 = np.asarray(x2, dtype=float)
    if x1.shape[-2] < _MIN_POINTS:
        raise EpipolarError(f"the eight-point algorithm needs >= 8 matches, got {x1.shape[-2]}")
    t1, t2 = _normalising_transform(x1), _normalising_transform(x2)
    y1 = homogeneous(x1) @ np.swapaxes(t1, -1, -2)
    y2 = homogeneous(x2) @ np.swapaxes(t2, -1, -2)
    # Each match gives one row kron(y2, y1) of A e = 0 (e = E row-major).
    a = (y2[..., :, :, None] * y1[..., :, None, :]).reshape(*y1.shape[:-1], 9)
    # With exactly eight rows the null vector is the ninth right singular vector (full
    # matrices); with more, the thin decomposition already holds it and is much cheaper.
    _, _, vt = np.linalg.svd(a, full_matrices=a.shape[-2] < 9)
    e = vt[..., -1, :].reshape(*a.shape[:-2], 3, 3)
    e = np.swapaxes(t2, -1, -2) @ e @ t1
    u, _, vt = np.linalg.svd(e)
    return u @ np.diag([1.0, 1.0, 0.0]) @ vt


def sampson_error(essential: Any, x1: Any, x2: Any) -> Any:
    """Signed Sampson error ``x₂ᵀEx₁ / ‖(Ex₁)₁,₂, (Eᵀx₂)₁,₂‖`` (normalised image units).

    Its square is the first-order geometric distance of a match to the epipolar geometry;
    multiply by the focal length for pixels.

    Parameters
    ----------
    essential : (..., 3, 3) array
    x1, x2 : (..., N, 2) array
        Normalised image coordinates (numpy or torch, broadcastable).

    Returns
    -------
    (..., N) array
    """
    xp, (e, x1, x2) = as_arrays(essential, x1, x2)
    one = xp.ones_like(x1[..., :1])
    y1 = xp.concat([x1, one], axis=-1)
    y2 = xp.concat([x2, xp.ones_like(x2[..., :1])], axis=-1)
    ex1 = y1 @ xp.matrix_transpose(e)
    etx2 = y2 @ e
    num = xp.sum(y2 * ex1, axis=-1)
    den = xp.sqrt(ex1[..., 0] ** 2 + ex1[..., 1] ** 2 + etx2[..., 0] ** 2 + etx2[..., 1] ** 2)
    return num / den


def ransac_essential(
    x1: np.ndarray,
    x2: np.ndarray,
    *,
    threshold: float,
    rng: np.random.Generator,
    confidence: float = 0.999,
    max_iterations: int = 2000,
    batch: int = 64,
) -> tuple[np.ndarray, np.ndarray]:
    """Robust essential matrix by RANSAC over eight-point hypotheses (MSAC scoring).

    Parameters
    ----------
    x1, x2 : (N, 2) array_like
        Matched normalised image coordinates.
    threshold : float
        Inlier threshold on the Sampson error, normalised units (pixels / focal length).
    rng : numpy.random.Generator
    confidence : float
        Probability of drawing at least one all-inlier sample; sets the sample count.
    max_iterations : int
        Cap on the number of hypotheses.
    batch : int
        Hypotheses evaluated together.

    Returns
    -------
    essential : (3, 3) numpy.ndarray
        The best hypothesis after local optimisation (the linear fit to *all* inliers can be
        worse than a minimal sample in near-degenerate views, so it is not forced).
    inliers : (N,) numpy.ndarray of bool

    Raises
    ------
    EpipolarError
        Fewer than eight matches or fewer than eight inliers.
    """
    x1 = np.asarray(x1, dtype=float)
    x2 = np.asarray(x2, dtype=float)
    n = x1.shape[0]
    if n < _MIN_POINTS:
        raise EpipolarError(f"{n} matches; at least 8 are needed")
    best_cost, best_e = np.inf, None
    needed, done = max_iterations, 0
    thr2 = threshold**2
    while done < min(needed, max_iterations):
        sample = np.argsort(rng.random((batch, n)), axis=1)[:, :_MIN_POINTS]
        hyp = eight_point(x1[sample], x2[sample])
        d2 = sampson_error(hyp, x1, x2) ** 2
        cost = np.sum(np.minimum(d2, thr2), axis=1)
        i = int(np.argmin(cost))
        if cost[i] < best_cost:
            best_cost, best_e = cost[i], hyp[i]
            # Local optimisation (LO-RANSAC): refit on the consensus set while it improves.
            for _ in range(_LOCAL_STEPS):
                inl = sampson_error(best_e, x1, x2) ** 2 < thr2
                if inl.sum() < _MIN_POINTS:
                    break
                e_lo = eight_point(x1[inl], x2[inl])
                c_lo = float(np.sum(np.minimum(sampson_error(e_lo, x1, x2) ** 2, thr2)))
                if c_lo >= best_cost:
                    break
                best_cost, best_e = c_lo, e_lo
            w = np.mean(sampson_error(best_e, x1, x2) ** 2 < thr2)
            fail = 1.0 - w**_MIN_POINTS
            needed = 0 if fail <= 0 else math.ceil(math.log(1 - confidence) / math.log(fail))
        done += batch
    inliers = sampson_error(best_e, x1, x2) ** 2 < thr2
    if inliers.sum() < _MIN_POINTS:
        raise EpipolarError(f"RANSAC found only {int(inliers.sum())} inliers of {n} matches")
    return best_e, inliers


def decompose_essential(essential: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """The four ``(R, t)`` with ``E ∝ [t×] R`` (``|t| = 1``).

    Parameters
    ----------
    essential : (3, 3) array_like

    Returns
    -------
    list of (R (3, 3), t (3,))
    """
    u, _, vt = np.linalg.svd(np.asarray(essential, dtype=float))
    u = u * np.sign(np.linalg.det(u))
    vt = vt * np.sign(np.linalg.det(vt))
    w = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    r1, r2 = u @ w @ vt, u @ w.T @ vt
    t = u[:, 2]
    return [(r1, t), (r1, -t), (r2, t), (r2, -t)]


def _depths(r: np.ndarray, t: np.ndarray, x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
    """Least-squares depths ``(z₁, z₂)`` with ``z₁ R x₁ + t = z₂ x₂`` for every match."""
    a1 = homogeneous(x1) @ r.T
    a2 = -homogeneous(x2)
    # Normal equations of [a1 a2] [z1 z2]ᵀ = −t, one 2×2 system per match.
    m = np.stack(
        [
            np.stack([np.sum(a1 * a1, -1), np.sum(a1 * a2, -1)], -1),
            np.stack([np.sum(a2 * a1, -1), np.sum(a2 * a2, -1)], -1),
        ],
        -2,
    )
    rhs = -np.stack([a1 @ t, a2 @ t], -1)
    return np.linalg.solve(m, rhs[..., None])[..., 0]


def pose_from_essential(
    essential: np.ndarray, x1: np.ndarray, x2: np.ndarray
) -> tuple[np.ndarray, np.ndarray, int]:
    """The decomposition that puts the most matches in front of both cameras.

    Parameters
    ----------
    essential : (3, 3) array_like
    x1, x2 : (N, 2) array_like
        Inlier matches (normalised coordinates).

    Returns
    -------
    rotation : (3, 3) numpy.ndarray
        ``R_Δ`` with ``P₂ = R_Δ P₁ + t``.
    translation : (3,) numpy.ndarray
        Unit ``t`` (direction only).
    in_front : int
        Matches passing the cheirality check.
    """
    best = None
    for r, t in decompose_essential(essential):
        z = _depths(r, t, np.asarray(x1, float), np.asarray(x2, float))
        count = int(np.sum((z[:, 0] > 0) & (z[:, 1] > 0)))
        if best is None or count > best[2]:
            best = (r, t, count)
    return best
