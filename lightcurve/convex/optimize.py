"""Batched Levenberg–Marquardt least squares in torch.

Minimises ``χ² = Σ r²`` for a batch of independent problems at once (pole starts × trial
periods), each with its own damping. Marquardt's scaled step (Moré 1978):
``(JᵀJ + μ D) δ = −Jᵀ r`` with ``D`` the largest ``diag(JᵀJ)`` met so far (MINPACK). Within
an iteration μ is multiplied by 10 until the step lowers χ² (each try costs one residual
evaluation), then the step is taken, μ divided by 10 and the Jacobian recomputed. A problem
stops when an accepted step lowers χ² by less than ``rtol`` relatively (twice in a row),
when μ exceeds ``1e12``, or after ``max_iter`` iterations (Jacobian evaluations).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import torch

__all__ = ["LMResult", "levenberg_marquardt"]

Residuals = Callable[[torch.Tensor, bool], tuple[torch.Tensor, torch.Tensor | None]]


@dataclass
class LMResult:
    """Outcome of :func:`levenberg_marquardt` (one row per problem)."""

    x: torch.Tensor
    chi2: torch.Tensor
    hessian: torch.Tensor
    """``JᵀJ`` over the free parameters at ``x`` (for covariances)."""
    iterations: torch.Tensor
    converged: torch.Tensor


def levenberg_marquardt(
    residuals: Residuals,
    x0: torch.Tensor,
    free: torch.Tensor,
    max_iter: int = 50,
    rtol: float = 1e-6,
    damping: float = 1e-3,
    project: Callable[[torch.Tensor], torch.Tensor] | None = None,
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

    Returns
    -------
    LMResult
    """
    x = x0.clone()
    batch = x.shape[0]
    index = torch.nonzero(free).flatten()
    r, jac = residuals(x, True)
    chi2 = (r * r).sum(dim=1)
    mu = torch.full((batch,), damping, dtype=x.dtype, device=x.device)
    quiet = torch.zeros(batch, dtype=torch.long, device=x.device)
    iterations = torch.zeros(batch, dtype=torch.long, device=x.device)
    active = torch.ones(batch, dtype=torch.bool, device=x.device)
    j_free = jac[..., index].to(x.dtype)
    hessian = j_free.transpose(1, 2) @ j_free
    gradient = (j_free.transpose(1, 2) @ r.to(x.dtype)[..., None])[..., 0]
    # MINPACK's scaling: the largest diag(JᵀJ) seen so far, 1 for columns still zero.
    scaling = torch.diagonal(hessian, dim1=1, dim2=2).clone()
    for _ in range(max_iter):
        rows = torch.nonzero(active).flatten()
        if len(rows) == 0:
            break
        # Rejected steps cost one residual evaluation: μ grows until the step is taken.
        trial, chi2_new, pending = x[rows].clone(), chi2[rows].clone(), torch.arange(len(rows))
        while len(pending):
            sub = rows[pending]
            diag = torch.where(scaling[sub] > 0, scaling[sub], torch.ones_like(scaling[sub]))
            system = hessian[sub] + torch.diag_embed(mu[sub, None] * diag)
            step = torch.linalg.solve(system, -gradient[sub][..., None])[..., 0]
            candidate = x[sub].clone()
            candidate[:, index] += step
            if project is not None:
                candidate = project(candidate)
            r_new, _ = residuals(candidate, False)
            value = (r_new * r_new).sum(dim=1)
            ok = torch.isfinite(value) & (value < chi2[sub])
            trial[pending[ok]], chi2_new[pending[ok]] = candidate[ok], value[ok]
            mu[sub[~ok]] *= 10
            pending = pending[~ok & (mu[sub] < 1e12)]
        moved = chi2_new < chi2[rows]
        accepted = rows[moved]
        iterations[rows] += 1
        if len(accepted):
            gain = (chi2[accepted] - chi2_new[moved]) / chi2[accepted]
            quiet[accepted] = torch.where(gain < rtol, quiet[accepted] + 1, 0)
            x[accepted] = trial[moved]
            chi2[accepted] = chi2_new[moved]
            r_acc, jac_acc = residuals(x[accepted], True)
            jf = jac_acc[..., index].to(x.dtype)
            hessian[accepted] = jf.transpose(1, 2) @ jf
            scaling[accepted] = torch.maximum(
                scaling[accepted], torch.diagonal(hessian[accepted], dim1=1, dim2=2)
            )
            gradient[accepted] = (jf.transpose(1, 2) @ r_acc.to(x.dtype)[..., None])[..., 0]
            mu[accepted] = (mu[accepted] / 10).clamp_min(1e-9)
        active &= (quiet < 2) & (mu < 1e12)
    return LMResult(x, chi2, hessian, iterations, ~active | (quiet >= 2))
