"""Nonlinear observability: Lie-derivative rank test and Fisher information over a trajectory.

Generic over the system: every function takes the dynamics ``f(x)`` (or a discrete step
``x ↦ x⁺``) and the measurement ``h(x)`` as torch callables, so the monocular EKF, the
observation planner and the stereo / relative-navigation filters share one implementation.
Derivatives come from ``torch.func`` automatic differentiation, never finite differences.

Rank test (Hermann & Krener 1977; Deng et al. 2024, eqs. 19–23)
-----------------------------------------------------
``L⁰h = h``, ``Lᵏh = (∂Lᵏ⁻¹h/∂x) f`` and the observability matrix
``Q_k = [dL⁰h; dL¹h; …; dLᵏh]``. The system is locally weakly observable at ``x`` when
``rank Q_k = n`` for some ``k ≤ n − 1``. Lie derivatives are nested Jacobian-vector products
(exact to rounding; cost grows about threefold per order, so orders above ~7 take minutes).
States on a manifold (a unit quaternion) enter through a *chart* ``δ ↦ x`` so that the rank
is counted in the ``n`` local coordinates.

The rank decision is numerical: each row of ``Q_k`` is scaled to unit norm (rows of
successive orders differ by powers of the rates), the columns by caller-given state scales,
and the rank is the number of singular values above ``rtol · σ_max``. The singular values
and the null space (the unobservable directions) are returned so the gap can be inspected.

Fisher information / observability Gramian
------------------------------------------
Along a trajectory ``x_0 … x_K`` with steps ``x_{k+1} = φ(x_k)``, the sensitivity
``S_k = ∂x_k/∂δ₀`` obeys ``S_{k+1} = (∂φ/∂x)(x_k) S_k`` and the information about the
initial state carried by measurements with noise covariance ``R`` is
``W = Σ_k S_kᵀ H_kᵀ R⁻¹ H_k S_k`` (the discrete observability Gramian). Its inverse bounds the
covariance of any unbiased estimator (Cramér–Rao), so ``√diag(W⁻¹)`` is a continuous measure
of how well each state can be known; directions with (near-)zero eigenvalues are
unobservable over that trajectory.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import torch
from torch.func import jacfwd, jvp, vmap

__all__ = [
    "Chart",
    "RankTest",
    "canonical_basis",
    "fisher_information",
    "information_sigmas",
    "lie_derivatives",
    "observability_gramian",
    "observability_matrix",
    "observability_rank",
    "rank_test",
    "step_jacobians",
]

Function = Callable[[torch.Tensor], torch.Tensor]


@dataclass(frozen=True)
class Chart:
    """Local coordinates ``δ ∈ ℝᵖ`` around a state: ``embed(δ)`` is a state, ``embed(0)`` the point.

    Attributes
    ----------
    dim : int
        Number of local coordinates ``p``.
    embed : callable
        ``δ (p,) torch.Tensor → x (n,) torch.Tensor``, differentiable.
    """

    dim: int
    embed: Function


def _stacked_lie(f: Function, h: Function, order: int) -> Function:
    """``x ↦ [L⁰h(x), …, L^order h(x)]`` concatenated, by nested JVPs."""

    def level0(x: torch.Tensor) -> torch.Tensor:
        return h(x).reshape(-1)

    g = level0
    for level in range(1, order + 1):

        def g(x: torch.Tensor, inner: Function = g, level: int = level) -> torch.Tensor:
            # inner(x) = [L⁰h, …, L^(level−1)h]; its derivative along f is [L¹h, …, L^level h].
            values, tangents = jvp(inner, (x,), (f(x),))
            return torch.cat([values[: values.shape[0] // level], tangents])

    return g


def lie_derivatives(f: Function, h: Function, x: torch.Tensor, order: int) -> torch.Tensor:
    """Lie derivatives ``Lᵏ_f h(x)`` for ``k = 0 … order`` (Deng et al. 2024, eq. 19).

    Parameters
    ----------
    f : callable
        ``(n,) → (n,)`` vector field.
    h : callable
        ``(n,) → (m,)`` measurement function.
    x : (n,) torch.Tensor
        Point of evaluation (float64 recommended).
    order : int
        Highest order ``k ≥ 0``.

    Returns
    -------
    (order + 1, m) torch.Tensor
    """
    if order < 0:
        raise ValueError(f"Lie-derivative order must be >= 0, got {order}")
    values = _stacked_lie(f, h, order)(x)
    return values.reshape(order + 1, -1)


def observability_matrix(
    f: Function,
    h: Function,
    x: torch.Tensor,
    order: int,
    chart: Chart | None = None,
) -> torch.Tensor:
    """The matrix ``Q_k = [dL⁰h; …; dLᵏh]`` (Deng et al. 2024, eq. 20), optionally in a chart.

    Parameters
    ----------
    f, h : callable
        Vector field and measurement on the (embedding) state.
    x : (n,) torch.Tensor
        Point of evaluation; with a chart it must equal ``chart.embed(0)``.
    order : int
        Highest Lie-derivative order ``k``.
    chart : Chart, optional
        Local coordinates around ``x`` (e.g. a multiplicative quaternion error); the rows are
        then ``dLʲh · ∂x/∂δ``.

    Returns
    -------
    ((order + 1) m, p) torch.Tensor
    """
    stacked = _stacked_lie(f, h, order)
    if chart is None:
        return jacfwd(stacked)(x)
    delta0 = torch.zeros(chart.dim, dtype=x.dtype, device=x.device)
    return jacfwd(lambda d: stacked(chart.embed(d)))(delta0)


@dataclass(frozen=True)
class RankTest:
    """Outcome of a numerical rank decision.

    Attributes
    ----------
    rank : int
        Singular values above ``tolerance``.
    singular_values : (p,) numpy.ndarray
        Of the row-normalised, column-scaled matrix, descending (padded with zeros when the
        matrix has fewer rows than columns).
    tolerance : float
        Absolute threshold ``rtol · σ_max``.
    null_space : (p, p − rank) numpy.ndarray
        Orthonormal unobservable directions in the *unscaled* coordinates.
    order : int or None
        Lie-derivative order used, when the matrix came from :func:`observability_rank`.
    """

    rank: int
    singular_values: np.ndarray
    tolerance: float
    null_space: np.ndarray
    order: int | None = None

    @property
    def full(self) -> bool:
        """Whether the rank equals the number of states."""
        return self.rank == self.singular_values.size

    def unobservable_directions(
        self, names: Sequence[str], threshold: float = 1e-6
    ) -> list[dict[str, float]]:
        """The null-space basis as ``{state name: component}`` (components above threshold).

        Parameters
        ----------
        names : sequence of str
            One name per state (column).
        threshold : float
            Components with smaller magnitude are left out.

        Returns
        -------
        list of dict
            One dict per unobservable direction, in canonical form: the rows of the reduced
            row-echelon form of the null space's basis, so the result depends only on the
            null space itself, not on the basis the SVD happened to return (which varies
            with the BLAS kernels of the processor when singular values are degenerate).
            Directions are ordered by their leading state (state order), each has unit
            norm and a positive leading component; for a null space spanned by coordinate
            axes they are those axes, in state order.
        """
        out = []
        for v in canonical_basis(self.null_space).T:
            out.append({n: float(c) for n, c in zip(names, v, strict=True) if abs(c) > threshold})
        return out


def canonical_basis(basis: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    """The canonical (reduced row-echelon) basis of the column space of ``basis``.

    Gauss–Jordan elimination with partial pivoting on ``basisᵀ`` gives the reduced
    row-echelon form, which is unique for a given subspace: pivots are taken in column
    (state) order, each direction has zeros on the other directions' pivot states. Rows are
    then scaled to unit norm with a positive pivot.

    Parameters
    ----------
    basis : (p, k) array
        Columns spanning the subspace (e.g. an orthonormal null-space basis).
    tol : float
        Components below ``tol`` times the largest are treated as zero when choosing pivots.

    Returns
    -------
    (p, k) numpy.ndarray
        The canonical basis, columns ordered by their pivot.
    """
    rows = np.array(np.asarray(basis, dtype=float).T)
    k, p = rows.shape
    if k == 0:
        return rows.T
    threshold = tol * np.max(np.abs(rows))
    pivot_row = 0
    for column in range(p):
        if pivot_row == k:
            break
        candidate = pivot_row + int(np.argmax(np.abs(rows[pivot_row:, column])))
        if abs(rows[candidate, column]) <= threshold:
            rows[pivot_row:, column] = 0.0
            continue
        rows[[pivot_row, candidate]] = rows[[candidate, pivot_row]]
        rows[pivot_row] /= rows[pivot_row, column]
        others = np.arange(k) != pivot_row
        rows[others] -= np.outer(rows[others, column], rows[pivot_row])
        pivot_row += 1
    rows = rows[:pivot_row]
    rows /= np.linalg.norm(rows, axis=1, keepdims=True)
    return rows.T


def rank_test(
    matrix: torch.Tensor | np.ndarray, scales: Sequence[float] | None = None, rtol: float = 1e-9
) -> RankTest:
    """Numerical rank with row normalisation, column scaling and a relative tolerance.

    Parameters
    ----------
    matrix : (r, p) array
        Observability matrix (or any matrix whose column space is tested).
    scales : sequence of float, optional
        Characteristic magnitude of each state (column), e.g. rad/s for rates; columns are
        multiplied by them so that the singular values compare like with like.
    rtol : float
        Singular values below ``rtol · σ_max`` count as zero. The default 1e-9 sits between
        double-precision rounding of nested derivatives (~1e-14) and genuinely weak
        directions.

    Returns
    -------
    RankTest
    """
    a = matrix.detach().cpu().numpy() if isinstance(matrix, torch.Tensor) else np.asarray(matrix)
    a = np.asarray(a, dtype=float)
    p = a.shape[1]
    s = np.ones(p) if scales is None else np.asarray(scales, dtype=float)
    if s.shape != (p,) or np.any(s <= 0):
        raise ValueError(f"scales must be {p} positive numbers")
    a = a * s
    norms = np.linalg.norm(a, axis=1)
    a = a[norms > 0] / norms[norms > 0, None]
    if a.shape[0] == 0:
        return RankTest(0, np.zeros(p), 0.0, np.eye(p))
    _, sv, vt = np.linalg.svd(a)
    sv = np.concatenate([sv, np.zeros(p - sv.size)])
    tol = float(rtol * sv[0])
    rank = int(np.sum(sv > tol))
    null = vt[rank:].T
    # Back to unscaled coordinates: a·diag(s)·v = 0 ⇔ a·(s∘v) = 0.
    null = null * s[:, None]
    if null.size:
        null, _ = np.linalg.qr(null)
    return RankTest(rank, sv, tol, null)


def observability_rank(
    f: Function,
    h: Function,
    x: torch.Tensor,
    *,
    max_order: int | None = None,
    chart: Chart | None = None,
    scales: Sequence[float] | None = None,
    rtol: float = 1e-9,
    patience: int = 2,
) -> RankTest:
    """Lie-derivative rank test with increasing order (Deng et al. 2024, eqs. 20–23).

    Orders ``k = 1, 2, …`` are tried until the rank is full, or it has not grown for
    ``patience`` consecutive orders, or ``max_order`` (default ``n − 1``) is reached.

    Parameters
    ----------
    f, h, x, chart
        See :func:`observability_matrix`.
    max_order : int, optional
        Highest order tried.
    scales, rtol
        See :func:`rank_test`.
    patience : int
        Orders without rank growth before stopping.

    Returns
    -------
    RankTest
        With ``order`` the last order computed.
    """
    n = chart.dim if chart is not None else x.shape[0]
    top = n - 1 if max_order is None else max_order
    best: RankTest | None = None
    stalled = 0
    for k in range(1, top + 1):
        test = rank_test(observability_matrix(f, h, x, k, chart), scales, rtol)
        test = RankTest(test.rank, test.singular_values, test.tolerance, test.null_space, k)
        stalled = stalled + 1 if best is not None and test.rank <= best.rank else 0
        best = test
        if test.full or stalled >= patience:
            break
    if best is None:
        best = rank_test(observability_matrix(f, h, x, 0, chart), scales, rtol)
        best = RankTest(best.rank, best.singular_values, best.tolerance, best.null_space, 0)
    return best


def step_jacobians(
    step: Callable[[torch.Tensor, torch.Tensor], torch.Tensor],
    states: torch.Tensor,
    dts: torch.Tensor,
) -> torch.Tensor:
    """Jacobians ``∂φ/∂x`` of a discrete step at every trajectory point, in one batch.

    Parameters
    ----------
    step : callable
        ``(x (n,), dt ()) → x⁺ (n,)``.
    states : (K, n) torch.Tensor
        Points at which to differentiate.
    dts : (K,) torch.Tensor
        Step lengths.

    Returns
    -------
    (K, n, n) torch.Tensor
    """
    return vmap(jacfwd(step, argnums=0))(states, dts)


def fisher_information(
    transitions: np.ndarray | torch.Tensor,
    measurement_jacobians: np.ndarray | torch.Tensor,
    noise_covariance: np.ndarray,
    initial: np.ndarray | None = None,
) -> np.ndarray:
    """``W = Σ_k S_kᵀ H_kᵀ R⁻¹ H_k S_k`` with ``S_{k+1} = F_k S_k`` (discrete Gramian).

    Parameters
    ----------
    transitions : (K, n, n) array
        ``F_k`` from epoch ``k`` to ``k + 1``.
    measurement_jacobians : (K + 1, m, n) array
        ``H_k`` at epochs ``0 … K``.
    noise_covariance : (m, m) array
        Measurement noise ``R``.
    initial : (n, p) array, optional
        ``S_0`` (a chart Jacobian); identity by default.

    Returns
    -------
    (p, p) numpy.ndarray
        Information about the initial (chart) state.
    """
    f = np.asarray(transitions.detach() if isinstance(transitions, torch.Tensor) else transitions)
    h = measurement_jacobians
    h = np.asarray(h.detach() if isinstance(h, torch.Tensor) else h)
    if h.shape[0] != f.shape[0] + 1:
        raise ValueError("need one measurement Jacobian per epoch: len(H) = len(F) + 1")
    r_inv = np.linalg.inv(np.asarray(noise_covariance, dtype=float))
    s = np.eye(f.shape[-1]) if initial is None else np.asarray(initial, dtype=float)
    sens = [s]
    for fk in f:
        s = fk @ s
        sens.append(s)
    hs = h @ np.stack(sens)
    w = np.einsum("kmi,mj,kjl->il", hs, r_inv, hs)
    return 0.5 * (w + w.T)


def observability_gramian(
    step: Callable[[torch.Tensor, torch.Tensor], torch.Tensor],
    h: Function,
    states: torch.Tensor,
    times: torch.Tensor,
    noise_covariance: np.ndarray,
    chart: Chart | None = None,
) -> np.ndarray:
    """Fisher information about the initial state over a trajectory, by autograd.

    Parameters
    ----------
    step : callable
        ``(x, dt) → x⁺``, the discrete dynamics (e.g. one RK4 step).
    h : callable
        ``(n,) → (m,)`` measurement function.
    states : (K + 1, n) torch.Tensor
        Trajectory at the measurement times (from ``step`` or any close approximation).
    times : (K + 1,) torch.Tensor
        Measurement times (s).
    noise_covariance : (m, m) array
        Measurement noise covariance ``R``.
    chart : Chart, optional
        Local coordinates of the initial state; the information is then about ``δ``.

    Returns
    -------
    (p, p) numpy.ndarray
    """
    dts = times[1:] - times[:-1]
    f = step_jacobians(step, states[:-1], dts)
    hj = vmap(jacfwd(h))(states)
    initial = None
    if chart is not None:
        delta0 = torch.zeros(chart.dim, dtype=states.dtype)
        initial = jacfwd(chart.embed)(delta0).detach().numpy()
    return fisher_information(f, hj, noise_covariance, initial)


def information_sigmas(information: np.ndarray, rcond: float = 1e-12) -> np.ndarray:
    """Cramér–Rao standard deviations ``√diag(W⁻¹)``; ``inf`` along unobservable directions.

    Parameters
    ----------
    information : (p, p) array
        Fisher information (symmetric positive semi-definite).
    rcond : float
        Eigenvalues below ``rcond · λ_max`` count as zero information.

    Returns
    -------
    (p,) numpy.ndarray
    """
    w = np.asarray(information, dtype=float)
    lam, vec = np.linalg.eigh(0.5 * (w + w.T))
    keep = lam > rcond * max(lam[-1], 0.0)
    var = np.einsum("ik,k,ik->i", vec[:, keep], 1.0 / lam[keep], vec[:, keep])
    # Any component of an unobservable direction on a state makes that state unbounded.
    touched = np.any(np.abs(vec[:, ~keep]) > 1e-8, axis=1)
    return np.where(touched, np.inf, np.sqrt(var))
