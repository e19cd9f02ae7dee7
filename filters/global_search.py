"""Global initialisation of attitude, rates (and shape) from a light curve.

A light curve's likelihood over ``(q, ω)`` is a sharp, multi-modal 6-D landscape: a
particle filter started uniform on SO(3) × a rate ball does not find its peak (measured on
a tumbling box-wing: final error ~100° after 40 min with 2·10⁴ particles, DESIGN.md). What
works is a search over the *initial* state ``x₀ = (q₀, ω₀[, k][, shape])`` at the first
measurement epoch, which determines the whole trajectory under torque-free motion:

1. **Screen** many candidates (uniform attitudes, rates uniform in the ball
   ``|ω| ≤ ω_max``, a shape index per candidate) on a short window of data with one
   batched propagation and one rendering call per shape, ranking them by a robust misfit
   (Student-t negative log-likelihood of the normalised residuals ``r = (m̂ − m)/σ``, so a
   misplaced glint does not dominate). Screening is successive: all candidates on a few
   epochs, the best fraction on more.
2. **Refine** the best few hundred by Levenberg–Marquardt, batched: every candidate's
   residual vector and its Jacobian with respect to
   ``u = [δθ (3, body-frame rotation vector, q = exp(δθ) ⊗ q_c), ω (3), k (2, optional)]``
   come from one forward-mode automatic-differentiation pass of the propagation and the
   renderer (``torch.autograd.forward_ad``), each candidate solving its own damped normal
   equations ``(JᵀJ + μ diag JᵀJ) Δu = −Jᵀr`` (Marquardt 1963). The window then grows
   (continuation) and the surviving candidates are refined again, so that the rate
   estimate improves before the long-arc attitude drift becomes non-linear.
3. **Rank** the refined candidates by ``χ² = Σ r²`` on the final window, merge duplicates
   and return them with their Gauss–Newton covariances ``(JᵀJ)⁻¹``, to seed a particle
   filter or a UKF bank.

The problem enters as callables: ``measure(q (N, E, 4), epochs (E,), shape (N,)) →
(N, E)`` predicted measurements (torch, differentiable), the epochs' times, the
measurements and their 1σ errors, and the inertia of each shape.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch

from filters.attitude import (
    attitude_angle,
    inertia_from_tanh,
    quaternion_conjugate,
    quaternion_multiply,
    quaternion_to_rotation_vector,
    random_quaternion,
    rotation_vector_to_quaternion,
)
from filters.ukf import propagate_torque_free

__all__ = [
    "BatchProblem",
    "Prior",
    "SearchResult",
    "global_search",
    "prior_candidates",
    "refine",
    "residual_jacobian",
    "screen",
    "uniform_candidates",
    "uniform_rates",
    "unpack",
]

#: ``measure(q (N, E, 4), epochs (E,), shape (N,)) → (N, E)`` predicted measurements.
Measure = Callable[[torch.Tensor, np.ndarray, torch.Tensor], torch.Tensor]


def uniform_rates(n: int, omega_max: float, rng: np.random.Generator) -> np.ndarray:
    """Body rates uniform in the ball ``|ω| ≤ omega_max`` (rad/s), shape (n, 3)."""
    direction = rng.standard_normal((n, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    return direction * omega_max * rng.random((n, 1)) ** (1.0 / 3.0)


@dataclass(frozen=True)
class Prior:
    """Gaussian prior on the initial state: ``δθ ~ N(0, σ_θ² I)`` about ``q``,
    ``ω ~ N(ω̄, diag σ_ω²)``.

    Parameters
    ----------
    q : (4,) array
        Prior mean attitude (inertial → body).
    omega : (3,) array
        Prior mean body rates (rad/s).
    attitude_sigma : float
        1σ of each component of the body-frame rotation vector (rad).
    omega_sigma : float or (3,) array
        1σ of the rates (rad/s).
    """

    q: np.ndarray
    omega: np.ndarray
    attitude_sigma: float
    omega_sigma: Any

    def sample(self, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """``n`` draws; the first one is the prior mean itself."""
        dtheta = rng.standard_normal((n, 3)) * self.attitude_sigma
        dtheta[0] = 0.0
        q = quaternion_multiply(rotation_vector_to_quaternion(dtheta), np.asarray(self.q, float))
        omega = np.asarray(self.omega, float) + rng.standard_normal((n, 3)) * np.asarray(
            self.omega_sigma, float
        )
        omega[0] = self.omega
        return q, omega

    def residuals(self, q: torch.Tensor, omega: torch.Tensor) -> torch.Tensor:
        """Whitened deviations ``[rotvec(q ⊗ q̄⁻¹)/σ_θ, (ω − ω̄)/σ_ω]``, shape (N, 6)."""
        q_bar = torch.as_tensor(np.asarray(self.q, float), dtype=q.dtype)
        dtheta = quaternion_to_rotation_vector(quaternion_multiply(q, quaternion_conjugate(q_bar)))
        sigma_w = torch.as_tensor(np.broadcast_to(self.omega_sigma, (3,)), dtype=q.dtype)
        w_bar = torch.as_tensor(np.asarray(self.omega, float), dtype=q.dtype)
        return torch.cat([dtheta / self.attitude_sigma, (omega - w_bar) / sigma_w], dim=1)

    def information(self, n_params: int) -> torch.Tensor:
        """Diagonal information ``diag(1/σ²)`` on ``[δθ, ω]`` (zero for further unknowns)."""
        sigma = np.concatenate(
            [np.full(3, self.attitude_sigma), np.broadcast_to(self.omega_sigma, (3,))]
        )
        info = np.zeros(n_params)
        info[:6] = 1.0 / sigma**2
        return torch.diag(torch.as_tensor(info))


@dataclass
class BatchProblem:
    """Measurements of one object and the model predicting them from initial states.

    Parameters
    ----------
    times : (E,) array
        Measurement times (s) since the reference epoch of the initial states.
    measured : (E,) array
        Measurements.
    sigma : (E,) array
        Their 1σ errors.
    measure : callable
        ``measure(q, epochs, shape)``: predictions for attitudes ``q (N, E_sel, 4)`` at
        the measurement indices ``epochs (E_sel,)`` for candidates of shape index
        ``shape (N,)`` (torch, differentiable in ``q``).
    inertias : sequence of (3, 3) arrays
        Body-frame inertia of each shape (any scale).
    principal_axes : sequence of (3, 3) arrays, optional
        Principal axes (columns) of each shape, used when the tanh inertia parameters
        ``k`` are estimated (``J = P diag(J(k)) Pᵀ``).
    estimate_inertia : bool
        Add the tanh parameters ``k = [k1, k2]`` (seed 004) to the unknowns.
    max_step : float
        Largest RK4 step of the propagation (s). RK4's error per step on a rotation by
        ``θ = |ω| h`` is about ``θ⁵/3840`` rad: 4·10⁻⁸ rad at 5°/s and 2 s.
    dtype : torch.dtype
        Precision of the propagation and of the least squares.
    """

    times: np.ndarray
    measured: np.ndarray
    sigma: np.ndarray
    measure: Measure
    inertias: Sequence[np.ndarray]
    principal_axes: Sequence[np.ndarray] | None = None
    estimate_inertia: bool = False
    max_step: float = 2.0
    dtype: torch.dtype = torch.float64
    _inertia: torch.Tensor = field(init=False, repr=False)
    _axes: torch.Tensor = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.times = np.asarray(self.times, dtype=float)
        self.measured = np.asarray(self.measured, dtype=float)
        self.sigma = np.asarray(self.sigma, dtype=float)
        if np.any(np.diff(self.times) < 0):
            raise ValueError("times must be non-decreasing")
        self._inertia = torch.as_tensor(np.stack(self.inertias), dtype=self.dtype)
        axes = self.principal_axes or [np.eye(3)] * len(self.inertias)
        self._axes = torch.as_tensor(np.stack(axes), dtype=self.dtype)

    @property
    def n_params(self) -> int:
        """Unknowns per candidate: 6, or 8 with the inertia."""
        return 8 if self.estimate_inertia else 6

    def window(self, duration: float, max_epochs: int) -> np.ndarray:
        """Indices of at most ``max_epochs`` measurements, evenly spread over the first
        ``duration`` seconds."""
        inside = np.flatnonzero(self.times <= self.times[0] + duration)
        if len(inside) <= max_epochs:
            return inside
        return inside[np.round(np.linspace(0, len(inside) - 1, max_epochs)).astype(int)]

    def trajectory(
        self,
        q0: torch.Tensor,
        omega0: torch.Tensor,
        k: Any,
        shape: torch.Tensor,
        epochs: Any,
        t_start: float = 0.0,
    ) -> torch.Tensor:
        """Attitudes at the given epochs of states known at ``t_start`` (torque-free RK4).

        Parameters
        ----------
        q0 : (N, 4) tensor
        omega0 : (N, 3) tensor
        k : (N, 2) tensor or None
            Tanh inertia parameters (with ``estimate_inertia``).
        shape : (N,) long tensor
        epochs : (E,) int array
            Measurement indices; epochs before ``t_start`` are reached backwards in time.
        t_start : float
            Time of the given states (s, on the axis of :attr:`times`).

        Returns
        -------
        (N, E, 4) tensor
        """
        if k is None:
            inertia = self._inertia[shape]
            if bool((shape == shape[0]).all()):
                inertia = inertia[0]  # one shared tensor: one GEMM per derivative
        else:
            axes = self._axes[shape]
            inertia = axes @ inertia_from_tanh(k) @ axes.transpose(-1, -2)
        epochs = np.asarray(epochs)
        offsets = self.times[epochs] - t_start
        out: list[Any] = [None] * len(epochs)
        for chain in (np.flatnonzero(offsets >= 0), np.flatnonzero(offsets < 0)[::-1]):
            q, w, t = q0, omega0, 0.0
            for i in chain[np.argsort(np.abs(offsets[chain]), kind="stable")]:
                q, w = propagate_torque_free(q, w, inertia, float(offsets[i] - t), self.max_step)
                t = float(offsets[i])
                out[i] = q
        return torch.stack(out, dim=1)

    def residuals_of(self, q: torch.Tensor, shape: torch.Tensor, epochs: Any) -> torch.Tensor:
        """Normalised residuals ``(m̂ − m)/σ`` of attitudes ``q (N, E, 4)``, shape (N, E)."""
        measured = torch.as_tensor(self.measured[epochs], dtype=self.dtype)
        sigma = torch.as_tensor(self.sigma[epochs], dtype=self.dtype)
        return (self.measure(q, np.asarray(epochs), shape) - measured) / sigma

    def residuals(
        self, q0: torch.Tensor, omega0: torch.Tensor, k: Any, shape: torch.Tensor, epochs: Any
    ) -> torch.Tensor:
        """Normalised residuals of initial states, shape (N, E)."""
        return self.residuals_of(self.trajectory(q0, omega0, k, shape, epochs), shape, epochs)


@dataclass
class SearchResult:
    """Ranked candidate initial states at the reference epoch.

    Attributes
    ----------
    q : (M, 4) numpy.ndarray
        Attitudes (inertial → body).
    omega : (M, 3) numpy.ndarray
        Body rates (rad/s).
    k : (M, 2) numpy.ndarray or None
        Tanh inertia parameters (when estimated).
    shape : (M,) int numpy.ndarray
        Shape index.
    chi2 : (M,) numpy.ndarray
        ``Σ r²`` on the final window (ascending).
    covariance : (M, p, p) numpy.ndarray
        Gauss–Newton covariance ``(JᵀJ)⁻¹`` of ``[δθ, ω(, k)]``.
    epochs : (E,) int numpy.ndarray
        Measurement indices of the final window.
    screened : int
        Number of candidates screened.
    """

    q: np.ndarray
    omega: np.ndarray
    k: np.ndarray | None
    shape: np.ndarray
    chi2: np.ndarray
    covariance: np.ndarray
    epochs: np.ndarray
    screened: int

    def __len__(self) -> int:
        return len(self.chi2)


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
) -> tuple[torch.Tensor, torch.Tensor, Any, torch.Tensor]:
    """Candidates uniform on SO(3), in the rate ball ``|ω| ≤ omega_max``, over the shapes
    (and in ``[−k_range, k_range]²`` for the tanh inertia when it is estimated).

    Returns
    -------
    q0 (n, 4), omega0 (n, 3), k (n, 2) or None, shape (n,) : tensors
    """
    q = torch.as_tensor(random_quaternion(n, rng), dtype=problem.dtype)
    w = torch.as_tensor(uniform_rates(n, omega_max, rng), dtype=problem.dtype)
    shape = torch.as_tensor(rng.integers(0, n_shapes, n), dtype=torch.long)
    k = None
    if problem.estimate_inertia:
        k = torch.as_tensor(rng.uniform(-k_range, k_range, (n, 2)), dtype=q.dtype)
    return q, w, k, shape


def prior_candidates(
    problem: BatchProblem,
    n: int,
    prior: Prior,
    rng: np.random.Generator,
    shapes: Sequence[int] = (0,),
    k: Any = None,
) -> tuple[torch.Tensor, torch.Tensor, Any, torch.Tensor]:
    """``n`` draws from a Gaussian prior for each listed shape (the prior mean first).

    Returns
    -------
    q0, omega0, k, shape : tensors (``n · len(shapes)`` rows)
    """
    q, w = prior.sample(n, rng)
    rows = len(shapes) * n
    q = torch.as_tensor(np.tile(q, (len(shapes), 1)), dtype=problem.dtype)
    w = torch.as_tensor(np.tile(w, (len(shapes), 1)), dtype=problem.dtype)
    shape = torch.as_tensor(np.repeat(np.asarray(shapes), n), dtype=torch.long)
    kk = None
    if problem.estimate_inertia:
        k0 = np.zeros(2) if k is None else np.asarray(k, float)
        kk = torch.as_tensor(np.broadcast_to(k0, (rows, 2)).copy(), dtype=problem.dtype)
    return q, w, kk, shape


def screen(
    problem: BatchProblem,
    candidates: tuple[torch.Tensor, torch.Tensor, Any, torch.Tensor],
    duration: float,
    keep: int,
    stages: Sequence[int] = (8, 24),
    fraction: float = 0.1,
    batch: int = 8192,
    nu: float = 4.0,
    prior: Prior | None = None,
) -> tuple[torch.Tensor, torch.Tensor, Any, torch.Tensor]:
    """Successive screening: returns the ``keep`` candidates of lowest misfit.

    Stage ``i`` evaluates the survivors on ``stages[i]`` epochs spread over ``duration``
    seconds and keeps the best ``fraction`` of them (at least ``keep``). The misfit is the
    Student-t negative log-likelihood of the normalised residuals (plus ``½|r_prior|²``
    with a prior).

    Parameters
    ----------
    problem : BatchProblem
    candidates : tuple of tensors
        ``(q0, omega0, k, shape)`` as from :func:`uniform_candidates`.
    duration : float
        Window (s).
    keep : int
        Survivors of the last stage.

    Returns
    -------
    q0, omega0, k, shape : tensors
    """
    q, w, k, shape = candidates
    for i, n_epochs in enumerate(stages):
        epochs = problem.window(duration, n_epochs)
        costs = []
        for s in range(0, len(q), batch):
            part = slice(s, s + batch)
            kk = None if k is None else k[part]
            cost = _robust_cost(problem.residuals(q[part], w[part], kk, shape[part], epochs), nu)
            if prior is not None:
                cost = cost + 0.5 * (prior.residuals(q[part], w[part]) ** 2).sum(dim=1)
            costs.append(cost)
        cost = torch.nan_to_num(torch.cat(costs), nan=math.inf)
        survivors = keep if i == len(stages) - 1 else max(keep, int(len(q) * fraction))
        best = torch.argsort(cost)[:survivors]
        q, w, shape = q[best], w[best], shape[best]
        k = None if k is None else k[best]
    return q, w, k, shape


def unpack(u: torch.Tensor, q_center: torch.Tensor) -> tuple[torch.Tensor, Any, Any]:
    """``u = [δθ, ω(, k)]`` → ``(q = exp(δθ) ⊗ q_center, ω, k or None)``."""
    q = quaternion_multiply(rotation_vector_to_quaternion(u[:, :3]), q_center)
    return q, u[:, 3:6], (u[:, 6:8] if u.shape[1] > 6 else None)


def residual_jacobian(
    problem: BatchProblem,
    u: torch.Tensor,
    q_center: torch.Tensor,
    shape: torch.Tensor,
    epochs: Any,
    prior: Prior | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Residuals ``r (N, E)`` and their Jacobian ``∂r/∂u (N, E, p)`` at ``u``.

    ``J = ∂r/∂q(t_e) · ∂q(t_e)/∂u``. The first factor comes from ONE reverse-mode autograd
    pass through the measurement function for all candidates and epochs: ``r[b, e]``
    depends on ``q[b, e]`` only, so the gradient of ``Σ r`` holds every
    ``∂r[b, e]/∂q[b, e]``. The second is the sensitivity of the RK4 map, by central
    differences of ``2p + 1`` propagated replicas (steps 1e-5 rad, 1e-7 rad/s, 1e-5 for
    ``k``; no rendering). With a prior, its whitened residuals (6 more rows, Jacobian
    taken as ``diag(1/σ)``) are appended.

    Parameters
    ----------
    problem : BatchProblem
    u : (N, p) tensor
        ``[δθ, ω(, k)]`` about ``q_center``.
    q_center : (N, 4) tensor
    shape : (N,) long tensor
    epochs : (E,) int array
    prior : Prior, optional

    Returns
    -------
    r : (N, E[+6]) tensor
    jacobian : (N, E[+6], p) tensor
    """
    m, p = u.shape
    eye = torch.eye(p, dtype=u.dtype)
    fd_step = torch.tensor([1e-5] * 3 + [1e-7] * 3 + [1e-5] * (p - 6), dtype=u.dtype)
    steps = torch.cat([torch.zeros(1, p, dtype=u.dtype), eye * fd_step, -eye * fd_step])
    replicas = (u[:, None] + steps).reshape(-1, p)
    q, w, kk = unpack(replicas, q_center.repeat_interleave(len(steps), dim=0))
    traj = problem.trajectory(q, w, kk, shape.repeat_interleave(len(steps)), epochs)
    traj = traj.reshape(m, len(steps), *traj.shape[1:])
    tangent = (traj[:, 1 : p + 1] - traj[:, p + 1 :]) / (2.0 * fd_step[:, None, None])
    primal = traj[:, 0].detach().requires_grad_(True)
    with torch.enable_grad():
        r = problem.residuals_of(primal, shape, epochs)
        (gradient,) = torch.autograd.grad(r.sum(), primal)
    r, jac = r.detach(), torch.einsum("nec,npec->nep", gradient, tangent)
    if prior is None:
        return r, jac
    q, w, _ = unpack(u, q_center)
    root = torch.sqrt(prior.information(p)[:6]).to(u.dtype)
    return torch.cat([r, prior.residuals(q, w)], dim=1), torch.cat(
        [jac, root.expand(m, *root.shape)], dim=1
    )


def refine(
    problem: BatchProblem,
    q0: torch.Tensor,
    omega0: torch.Tensor,
    k: Any,
    shape: torch.Tensor,
    epochs: np.ndarray,
    iterations: int = 15,
    damping: float = 1e-2,
    prior: Prior | None = None,
) -> tuple[torch.Tensor, torch.Tensor, Any, torch.Tensor, torch.Tensor]:
    """Batched Levenberg–Marquardt on ``u = [δθ, ω(, k)]`` (maximum a posteriori with a
    prior), Jacobians from :func:`residual_jacobian`.

    Parameters
    ----------
    problem : BatchProblem
    q0, omega0, k, shape : tensors
        Starting candidates (N of them).
    epochs : (E,) int array
        Measurement indices of the window.
    iterations : int
        LM iterations (each one Jacobian pass and one trial evaluation).
    damping : float
        Initial Marquardt damping ``μ``.
    prior : Prior, optional
        Adds the whitened prior deviations to the residuals (their Jacobian is taken as
        ``diag(1/σ)``, exact at the prior mean).

    Returns
    -------
    q0, omega0, k : tensors
        Refined candidates.
    chi2 : (N,) tensor
        ``Σ r²`` on the window (prior term included).
    covariance : (N, p, p) tensor
        ``(JᵀJ)⁻¹`` at the solution (the posterior covariance with a prior).
    """
    n = len(q0)
    q_center = q0.detach().clone()
    parts = [torch.zeros(n, 3, dtype=q0.dtype), omega0.detach()]
    if problem.estimate_inertia:
        parts.append(k.detach())
    u = torch.cat(parts, dim=1)
    mu = torch.full((n,), damping, dtype=q0.dtype)

    def linearise(u_: torch.Tensor, rows: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        return residual_jacobian(problem, u_, q_center[rows], shape[rows], epochs, prior)

    rows = torch.arange(n)
    r, jac = linearise(u, rows)
    chi2 = (r * r).sum(dim=1)
    for _ in range(iterations):
        jtj = jac.transpose(1, 2) @ jac
        jtr = (jac.transpose(1, 2) @ r[..., None])[..., 0]
        scaled = jtj + mu[:, None, None] * torch.diag_embed(
            torch.diagonal(jtj, dim1=1, dim2=2) + 1e-12
        )
        trial = u + torch.nan_to_num(-torch.linalg.solve(scaled, jtr))
        # The trial point is linearised at once: accepted steps need no second pass.
        r_trial, jac_trial = linearise(trial, rows)
        chi2_trial = torch.nan_to_num((r_trial * r_trial).sum(dim=1), nan=math.inf)
        better = chi2_trial < chi2
        u = torch.where(better[:, None], trial, u)
        r = torch.where(better[:, None], r_trial, r)
        jac = torch.where(better[:, None, None], jac_trial, jac)
        chi2 = torch.where(better, chi2_trial, chi2)
        mu = torch.where(better, mu / 3.0, mu * 4.0).clamp(1e-9, 1e9)
    jtj = jac.transpose(1, 2) @ jac
    covariance = torch.linalg.pinv(jtj, hermitian=True)
    q, w, kk = unpack(u, q_center)
    return q, w, kk, chi2, covariance


def _distinct(
    q: np.ndarray, omega: np.ndarray, shape: np.ndarray, angle: float, rate: float
) -> np.ndarray:
    """Indices of candidates (already sorted by cost) not duplicating a better one."""
    kept: list[int] = []
    for i in range(len(q)):
        if not kept:
            kept.append(i)
            continue
        j = np.asarray(kept)
        same = (
            (shape[j] == shape[i])
            & (attitude_angle(q[j], q[i]) < angle)
            & (np.linalg.norm(omega[j] - omega[i], axis=1) < rate)
        )
        if not same.any():
            kept.append(i)
    return np.asarray(kept, dtype=int)


def global_search(
    problem: BatchProblem,
    n_candidates: int = 100_000,
    omega_max: float = math.radians(5.0),
    n_shapes: int = 1,
    seed: int | np.random.Generator | None = None,
    prior: Prior | None = None,
    screen_duration: float = 60.0,
    windows: Sequence[float] = (60.0, 180.0, 600.0),
    keep: Sequence[int] = (256, 48, 12),
    max_epochs: int = 120,
    iterations: int = 15,
    distinct_angle: float = math.radians(3.0),
    distinct_rate: float = math.radians(0.05),
    progress: Callable[[str], None] | None = None,
) -> SearchResult:
    """Screen initial states, refine the best by batched LM with continuation.

    Parameters
    ----------
    problem : BatchProblem
    n_candidates : int
        Candidates screened (per shape with a prior).
    omega_max : float
        Radius of the rate ball (rad/s) of uniform candidates.
    n_shapes : int
        Shape indices ``[0, n_shapes)`` searched.
    seed : int or numpy.random.Generator, optional
    prior : Prior, optional
        Draw the candidates from this Gaussian prior (for every shape) instead of
        uniformly, and refine maximum a posteriori.
    screen_duration : float
        Window of the screening (s).
    windows : sequence of float
        Growing refinement windows (s); the last one is the window of the returned χ².
    keep : sequence of int
        Candidates refined on each window (the best of the previous stage).
    max_epochs : int
        Measurements used per window (spread evenly over it).
    iterations : int
        LM iterations per window.
    distinct_angle, distinct_rate : float
        Candidates closer than this (rad, rad/s) to a better one are duplicates.
    progress : callable, optional
        Receives a short message after each stage.

    Returns
    -------
    SearchResult
    """
    rng = np.random.default_rng(seed)
    if prior is None:
        candidates = uniform_candidates(problem, n_candidates, omega_max, rng, n_shapes)
    else:
        candidates = prior_candidates(problem, n_candidates, prior, rng, range(n_shapes))
    q, w, k, shape = screen(problem, candidates, screen_duration, keep[0], prior=prior)
    if progress:
        progress(f"screened {len(candidates[0])} candidates")
    chi2 = covariance = None
    epochs = None
    for duration, count in zip(windows, keep, strict=True):
        if chi2 is not None:
            best = torch.argsort(chi2)[:count]
            q, w, shape = q[best], w[best], shape[best]
            k = None if k is None else k[best]
        epochs = problem.window(duration, max_epochs)
        q, w, k, chi2, covariance = refine(problem, q, w, k, shape, epochs, iterations, prior=prior)
        if progress:
            progress(f"refined {len(q)} candidates on {duration:.0f} s, best χ² {chi2.min():.1f}")
    order = torch.argsort(chi2).numpy()
    q_np = q.detach().numpy()[order]
    w_np = w.detach().numpy()[order]
    shape_np = shape.numpy()[order]
    kept = order[_distinct(q_np, w_np, shape_np, distinct_angle, distinct_rate)]
    return SearchResult(
        q=q.detach().numpy()[kept],
        omega=w.detach().numpy()[kept],
        k=None if k is None else k.detach().numpy()[kept],
        shape=shape.numpy()[kept],
        chi2=chi2.detach().numpy()[kept],
        covariance=covariance.detach().numpy()[kept],
        epochs=epochs,
        screened=len(candidates[0]),
    )
