"""Batched Levenberg–Marquardt refinement of candidate initial states (Marquardt 1963)
with an exact attitude sensitivity, and the refinement of their photometric twins.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import torch

from filters.attitude import (
    attitude_matrix,
    quaternion_conjugate,
    quaternion_multiply,
    rotation_vector_to_quaternion,
)
from filters.global_search.problem import (
    BatchProblem,
    Candidates,
    Prior,
    Twins,
)


def residual_jacobian(
    problem: BatchProblem,
    q0: torch.Tensor,
    v: torch.Tensor,
    shape: torch.Tensor,
    epochs: Any,
    *,
    prior: Prior | None = None,
    t_start: float = 0.0,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Residuals ``r (N, E)`` and their Jacobian ``(N, E, p)`` with respect to
    ``[η, ω(, k)]``, ``η`` a body-frame rotation of the initial attitude
    (``q₀ ← exp(η) ⊗ q₀``).

    ``J = ∂r/∂θ(t_e) · ∂θ(t_e)/∂x``, ``θ`` a body-frame rotation of the attitude at each
    epoch (``q ← exp(θ) ⊗ q``). The first factor is a central difference of the measurement
    function for all candidates and epochs at once: ``r[b, e]`` depends on ``q[b, e]``
    only, so six extra predictions (``θ = ±h e_j``, ``h = ε^⅓``: 6·10⁻⁶ rad in float64,
    truncation and rounding errors both ~10⁻¹¹ relative) give every ``∂r[b, e]/∂θ``. The
    measurement function needs no derivatives (the renderer's fused kernels evaluate it;
    any BRDF and shadowing mode works alike). For the second: the kinematics
    ``q̇ = ½ [ω, 0] ⊗ q`` are linear in ``q`` and torque-free rates do not depend on the
    attitude, so ``q(t) = Φ(t) ⊗ q₀`` with ``Φ = q(t) ⊗ q₀⁻¹`` and
    ``∂q(t)/∂η_j = Φ(t) ⊗ [½ e_j, 0] ⊗ q₀`` exactly, without propagation; the rate and
    inertia sensitivities are forward differences of the RK4 map (steps 10⁻⁶ rad/s and
    10⁻⁵, ``p − 3`` propagated replicas, no rendering; relative truncation error
    ``~ ½ h t``, 5·10⁻⁴ for a 10³ s window, harmless in Gauss–Newton steps). A tangent
    ``δq`` of the attitude is the rotation ``δθ = 2 vec(δq ⊗ q⁻¹)``. With a prior, its
    whitened residuals (6 more rows, Jacobian ``diag(1/σ)``) are appended.

    Every candidate's values depend on its own state only (the propagation and the
    measurement function work row by row), so :func:`refine` evaluates the residuals of
    all its trial states and the Jacobian of the accepted ones only.

    Parameters
    ----------
    problem : BatchProblem
    q0 : (N, 4) tensor
        Attitudes at ``t_start``.
    v : (N, p − 3) tensor
        ``[ω(, k)]``.
    shape : (N,) long tensor
    epochs : (E,) int array
    prior : Prior, optional
    t_start : float
        Epoch of the states (s, on the problem's time axis).

    Returns
    -------
    r : (N, E[+6]) tensor
    jacobian : (N, E[+6], p) tensor
    """
    base = _trajectory(problem, q0, v, shape, epochs, t_start)
    r = _residuals(problem, q0, v, shape, epochs, base, prior=prior)
    return r, _jacobian(problem, q0, v, shape, epochs, base, prior=prior, t_start=t_start)


def _trajectory(
    problem: BatchProblem,
    q0: torch.Tensor,
    v: torch.Tensor,
    shape: torch.Tensor,
    epochs: Any,
    t_start: float,
) -> torch.Tensor:
    """Attitudes ``(N, E, 4)`` of states ``q0 (N, 4)``, ``v = [ω(, k)] (N, p − 3)``."""
    return problem.trajectory(
        q0, v[:, :3], v[:, 3:] if v.shape[1] > 3 else None, shape, epochs, t_start
    )


def _residuals(
    problem: BatchProblem,
    q0: torch.Tensor,
    v: torch.Tensor,
    shape: torch.Tensor,
    epochs: Any,
    trajectory: torch.Tensor,
    *,
    prior: Prior | None,
) -> torch.Tensor:
    """Normalised residuals of a trajectory ``(N, E, 4)`` (with the prior's whitened
    deviations of ``q0``, ``ω`` appended), shape (N, E[+6])."""
    r = problem.profiled(problem.residuals_of(trajectory, shape, epochs), epochs)
    if problem.has_inertia_prior:
        r = torch.cat([r, problem.inertia_residuals(v[:, 3:5], shape)], dim=1)
    if prior is None:
        return r
    return torch.cat([r, prior.residuals(q0, v[:, :3])], dim=1)


def _jacobian(
    problem: BatchProblem,
    q0: torch.Tensor,
    v: torch.Tensor,
    shape: torch.Tensor,
    epochs: Any,
    base: torch.Tensor,
    *,
    prior: Prior | None,
    t_start: float,
) -> torch.Tensor:
    """The Jacobian of :func:`residual_jacobian` given the states' trajectory ``base
    (N, E, 4)``, shape (N, E[+6], p)."""
    m, d = v.shape
    fd_step = torch.tensor([1e-6] * 3 + [1e-5] * (d - 3), dtype=v.dtype)
    replicas = (v[:, None] + torch.diag(fd_step)).reshape(-1, d)
    traj = _trajectory(
        problem,
        q0.repeat_interleave(d, dim=0),
        replicas,
        shape.repeat_interleave(d),
        epochs,
        t_start,
    )
    traj = traj.reshape(m, d, *traj.shape[1:])
    rate_tangent = (traj - base[:, None]) / fd_step[:, None, None]
    # Attitude columns: δθ_j = vec(Φ ⊗ [e_j, 0] ⊗ Φ⁻¹) = A(Φ) e_j. Rate and inertia columns:
    # δθ = 2 vec(δq ⊗ q⁻¹) = 2 (q₄ δq_v − δq₄ q_v + δq_v × q_v), q = q(t).
    phi = quaternion_multiply(base, quaternion_conjugate(q0)[:, None])
    attitude_rotations = attitude_matrix(phi).permute(0, 3, 1, 2)
    qv, q4 = base[:, None, :, :3], base[:, None, :, 3:]
    dv, d4 = rate_tangent[..., :3], rate_tangent[..., 3:]
    rate_rotations = 2.0 * (q4 * dv - d4 * qv + torch.linalg.cross(dv, qv.expand_as(dv)))
    rotations = torch.cat([attitude_rotations, rate_rotations], dim=1)
    gradient = _rotation_differences(problem, base, shape, epochs)
    jac = problem.profiled(torch.einsum("nje,npej->nep", gradient, rotations), epochs)
    if problem.has_inertia_prior:
        rows = torch.zeros((2, d + 3), dtype=v.dtype)
        rows[0, 6] = rows[1, 7] = 1.0 / problem.inertia_sigma
        jac = torch.cat([jac, rows.expand(m, 2, d + 3)], dim=1)
    if prior is None:
        return jac
    root = torch.sqrt(prior.information(d + 3)[:6]).to(v.dtype)
    return torch.cat([jac, root.expand(m, *root.shape)], dim=1)


def _rotation_differences(
    problem: BatchProblem, q: torch.Tensor, shape: torch.Tensor, epochs: Any
) -> torch.Tensor:
    """Central differences ``∂r/∂θ (N, 3, E)`` of the residuals of attitudes ``q (N, E, 4)``
    with respect to body-frame rotations ``θ`` (``q ← exp(θ) ⊗ q``)."""
    n = len(q)
    h = float(torch.finfo(q.dtype).eps) ** (1.0 / 3.0)
    axes = h * torch.eye(3, dtype=q.dtype)
    turns = rotation_vector_to_quaternion(torch.cat([axes, -axes]))
    # exp(θ) ⊗ q is linear in q: one product with the stacked left-multiplication matrices.
    left = torch.stack([quaternion_multiply(turns, e) for e in torch.eye(4, dtype=q.dtype)], -1)
    probes = (q @ left.reshape(24, 4).T).reshape(*q.shape[:2], 6, 4).permute(0, 2, 1, 3)
    attitudes = probes.reshape(n * 6, *q.shape[1:])
    r = problem.residuals_of(attitudes, shape.repeat_interleave(6), epochs).reshape(n, 6, -1)
    return (r[:, :3] - r[:, 3:]) / (2.0 * h)


def refine(
    problem: BatchProblem,
    candidates: Candidates,
    epochs: np.ndarray,
    *,
    iterations: int = 15,
    damping: float = 1e-2,
    prior: Prior | None = None,
    t_start: float = 0.0,
) -> Candidates:
    """Batched Levenberg–Marquardt on ``[η, ω(, k)]`` (maximum a posteriori with a prior),
    Jacobians from :func:`residual_jacobian`; each accepted step turns the attitude,
    ``q₀ ← exp(Δη) ⊗ q₀``.

    Every iteration evaluates the residuals of every candidate's trial state (one
    propagation and one prediction per candidate and epoch) and then linearises the
    accepted ones only (``p − 3`` more propagations and six more predictions): a rejected
    step's Jacobian is never used. On the searches of the README main job about a third of
    the trial steps are rejected.

    Parameters
    ----------
    problem : BatchProblem
    candidates : Candidates
        Starting states (N of them).
    epochs : (E,) int array
        Measurement indices of the window.
    iterations : int
        LM iterations (each one trial evaluation, and a Jacobian pass where accepted).
    damping : float
        Initial Marquardt damping ``μ``.
    prior : Prior, optional
        Adds the whitened prior deviations to the residuals (their Jacobian is taken as
        ``diag(1/σ)``, exact at the prior mean).
    t_start : float
        Epoch of the candidates (s, on the problem's time axis): 0 for initial states,
        the last measurement's time to fit final states (epochs reached backwards).

    Returns
    -------
    Candidates
        The refined states with ``chi2`` (``Σ r²`` on the window, prior term included) and
        ``covariance`` (``(JᵀJ)⁻¹`` of ``[η (rad, body frame), ω(, k)]`` at the solution,
        the posterior covariance with a prior).
    """
    shape = candidates.shape
    n = len(candidates)
    q = candidates.q.detach().clone()
    v = candidates.params.detach()
    mu = torch.full((n,), damping, dtype=q.dtype)
    r, jac = residual_jacobian(problem, q, v, shape, epochs, prior=prior, t_start=t_start)
    chi2 = torch.nan_to_num((r * r).sum(dim=1), nan=math.inf)
    stalled = 0
    for _ in range(iterations):
        jtj = jac.transpose(1, 2) @ jac
        jtr = (jac.transpose(1, 2) @ r[..., None])[..., 0]
        scaled = jtj + mu[:, None, None] * torch.diag_embed(
            torch.diagonal(jtj, dim1=1, dim2=2) + 1e-12
        )
        step = torch.nan_to_num(-torch.linalg.solve(scaled, jtr))
        q_trial = quaternion_multiply(rotation_vector_to_quaternion(step[:, :3]), q)
        v_trial = v + step[:, 3:]
        base = _trajectory(problem, q_trial, v_trial, shape, epochs, t_start)
        r_trial = _residuals(problem, q_trial, v_trial, shape, epochs, base, prior=prior)
        chi2_trial = torch.nan_to_num((r_trial * r_trial).sum(dim=1), nan=math.inf)
        better = chi2_trial < chi2
        progress_made = better & (chi2 - chi2_trial > 1e-4 * chi2)
        stalled = 0 if bool(progress_made.any()) else stalled + 1
        accepted = torch.nonzero(better).flatten()
        if len(accepted):
            jac[accepted] = _jacobian(
                problem,
                q_trial[accepted],
                v_trial[accepted],
                shape[accepted],
                epochs,
                base[accepted],
                prior=prior,
                t_start=t_start,
            )
        q = torch.where(better[:, None], q_trial, q)
        v = torch.where(better[:, None], v_trial, v)
        r = torch.where(better[:, None], r_trial, r)
        chi2 = torch.where(better, chi2_trial, chi2)
        mu = torch.where(better, mu / 3.0, mu * 4.0).clamp(1e-9, 1e9)
        if stalled >= 2:  # no candidate improved by 10⁻⁴ of its χ² twice in a row
            break
    return Candidates(
        q=q,
        omega=v[:, :3],
        shape=shape,
        k=v[:, 3:] if v.shape[1] > 3 else None,
        chi2=chi2,
        covariance=_gauss_newton_covariance(jac),
    )


def _gauss_newton_covariance(jac: torch.Tensor) -> torch.Tensor:
    """``(JᵀJ)⁺`` per candidate, computed on the unit-diagonal (Jacobi-scaled) matrix; a
    candidate whose Jacobian is not finite gets ``10⁶ I`` (no information)."""
    jtj = jac.transpose(1, 2) @ jac
    finite = torch.isfinite(jtj).all(dim=2).all(dim=1)
    jtj = torch.where(finite[:, None, None], jtj, torch.eye(jtj.shape[1], dtype=jtj.dtype))
    scale = torch.sqrt(torch.diagonal(jtj, dim1=1, dim2=2).clamp_min(1e-300))
    scaled = jtj / (scale[:, :, None] * scale[:, None, :])
    try:
        inverse = torch.linalg.pinv(scaled, hermitian=True)
    except RuntimeError:  # eigh did not converge: the SVD route is slower but robust
        inverse = torch.linalg.pinv(scaled)
    covariance = inverse / (scale[:, :, None] * scale[:, None, :])
    uninformed = 1e6 * torch.eye(jtj.shape[1], dtype=jtj.dtype).expand_as(covariance)
    return torch.where(finite[:, None, None], covariance, uninformed)


def _with_twins(
    problem: BatchProblem,
    twins: Twins,
    candidates: Candidates,
    epochs: np.ndarray,
    *,
    iterations: int,
    prior: Prior | None,
) -> tuple[Candidates, int]:
    """The candidates followed by their refined twins (every kind ``twins`` returns), and
    ``1 +`` the number of kinds that any candidate has."""
    parts = [candidates]
    for q2, w2, has in twins(
        candidates.q.numpy(), candidates.omega.numpy(), candidates.shape.numpy()
    ):
        rows = torch.as_tensor(np.flatnonzero(has))
        if len(rows) == 0:
            continue
        start = candidates.take(rows)
        start.q = torch.as_tensor(q2[has], dtype=start.q.dtype)
        start.omega = torch.as_tensor(w2[has], dtype=start.omega.dtype)
        parts.append(refine(problem, start, epochs, iterations=iterations, prior=prior))
    return Candidates.concat(parts), len(parts)
