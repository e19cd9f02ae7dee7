"""Roughening of a resampled particle cloud: per-cluster Gaussian kernels on SO(3) × ℝⁿ.

After resampling, each particle is jittered by ``N(0, h² C_c)`` (Musso, Oudjane & Le Gland
2001), ``C_c`` the weighted covariance of its cluster ``c`` in the local state
``[δθ (rotation vector about the cluster's centre attitude), ω, k]`` and the bandwidth

``h = b (4/(d + 2))^{1/(d+4)} N_c^{−1/(d+4)}``

(``d`` the dimension, ``N_c`` the cluster's effective sample size, ``b ≤ 1`` a shrink
factor). The attitude part of a jitter is applied on SO(3): ``q ← exp(δθ) ⊗ q``. Used by
:class:`filters.particle.AttitudeParticleFilter`.

References
----------
Musso, C., Oudjane, N. & Le Gland, F. (2001). Improving regularised particle filters. In
*Sequential Monte Carlo Methods in Practice*, Springer, 247–271.
"""

from __future__ import annotations

from typing import Any

import torch

from filters.attitude import (
    quaternion_conjugate,
    quaternion_multiply,
    quaternion_normalize,
    quaternion_to_rotation_vector,
    rotation_vector_to_quaternion,
)

__all__ = ["jittered", "kernel_covariance", "local_state"]


def local_state(
    q: torch.Tensor, omega: torch.Tensor, k: Any, q_center: torch.Tensor
) -> torch.Tensor:
    """``[δθ about q_center, ω(, k)]`` of every particle.

    Parameters
    ----------
    q : (N, 4) tensor
        Attitudes (inertial → body).
    omega : (N, 3) tensor
        Body rates (rad/s).
    k : (N, 2) tensor or None
        Tanh inertia parameters, if part of the state.
    q_center : (N, 4) tensor
        Centre attitude of every particle's cluster.

    Returns
    -------
    (N, d) tensor
        ``δθ`` (rad, rotation vector of ``q ⊗ q_center⁻¹``), ``ω`` and ``k``.
    """
    dtheta = quaternion_to_rotation_vector(quaternion_multiply(q, quaternion_conjugate(q_center)))
    parts = [dtheta, omega] + ([k] if k is not None else [])
    return torch.cat(parts, dim=1)


def kernel_covariance(
    state: torch.Tensor,
    labels: torch.Tensor,
    n_clusters: int,
    weights: torch.Tensor,
    bandwidth: float,
) -> torch.Tensor:
    """Kernel covariance ``h² C_c`` of every cluster from the weighted particles.

    Parameters
    ----------
    state : (N, d) tensor
        Local states (:func:`local_state`).
    labels : (N,) long tensor
        Cluster of every particle, in ``[0, n_clusters)``.
    n_clusters : int
    weights : (N,) tensor
        Particle weights (any scale per cluster).
    bandwidth : float
        Shrink factor ``b``.

    Returns
    -------
    (C, d, d) tensor
        ``h² C_c``, ``h`` from the cluster's effective sample size; zero for a cluster
        whose particles carry no weight.
    """
    c, d, dtype = n_clusters, state.shape[1], state.dtype
    total = torch.zeros(c, dtype=dtype).index_add_(0, labels, weights)
    # Weights normalised within each cluster: a light cluster (total 1e-200, say) keeps
    # O(1) weights, so neither its mean nor its effective size underflows to 0/0.
    w = weights / torch.where(total > 0, total, torch.ones_like(total))[labels]
    squares = torch.zeros(c, dtype=dtype).index_add_(0, labels, w * w)
    mean = torch.zeros((c, d), dtype=dtype).index_add_(0, labels, w[:, None] * state)
    dev = state - mean[labels]
    outer = w[:, None, None] * dev[:, :, None] * dev[:, None, :]
    covariance = torch.zeros((c, d, d), dtype=dtype).index_add_(0, labels, outer)
    m_eff = 1.0 / torch.where(squares > 0, squares, torch.ones_like(squares))
    h = bandwidth * (4.0 / (d + 2)) ** (1.0 / (d + 4)) * m_eff ** (-1.0 / (d + 4))
    # A cluster whose particles carry no weight at all gets no jitter.
    return torch.nan_to_num((h * h)[:, None, None] * covariance, nan=0.0, posinf=0.0)


def jittered(
    q: torch.Tensor, omega: torch.Tensor, k: Any, root: torch.Tensor, generator: torch.Generator
) -> tuple[torch.Tensor, torch.Tensor, Any]:
    """Particles moved by ``root @ N(0, I)``.

    Parameters
    ----------
    q, omega, k : tensors
        As in :func:`local_state`.
    root : (N, d, d) tensor
        Square roots of the kernel covariances, per particle.
    generator : torch.Generator
        Source of the standard normal draws.

    Returns
    -------
    q, omega, k
        Jittered attitudes (``exp(δθ) ⊗ q``, renormalised), rates (rad/s) and ``k``.
    """
    d = root.shape[-1]
    noise = torch.randn((len(q), d, 1), generator=generator, dtype=q.dtype)
    step = (root @ noise)[..., 0]
    q = quaternion_normalize(quaternion_multiply(rotation_vector_to_quaternion(step[:, :3]), q))
    omega = omega + step[:, 3:6]
    k = None if k is None else k + step[:, 6:8]
    return q, omega, k
