"""Modes of a weighted particle cloud over ``(q, ω[, k][, shape])``.

Particles are clustered greedily by attitude angle and rate difference, within a shape;
each cluster is a **mode** with its weight, its weighted quaternion mean (Markley et al.
2007, "Averaging quaternions", :func:`filters.attitude.quaternion_mean`) and its spread.
:class:`filters.particle.AttitudeParticleFilter` uses the clusters for its per-mode
roughening kernels, its estimate and its list of posterior modes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from filters.attitude import (
    attitude_angle,
    quaternion_canonical,
    quaternion_conjugate,
    quaternion_mean,
    quaternion_multiply,
    quaternion_to_rotation_vector,
)

__all__ = ["Mode", "greedy_clusters", "heaviest_mode", "weighted_modes"]


@dataclass(frozen=True)
class Mode:
    """A cluster of particles.

    Attributes
    ----------
    quaternion : (4,) numpy.ndarray
        Weighted mean attitude (sign-canonical).
    omega : (3,) numpy.ndarray
        Weighted mean body rates (rad/s).
    weight : float
        Total weight of the cluster.
    shape : int
        Shape index of the cluster.
    attitude_sigma : float
        RMS attitude deviation of the members from the mean (rad).
    omega_sigma : (3,) numpy.ndarray
        Standard deviation of the members' rates (rad/s).
    k : (2,) numpy.ndarray or None
        Weighted mean tanh inertia parameters.
    """

    quaternion: np.ndarray
    omega: np.ndarray
    weight: float
    shape: int
    attitude_sigma: float
    omega_sigma: np.ndarray
    k: np.ndarray | None = None


def greedy_clusters(
    q: torch.Tensor,
    omega: torch.Tensor,
    shape: torch.Tensor,
    weights: torch.Tensor,
    *,
    angle: float,
    rate: float,
    max_clusters: int,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Greedy clustering: the heaviest unassigned particle seeds a cluster of every
    unassigned particle of its shape within ``angle`` (rad) and ``rate`` (rad/s); after
    ``max_clusters`` seeds every shape still without one gets one, and the rest join their
    nearest seed of the same shape (so the cost stays ``O(max_clusters · N)``). Among
    equally heavy particles (all of them after a resampling) the first in particle order
    seeds: an unstable sort would leave that choice, and with it the clusters, to the
    sorting kernel of the processor.

    Parameters
    ----------
    q : (N, 4) tensor
    omega : (N, 3) tensor
    shape : (N,) long tensor
    weights : (N,) tensor

    Returns
    -------
    labels : (N,) long tensor
    centers : (C, 4) tensor
        Seed attitude of each cluster.
    """
    labels = torch.full((len(q),), -1, dtype=torch.long)
    seeds: list[int] = []
    cos_half = math.cos(0.5 * angle)
    order = torch.argsort(weights, descending=True, stable=True)
    while len(seeds) < max_clusters:
        free = order[labels[order] < 0]
        if len(free) == 0:
            break
        seed = int(free[0])
        # angle(q, q_s) ≤ θ  ⇔  |q · q_s| ≥ cos(θ/2): one matrix-vector product.
        near = (
            (labels < 0)
            & (shape == shape[seed])
            & (torch.abs(q @ q[seed]) >= cos_half)
            & (torch.linalg.vector_norm(omega - omega[seed], dim=1) <= rate)
        )
        near[seed] = True
        labels[near] = len(seeds)
        seeds.append(seed)
    unseeded = (labels < 0) & ~torch.isin(shape, shape[seeds])
    for value in torch.unique(shape[unseeded]).tolist():
        members = unseeded & (shape == value)
        labels[members] = len(seeds)
        seeds.append(int(order[members[order]][0]))
    rest = labels < 0
    if rest.any():
        closeness = torch.abs(q[rest] @ q[seeds].T)
        closeness = torch.where(shape[rest][:, None] == shape[seeds][None], closeness, -1.0)
        labels[rest] = torch.argmax(closeness, dim=1)
    return labels, q[seeds]


def weighted_modes(
    q: torch.Tensor,
    omega: torch.Tensor,
    shape: torch.Tensor,
    log_weights: torch.Tensor,
    labels: torch.Tensor,
    *,
    k: torch.Tensor | None = None,
    min_weight: float = 0.01,
) -> list[Mode]:
    """The clusters ``labels`` of normalised log-weighted particles as modes, heaviest
    first; clusters lighter than ``min_weight`` are left out."""
    weights = torch.exp(log_weights)
    out = []
    for c in range(int(labels.max()) + 1):
        members = labels == c
        w = weights[members]
        total = float(w.sum())
        if total < min_weight:
            continue
        # normalised in the log domain: defined even when the total underflows to 0
        log_w = log_weights[members]
        finite = bool(torch.isfinite(log_w).any())
        wn = torch.softmax(log_w, dim=0) if finite else torch.full_like(log_w, 1 / len(log_w))
        qm = quaternion_mean(q[members], wn)
        wm = (wn[:, None] * omega[members]).sum(dim=0)
        angle = attitude_angle(q[members], qm[None])
        km = None if k is None else (wn[:, None] * k[members]).sum(dim=0).numpy()
        out.append(
            Mode(
                quaternion=quaternion_canonical(qm).numpy(),
                omega=wm.numpy(),
                weight=total,
                shape=int(shape[members][0]),
                attitude_sigma=float(torch.sqrt(torch.sum(wn * angle**2))),
                omega_sigma=torch.sqrt(
                    torch.sum(wn[:, None] * (omega[members] - wm) ** 2, dim=0)
                ).numpy(),
                k=km,
            )
        )
    return sorted(out, key=lambda m: -m.weight)


def heaviest_mode(
    q: torch.Tensor, omega: torch.Tensor, weights: torch.Tensor, labels: torch.Tensor
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean state of the heaviest cluster and its covariance.

    Returns
    -------
    q : (4,) numpy.ndarray
        Weighted quaternion mean of the heaviest cluster (sign-canonical).
    omega : (3,) numpy.ndarray
        Weighted mean rates (rad/s).
    covariance : (6, 6) numpy.ndarray
        Weighted covariance of ``[δθ, ω]`` of the cluster's particles about the mean
        (rad², rad²/s²).
    """
    mass = torch.zeros(int(labels.max()) + 1, dtype=weights.dtype).index_add_(0, labels, weights)
    members = labels == int(torch.argmax(mass))
    wn = weights[members] / weights[members].sum()
    qm = quaternion_canonical(quaternion_mean(q[members], wn))
    dtheta = quaternion_to_rotation_vector(
        quaternion_multiply(q[members], quaternion_conjugate(qm)[None])
    )
    state = torch.cat([dtheta, omega[members]], dim=1)
    mean = (wn[:, None] * state).sum(dim=0)
    dev = state - mean
    covariance = (wn[:, None] * dev).T @ dev
    return qm.numpy(), mean[3:].numpy(), covariance.numpy()
