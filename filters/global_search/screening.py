"""Candidate initial states and their screening: uniform (scrambled Sobol') and prior
draws, ranked by a robust misfit on a short window.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import torch

from filters.global_search.problem import (
    BatchProblem,
    Candidates,
    Count,
    Prior,
)


def uniform_rates(n: int, omega_max: float, rng: np.random.Generator) -> np.ndarray:
    """Body rates uniform in the ball ``|ω| ≤ omega_max`` (rad/s), shape (n, 3)."""
    return _ball(rng.random((n, 3)), omega_max)


def _ball(u: np.ndarray, radius: float) -> np.ndarray:
    """Map uniform ``u ∈ [0, 1)³`` to the ball: radius ``R u₀^{1/3}``, direction from
    ``cos θ = 1 − 2u₁``, ``φ = 2π u₂`` (volume preserving)."""
    r = radius * u[:, 0] ** (1.0 / 3.0)
    cos_t = 1.0 - 2.0 * u[:, 1]
    sin_t = np.sqrt(np.clip(1.0 - cos_t**2, 0.0, None))
    phi = 2.0 * np.pi * u[:, 2]
    return r[:, None] * np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t], axis=1)


def _shoemake(u: np.ndarray) -> np.ndarray:
    """Map uniform ``u ∈ [0, 1)³`` to a uniform attitude (Shoemake 1992, *Graphics Gems
    III*): ``q = [√(1−u₀) sin 2πu₁, √(1−u₀) cos 2πu₁, √u₀ sin 2πu₂, √u₀ cos 2πu₂]``."""
    a, b = np.sqrt(1.0 - u[:, 0]), np.sqrt(u[:, 0])
    t1, t2 = 2.0 * np.pi * u[:, 1], 2.0 * np.pi * u[:, 2]
    return np.stack([a * np.sin(t1), a * np.cos(t1), b * np.sin(t2), b * np.cos(t2)], axis=1)


def low_discrepancy_states(
    n: int, omega_max: float, rng: np.random.Generator, extra_dims: int = 0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Attitudes uniform on SO(3) and rates uniform in the ball from a scrambled Sobol'
    sequence (scipy.stats.qmc): the gaps a random sample leaves in the 6-D search space
    shrink, so fewer candidates cover it equally well.

    Returns
    -------
    q : (n, 4), omega : (n, 3), extra : (n, extra_dims) uniform in [0, 1)
    """
    from scipy.stats import qmc

    sobol = qmc.Sobol(6 + extra_dims, scramble=True, seed=rng)
    u = sobol.random_base2(max(0, math.ceil(math.log2(n))))[:n]
    return _shoemake(u[:, :3]), _ball(u[:, 3:6], omega_max), u[:, 6:]


def _best(cost: torch.Tensor, shape: torch.Tensor, count: Count, per_shape: bool) -> torch.Tensor:
    """Indices of the ``count`` lowest costs, overall or for every shape index (``count``
    may then be an array over the shape indices). Equal costs keep candidate order (stable
    sorts here and below: an unstable sort leaves the order of ties to the sorting kernel of
    the processor)."""
    if not per_shape:
        return torch.argsort(cost, stable=True)[:count]
    picks = []
    for s in torch.unique(shape):
        rows = torch.nonzero(shape == s).flatten()
        picks.append(rows[torch.argsort(cost[rows], stable=True)[: _count(count, s)]])
    return torch.cat(picks)


def _count(count: Count, shape: Any) -> int:
    """The count of one shape index from a count shared by all or one per shape."""
    return int(count) if np.ndim(count) == 0 else int(count[int(shape)])


def _robust_cost(r: torch.Tensor, nu: float) -> torch.Tensor:
    """Student-t negative log-likelihood ``Σ (ν + 1)/2 · ln(1 + r²/ν)`` per row."""
    return 0.5 * (nu + 1.0) * torch.log1p(r * r / nu).sum(dim=-1)


def uniform_candidates(
    problem: BatchProblem,
    n: int,
    omega_max: float,
    rng: np.random.Generator,
    n_shapes: int = 1,
    k_range: float = 1.5,
) -> Candidates:
    """Candidates uniform on SO(3), in the rate ball ``|ω| ≤ omega_max``, over the shapes
    (and in ``[−k_range, k_range]²`` for the tanh inertia when it is estimated), from a
    scrambled Sobol' sequence (:func:`low_discrepancy_states`).
    """
    extra = 3 if problem.estimate_inertia else 1
    q, w, u = low_discrepancy_states(n, omega_max, rng, extra)
    shape = torch.as_tensor(np.minimum((u[:, 0] * n_shapes).astype(int), n_shapes - 1))
    k = None
    if problem.has_inertia_prior:  # each shape's own inertia: the prior's mean
        k = torch.as_tensor(problem.k_mean[shape.numpy()], dtype=problem.dtype)
    elif problem.estimate_inertia:
        k = torch.as_tensor(k_range * (2.0 * u[:, 1:3] - 1.0), dtype=problem.dtype)
    return Candidates(
        q=torch.as_tensor(q, dtype=problem.dtype),
        omega=torch.as_tensor(w, dtype=problem.dtype),
        shape=shape,
        k=k,
    )


def prior_candidates(
    problem: BatchProblem,
    n: int,
    prior: Prior,
    rng: np.random.Generator,
    shapes: Sequence[int] = (0,),
    k: Any = None,
) -> Candidates:
    """``n`` draws from a Gaussian prior for each listed shape (the prior mean first),
    ``n · len(shapes)`` candidates."""
    q, w = prior.sample(n, rng)
    rows = len(shapes) * n
    kk = None
    if problem.estimate_inertia:
        if k is not None:
            k0 = np.broadcast_to(np.asarray(k, float), (rows, 2))
        elif problem.has_inertia_prior:
            k0 = problem.k_mean[np.repeat(np.asarray(shapes), n)]
        else:
            k0 = np.zeros((rows, 2))
        kk = torch.as_tensor(np.array(k0), dtype=problem.dtype)
    return Candidates(
        q=torch.as_tensor(np.tile(q, (len(shapes), 1)), dtype=problem.dtype),
        omega=torch.as_tensor(np.tile(w, (len(shapes), 1)), dtype=problem.dtype),
        shape=torch.as_tensor(np.repeat(np.asarray(shapes), n), dtype=torch.long),
        k=kk,
    )


def screen(
    problem: BatchProblem,
    candidates: Candidates,
    duration: float,
    keep: int,
    *,
    stages: Sequence[int] = (8, 24),
    fraction: float = 0.1,
    batch: int = 8192,
    nu: float = 4.0,
    prior: Prior | None = None,
    tolerance: float = 0.0,
    per_shape: bool = False,
) -> Candidates:
    """Successive screening: returns the ``keep`` candidates of lowest misfit.

    Stage ``i`` evaluates the survivors on ``stages[i]`` epochs spread over ``duration``
    seconds and keeps the best ``fraction`` of them (at least ``keep``). The misfit is the
    Student-t negative log-likelihood of the normalised residuals (plus ``½|r_prior|²``
    with a prior). With ``tolerance > 0`` the residuals are normalised by
    ``√(σ² + tolerance²)`` instead of ``σ``: a candidate 10° off then scores better than one
    90° off instead of both scoring "terrible", which widens the basin the screening sees.

    Parameters
    ----------
    problem : BatchProblem
    candidates : Candidates
        As from :func:`uniform_candidates`.
    duration : float
        Window (s).
    keep : int
        Survivors of the last stage.
    tolerance : float
        Model tolerance added in quadrature to the measurement errors (measurement units).
    per_shape : bool
        Keep the best of every shape index (``keep`` each) rather than the best overall.

    Returns
    -------
    Candidates
    """
    for i, n_epochs in enumerate(stages):
        epochs = problem.window(duration, n_epochs)
        costs = []
        for s in range(0, len(candidates), batch):
            part = candidates.take(slice(s, s + batch))
            r = problem.residuals(part.q, part.omega, part.k, part.shape, epochs)
            if tolerance > 0.0:
                sigma = problem.sigma[epochs]
                r = r * torch.as_tensor(sigma / np.sqrt(sigma**2 + tolerance**2), dtype=r.dtype)
            cost = _robust_cost(r, nu)
            if prior is not None:
                cost = cost + 0.5 * (prior.residuals(part.q, part.omega) ** 2).sum(dim=1)
            costs.append(cost)
        cost = torch.nan_to_num(torch.cat(costs), nan=math.inf)
        survivors = keep if i == len(stages) - 1 else max(keep, int(len(candidates) * fraction))
        if per_shape and i < len(stages) - 1:
            shapes = max(1, len(torch.unique(candidates.shape)))
            survivors = max(keep, int(len(candidates) * fraction / shapes))
        candidates = candidates.take(_best(cost, candidates.shape, survivors, per_shape))
    return candidates
