"""Batched Levenberg–Marquardt least squares in torch.

Minimises ``χ² = Σ r²`` for a batch of independent problems at once (pole starts × trial
periods), each with its own damping. The step solves Marquardt's scaled system (Moré 1978)
``(JᵀJ + μ D) δ = −Jᵀ r``, ``D = diag(JᵀJ)`` at the current point (``scaling="current"``,
Marquardt 1963, as in the Numerical-Recipes routine of DAMIT's convexinv) or the largest
``diag(JᵀJ)`` met so far (``"max"``, MINPACK). The damping follows the gain ratio
``ρ = (χ² − χ²(x + δ)) / (μ δᵀDδ − δᵀJᵀr)`` (actual over predicted decrease; Nielsen 1999,
Madsen, Nielsen & Tingleff 2004, eq. 2.21): a step with ρ > 0 is taken and
``μ ← μ max(1/3, 1 − (2ρ − 1)³)``; otherwise ``μ ← ν μ``, ``ν ← 2ν`` and the step is retried
(one residual evaluation per try). A problem stops when an accepted step lowers χ² by less
than ``rtol`` relatively twice in a row, when μ exceeds ``1e12``, or after ``max_iter``
iterations (Jacobian evaluations).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import torch

__all__ = ["LMResult", "levenberg_marquardt", "scaled_inverse"]

Residuals = Callable[[torch.Tensor, bool], tuple[torch.Tensor, torch.Tensor | None]]

_MAX_DAMPING = 1e12


@dataclass
class LMResult:
    """Outcome of :func:`levenberg_marquardt` (one row per problem)."""

    x: torch.Tensor
    chi2: torch.Tensor
    hessian: torch.Tensor
    """``JᵀJ`` over the free parameters at ``x`` (for covariances)."""
    iterations: torch.Tensor
    converged: torch.Tensor
    evaluations: torch.Tensor
    """Residual evaluations without Jacobian (the tried steps)."""


def levenberg_marquardt(
    residuals: Residuals,
    x0: torch.Tensor,
    free: torch.Tensor,
    max_iter: int = 50,
    rtol: float = 1e-6,
    damping: float = 1e-3,
    project: Callable[[torch.Tensor], torch.Tensor] | None = None,
    scaling: str = "current",
) -> LMResult:
    """Minimise ``Σ r(x)²`` for each row of ``x0``.

    Parameters
    ----------
    residuals : callable
        ``residuals(x, jacobian) → (r, J)`` for ``x`` of shape (B, P): r (B, R), J (B, R, P)
        (or None when ``jacobian`` is False).
    x0 : (B, P) tensor
        Starting points.
    free : (P,) bool tensor
        Parameters to optimise; the others stay at their ``x0`` values.
    max_iter : int
        Maximum number of iterations (Jacobian evaluations).
    rtol : float
        Relative χ² decrease below which an accepted step counts as converged.
    damping : float
        Initial μ.
    project : callable, optional
        Maps parameters back to their canonical domain after each step (e.g. pole latitude).
    scaling : {"current", "max"}
        ``D`` from the current ``diag(JᵀJ)`` or the largest met so far.

    Returns
    -------
    LMResult
    """
    if scaling not in ("current", "max"):
        raise ValueError(f"scaling must be 'current' or 'max', got {scaling!r}")
    x = x0.clone()
    batch = x.shape[0]
    index = torch.nonzero(free).flatten()
    r, jac = residuals(x, True)
    chi2 = (r * r).sum(dim=1)
    mu = torch.full((batch,), damping, dtype=x.dtype, device=x.device)
    nu = torch.full_like(mu, 2.0)
    quiet = torch.zeros(batch, dtype=torch.long, device=x.device)
    iterations = torch.zeros_like(quiet)
    evaluations = torch.zeros_like(quiet)
    active = torch.ones(batch, dtype=torch.bool, device=x.device)
    hessian, gradient = _normal_equations(jac[..., index].to(x.dtype), r.to(x.dtype))
    diagonal = torch.diagonal(hessian, dim1=1, dim2=2).clone()
    for _ in range(max_iter):
        rows = torch.nonzero(active).flatten()
        if len(rows) == 0:
            break
        trial, chi2_new, pending = x[rows].clone(), chi2[rows].clone(), torch.arange(len(rows))
        while len(pending):
            sub = rows[pending]
            scale = torch.where(diagonal[sub] > 0, diagonal[sub], torch.ones_like(diagonal[sub]))
            step = _damped_step(hessian[sub], gradient[sub], mu[sub, None] * scale)
            predicted = (mu[sub, None] * scale * step * step).sum(1) - (gradient[sub] * step).sum(1)
            candidate = x[sub].clone()
            candidate[:, index] += step
            if project is not None:
                candidate = project(candidate)
            r_new, _ = residuals(candidate, False)
            evaluations[sub] += 1
            value = (r_new * r_new).sum(dim=1)
            gain = (chi2[sub] - value) / predicted.clamp_min(torch.finfo(x.dtype).tiny)
            ok = torch.isfinite(value) & (value < chi2[sub]) & (gain > 0)
            trial[pending[ok]], chi2_new[pending[ok]] = candidate[ok], value[ok]
            good, bad = sub[ok], sub[~ok]
            mu[good] *= torch.clamp_min(1 - (2 * gain[ok] - 1) ** 3, 1 / 3)
            nu[good] = 2.0
            mu[bad] *= nu[bad]
            nu[bad] *= 2.0
            pending = pending[~ok & (mu[sub] < _MAX_DAMPING)]
        moved = chi2_new < chi2[rows]
        accepted = rows[moved]
        iterations[rows] += 1
        if len(accepted):
            decrease = (chi2[accepted] - chi2_new[moved]) / chi2[accepted]
            quiet[accepted] = torch.where(decrease < rtol, quiet[accepted] + 1, 0)
            x[accepted] = trial[moved]
            chi2[accepted] = chi2_new[moved]
            r_acc, jac_acc = residuals(x[accepted], True)
            hessian[accepted], gradient[accepted] = _normal_equations(
                jac_acc[..., index].to(x.dtype), r_acc.to(x.dtype)
            )
            current = torch.diagonal(hessian[accepted], dim1=1, dim2=2)
            diagonal[accepted] = (
                current if scaling == "current" else torch.maximum(diagonal[accepted], current)
            )
            mu[accepted] = mu[accepted].clamp_min(1e-12)
        active &= (quiet < 2) & (mu < _MAX_DAMPING)
    return LMResult(x, chi2, hessian, iterations, ~active | (quiet >= 2), evaluations)


def _damped_step(hessian: torch.Tensor, gradient: torch.Tensor, damping: torch.Tensor):
    """Solve ``(JᵀJ + diag(damping)) δ = −Jᵀr`` in Jacobi-scaled form.

    The columns of J differ by many orders of magnitude (a rotation rate in rad/s multiplies
    epochs of 10⁸–10⁹ s; shape coefficients are of order one), so ``JᵀJ`` itself has a
    condition number beyond 1/ε of float64 and a direct solve returns noise in the stiff
    directions. With ``s = √diag(JᵀJ)`` the system ``(H/ssᵀ + diag(damping)/s²) y = −g/s``,
    ``δ = y/s``, has a unit diagonal and is solved by Cholesky (LU if that fails).
    """
    diag = torch.diagonal(hessian, dim1=-2, dim2=-1)
    s = torch.sqrt(torch.where(diag > 0, diag, torch.ones_like(diag)))
    system = hessian / (s[..., :, None] * s[..., None, :]) + torch.diag_embed(damping / s**2)
    rhs = -(gradient / s)[..., None]
    factor, info = torch.linalg.cholesky_ex(system)
    if bool((info == 0).all()):
        y = torch.cholesky_solve(rhs, factor)
    else:
        y = torch.linalg.solve(system, rhs)
    return y[..., 0] / s


def scaled_inverse(hessian: torch.Tensor) -> torch.Tensor:
    """``(JᵀJ)⁻¹`` through the Jacobi-scaled matrix (see :func:`_damped_step`)."""
    diag = torch.diagonal(hessian, dim1=-2, dim2=-1)
    s = torch.sqrt(torch.where(diag > 0, diag, torch.ones_like(diag)))
    inverse = torch.linalg.inv(hessian / (s[..., :, None] * s[..., None, :]))
    return inverse / (s[..., :, None] * s[..., None, :])


def _normal_equations(jac: torch.Tensor, r: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """``JᵀJ`` and ``Jᵀr`` for a batch, (B, P, P) and (B, P)."""
    jt = jac.transpose(1, 2)
    return jt @ jac, (jt @ r[..., None])[..., 0]
