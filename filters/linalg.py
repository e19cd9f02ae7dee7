"""Batched square roots of covariance matrices that survive degenerate input (torch).

Particle clouds that collapse onto one point and Gauss–Newton covariances of unobservable
directions give covariances that are singular or have clustered eigenvalues; a Cholesky
factorisation fails on them from rounding, and LAPACK's ``syevd`` behind
``torch.linalg.eigh`` can fail to converge (``error code 5``, seen on a roughening kernel
of the box PF study). :func:`covariance_root` falls back to the SVD of the
unit-diagonal (Jacobi-scaled) matrix, which always converges.
"""

from __future__ import annotations

import torch

__all__ = ["covariance_root"]


def covariance_root(covariance: torch.Tensor) -> torch.Tensor:
    """Symmetric factor ``L`` with ``L Lᵀ = C`` for a batch of PSD matrices.

    Parameters
    ----------
    covariance : (..., n, n) tensor
        Symmetric positive semi-definite matrices (symmetrised here; negative eigenvalues
        from rounding are clipped to zero).

    Returns
    -------
    (..., n, n) tensor
        ``V diag(√λ)`` from the eigen-decomposition ``C = V diag(λ) Vᵀ`` (or the SVD of
        the scaled matrix when that does not converge).
    """
    c = 0.5 * (covariance + covariance.transpose(-1, -2))
    try:
        values, vectors = torch.linalg.eigh(c)
        return vectors * torch.sqrt(values.clamp_min(0.0))[..., None, :]
    except RuntimeError:  # torch.linalg.LinAlgError derives from RuntimeError
        scale = torch.sqrt(torch.diagonal(c, dim1=-2, dim2=-1).clamp_min(1e-300))
        scaled = c / (scale[..., :, None] * scale[..., None, :])
        u, s, _ = torch.linalg.svd(scaled)
        return scale[..., :, None] * u * torch.sqrt(s)[..., None, :]
