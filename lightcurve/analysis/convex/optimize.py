"""Batched Levenberg–Marquardt least squares (numpy; torch problems are accepted too).

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

The iteration runs on numpy arrays. A problem posed in torch (``x0`` a tensor, residuals
returning tensors) is solved the same way, its arrays converted at the boundary, and the
result is returned as tensors on ``x0``'s device.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

__all__ = ["LMResult", "levenberg_marquardt", "scaled_inverse"]

Residuals = Callable[[Any, bool], tuple[Any, Any]]

_MAX_DAMPING = 1e12


@dataclass
class LMResult:
    """Outcome of :func:`levenberg_marquardt` (one row per problem)."""

    x: Any
    chi2: Any
    hessian: Any
    """``JᵀJ`` over the free parameters at ``x`` (for covariances)."""
    iterations: Any
    converged: Any
    evaluations: Any
    """Residual evaluations without Jacobian (the tried steps)."""
    stopped: Any = None
    """Problems ended early by ``stop`` (neither converged nor out of iterations)."""


def levenberg_marquardt(
    residuals: Residuals,
    x0: Any,
    free: Any,
    *,
    max_iter: int = 50,
    rtol: float = 1e-6,
    damping: float = 1e-3,
    project: Callable[[np.ndarray], np.ndarray] | None = None,
    scaling: str = "current",
    stop: Callable[[int, np.ndarray, np.ndarray], np.ndarray] | None = None,
) -> LMResult:
    """Minimise ``Σ r(x)²`` for each row of ``x0``.

    Parameters
    ----------
    residuals : callable
        ``residuals(x, jacobian) → (r, J)`` for ``x`` of shape (B, P): r (B, R), J (B, R, P)
        or only the columns of the free parameters (B, R, Q) (None when ``jacobian`` is
        False).
    x0 : (B, P) array or tensor
        Starting points.
    free : (P,) bool array or tensor
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
    stop : callable, optional
        ``stop(iteration, chi2, active) → (B,) bool``: problems to end now, called after
        every iteration with the current χ² of all problems and the mask of those still
        running (early rejection in period scans).

    Returns
    -------
    LMResult
        numpy arrays, or tensors on ``x0``'s device when ``x0`` is a torch tensor.
    """
    if scaling not in ("current", "max"):
        raise ValueError(f"scaling must be 'current' or 'max', got {scaling!r}")
    if not isinstance(x0, np.ndarray) and type(x0).__module__.startswith("torch"):
        return _solve_torch(
            residuals,
            x0,
            free,
            max_iter=max_iter,
            rtol=rtol,
            damping=damping,
            project=project,
            scaling=scaling,
            stop=stop,
        )
    x = np.array(x0, dtype=float)
    batch = x.shape[0]
    index = np.flatnonzero(np.asarray(free))
    r, jac = residuals(x, True)
    chi2 = (r * r).sum(axis=1)
    mu = np.full(batch, damping)
    nu = np.full(batch, 2.0)
    quiet = np.zeros(batch, dtype=int)
    iterations = np.zeros(batch, dtype=int)
    evaluations = np.zeros(batch, dtype=int)
    active = np.ones(batch, dtype=bool)
    stopped = np.zeros(batch, dtype=bool)
    hessian, gradient = _normal_equations(_free_columns(jac, index), r)
    diagonal = np.diagonal(hessian, axis1=1, axis2=2).copy()
    for iteration in range(max_iter):
        rows = np.flatnonzero(active)
        if len(rows) == 0:
            break
        trial, chi2_new, pending = x[rows].copy(), chi2[rows].copy(), np.arange(len(rows))
        while len(pending):
            sub = rows[pending]
            scale = np.where(diagonal[sub] > 0, diagonal[sub], 1.0)
            step = _damped_step(hessian[sub], gradient[sub], mu[sub, None] * scale)
            predicted = (mu[sub, None] * scale * step * step).sum(1) - (gradient[sub] * step).sum(1)
            candidate = x[sub].copy()
            candidate[:, index] += step
            if project is not None:
                candidate = project(candidate)
            # A step too long can overflow the model; its χ² is then not finite and the step
            # is rejected like any other that does not lower χ², without numpy's warnings.
            with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
                r_new, _ = residuals(candidate, False)
                value = (r_new * r_new).sum(axis=1)
            evaluations[sub] += 1
            with np.errstate(invalid="ignore"):
                gain = (chi2[sub] - value) / np.maximum(predicted, np.finfo(float).tiny)
                ok = np.isfinite(value) & (value < chi2[sub]) & (gain > 0)
            trial[pending[ok]], chi2_new[pending[ok]] = candidate[ok], value[ok]
            good, bad = sub[ok], sub[~ok]
            mu[good] *= np.maximum(1 - (2 * gain[ok] - 1) ** 3, 1 / 3)
            nu[good] = 2.0
            mu[bad] *= nu[bad]
            nu[bad] *= 2.0
            pending = pending[~ok & (mu[sub] < _MAX_DAMPING)]
        moved = chi2_new < chi2[rows]
        accepted = rows[moved]
        iterations[rows] += 1
        if len(accepted):
            decrease = (chi2[accepted] - chi2_new[moved]) / chi2[accepted]
            quiet[accepted] = np.where(decrease < rtol, quiet[accepted] + 1, 0)
            x[accepted] = trial[moved]
            chi2[accepted] = chi2_new[moved]
            r_acc, jac_acc = residuals(x[accepted], True)
            hessian[accepted], gradient[accepted] = _normal_equations(
                _free_columns(jac_acc, index), r_acc
            )
            current = np.diagonal(hessian[accepted], axis1=1, axis2=2)
            diagonal[accepted] = (
                current if scaling == "current" else np.maximum(diagonal[accepted], current)
            )
            mu[accepted] = np.maximum(mu[accepted], 1e-12)
        active &= (quiet < 2) & (mu < _MAX_DAMPING)
        if stop is not None and active.any():
            ended = np.asarray(stop(iteration + 1, chi2, active), dtype=bool) & active
            stopped |= ended
            active &= ~ended
    converged = (~active | (quiet >= 2)) & ~stopped
    return LMResult(x, chi2, hessian, iterations, converged, evaluations, stopped)


def _solve_torch(residuals, x0, free, *, max_iter, rtol, damping, project, scaling, stop):
    """:func:`levenberg_marquardt` of a problem posed in torch (see the module docstring)."""
    import torch

    def as_tensor(array):
        return torch.as_tensor(array, dtype=x0.dtype, device=x0.device)

    def as_array(tensor):
        return None if tensor is None else tensor.detach().cpu().numpy().astype(float)

    def numpy_residuals(x, jacobian):
        r, jac = residuals(as_tensor(x), jacobian)
        return as_array(r), as_array(jac)

    numpy_project = None if project is None else (lambda x: as_array(project(as_tensor(x))))
    result = levenberg_marquardt(
        numpy_residuals,
        as_array(x0),
        as_array(torch.as_tensor(free)).astype(bool),
        max_iter=max_iter,
        rtol=rtol,
        damping=damping,
        project=numpy_project,
        scaling=scaling,
        stop=stop,
    )
    floats = ("x", "chi2", "hessian")
    return LMResult(
        **{
            f.name: (
                as_tensor(getattr(result, f.name))
                if f.name in floats
                else torch.as_tensor(getattr(result, f.name), device=x0.device)
            )
            for f in fields(result)
        }
    )


def _damped_step(hessian: np.ndarray, gradient: np.ndarray, damping: np.ndarray) -> np.ndarray:
    """Solve ``(JᵀJ + diag(damping)) δ = −Jᵀr`` in Jacobi-scaled form.

    The columns of J differ by many orders of magnitude (a rotation rate in rad/s multiplies
    epochs of 10⁸–10⁹ s; shape coefficients are of order one), so ``JᵀJ`` itself has a
    condition number beyond 1/ε of float64 and a direct solve returns noise in the stiff
    directions. With ``s = √diag(JᵀJ)`` the system ``(H/ssᵀ + diag(damping)/s²) y = −g/s``,
    ``δ = y/s``, has a unit diagonal and is solved by LU (batched LAPACK).
    """
    diag = np.diagonal(hessian, axis1=-2, axis2=-1)
    s = np.sqrt(np.where(diag > 0, diag, 1.0))
    system = hessian / (s[..., :, None] * s[..., None, :])
    system[..., np.arange(s.shape[-1]), np.arange(s.shape[-1])] += damping / s**2
    y = np.linalg.solve(system, -(gradient / s)[..., None])[..., 0]
    return y / s


def scaled_inverse(hessian: Any) -> Any:
    """``(JᵀJ)⁻¹`` through the Jacobi-scaled matrix (see :func:`_damped_step`); numpy or
    torch in, the same out."""
    if not isinstance(hessian, np.ndarray) and type(hessian).__module__.startswith("torch"):
        import torch

        array = hessian.detach().cpu().numpy().astype(float)
        return torch.as_tensor(scaled_inverse(array), dtype=hessian.dtype, device=hessian.device)
    diag = np.diagonal(hessian, axis1=-2, axis2=-1)
    s = np.sqrt(np.where(diag > 0, diag, 1.0))
    inverse = np.linalg.inv(hessian / (s[..., :, None] * s[..., None, :]))
    return inverse / (s[..., :, None] * s[..., None, :])


def _free_columns(jac: np.ndarray, index: np.ndarray) -> np.ndarray:
    """The free parameters' columns of J (already so when it has as many columns)."""
    return jac if jac.shape[-1] == len(index) else jac[..., index]


def _normal_equations(jac: np.ndarray, r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``JᵀJ`` and ``Jᵀr`` for a batch, (B, P, P) and (B, P)."""
    jt = np.swapaxes(jac, 1, 2)
    return jt @ jac, (jt @ r[..., None])[..., 0]
