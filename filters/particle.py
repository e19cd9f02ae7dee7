"""Particle filter for attitude, rates, optional inertia and a discrete shape index.

Each particle carries ``x = (q, ω[, k][, s])``: an attitude (inertial → body), body rates
(rad/s), optionally the two tanh inertia parameters ``k`` (Feng et al.) and a shape index
``s`` (joint attitude–shape inversion over a library). All particles are propagated
(torque-free RK4) and rendered in one batched torch call per shape, and the filter works
in log-weights:

* **Update** (SIR, Gordon, Salmond & Smith 1993): ``log w_i += β ℓ_i`` with the
  measurement log-likelihood ``ℓ_i`` — Gaussian, ``−½ ν_i²/R``, or Student-t with ``ν``
  degrees of freedom, ``−(ν + 1)/2 · ln(1 + ν_i²/(ν R))``, which tolerates outliers.
* **Tempering** (adaptive likelihood annealing, Neal 2001; Del Moral, Doucet & Jasra
  2006): when the whole likelihood would drop the effective sample size
  ``ESS = 1/Σ w_i²`` below ``ess_threshold · N``, only the fraction ``β`` that just
  reaches it (found by bisection) is applied; the particles are resampled and moved,
  their likelihood re-evaluated, and the rest of the likelihood follows in further
  stages.
* **Resampling**: systematic (Kitagawa 1996), whenever ESS falls below the threshold.
* **Mixture tracking** (Vermaak, Doucet & Pérez 2003): optionally every particle belongs
  to a mixture *component* (e.g. the initial-search candidate it was seeded around). The
  filtering density is then ``Σ_c π_c p_c(x)``; the global weights still carry
  ``π_c · w_{i|c}``, so ``π_c`` follows the component's predictive likelihood, but the
  ESS test, resampling and roughening work *within* each component, and tempering
  follows the weight-averaged ``Σ_c π_c ESS_c/N_c``. A component whose weight falls
  to 10⁻⁸ keeps its particles and can win back weight later — plain SIR resampling
  would have drained it for good, which loses the true mode whenever a photometric twin
  fits the early measurements slightly better.
* **Roughening / regularisation** (Musso, Oudjane & Le Gland 2001): after resampling,
  each particle is jittered by ``N(0, h² C_c)`` with ``C_c`` the weighted covariance of
  its cluster ``c`` (its mixture component, or with one component a greedy cluster) in
  ``[δθ (rotation vector about the cluster's centre attitude), ω, k]`` and the
  kernel bandwidth ``h = b (4/(d + 2))^{1/(d+4)} N_c^{−1/(d+4)}`` (``d`` the dimension,
  ``b ≤ 1`` a shrink factor). Per-mode covariances keep a multi-modal cloud from being
  smeared across its modes. The attitude jitter is applied on SO(3):
  ``q ← exp(δθ) ⊗ q``.
* **Resample-move** (Gilks & Berzuini 2001): optionally each jitter is a
  Metropolis–Hastings proposal accepted with probability
  ``min(1, exp(λ(x') − λ(x)))``, ``λ`` a tempered log-target supplied by the caller (for
  light curves: the likelihood of a window of recent measurements, see
  :mod:`lightcurve.inversion`). The jitter kernel is symmetric, so no proposal ratio.
* **Estimates**: the weighted quaternion mean (Markley et al. 2007,
  :func:`filters.attitude.quaternion_mean`) of the heaviest mode and its covariance, and
  the **modes**: particles clustered greedily by attitude angle and rate difference
  (optionally modulo a shape's symmetry group), each with its weight.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from filters.attitude import (
    PrincipalInertia,
    propagate_torque_free,
    quaternion_normalize,
    ratios_from_tanh,
)
from filters.linalg import covariance_root
from filters.particle_modes import Mode, greedy_clusters, heaviest_mode, weighted_modes
from filters.resampling import systematic_resample
from filters.roughening import jittered, kernel_covariance, local_state

__all__ = [
    "AttitudeParticleFilter",
    "Mode",
    "ParticleUpdate",
    "systematic_resample",
]

#: ``measure(q (N, 4), shape (N,) long) → (N,)`` predicted measurements (torch).
ParticleMeasure = Callable[[torch.Tensor, torch.Tensor], torch.Tensor]
#: ``target(q, ω, k, shape) → (N,)`` log-density used by resample-move.
MoveTarget = Callable[[torch.Tensor, torch.Tensor, Any, torch.Tensor], torch.Tensor]


@dataclass(frozen=True)
class ParticleUpdate:
    """Diagnostics of one measurement update.

    Attributes
    ----------
    predicted : float
        Weighted mean predicted measurement before the update.
    variance : float
        Weighted variance of the particles' predictions before the update.
    log_evidence : float
        ``ln Σ w_i p(z | x_i)`` (the measurement's marginal likelihood, tempered stages
        combined).
    ess : float
        Effective sample size after the update.
    stages : int
        Tempering stages used (1: the likelihood was applied at once).
    resampled : int
        Resampling events during the update.
    acceptance : float
        Mean Metropolis–Hastings acceptance of the moves (NaN without moves).
    """

    predicted: float
    variance: float
    log_evidence: float
    ess: float
    stages: int
    resampled: int
    acceptance: float


class AttitudeParticleFilter:
    """SIR / regularised particle filter over ``(q, ω[, k][, shape])``.

    Parameters
    ----------
    q : (N, 4) array
        Initial attitudes.
    omega : (N, 3) array
        Initial body rates (rad/s).
    inertias : sequence of (3, 3) arrays
        Inertia of each shape (any scale).
    log_weights : (N,) array, optional
        Initial log-weights (uniform when omitted), e.g. ``log prior − log proposal``.
    k : (N, 2) array, optional
        Tanh inertia parameters; their presence makes the inertia part of the state.
    shape : (N,) int array, optional
        Shape index of each particle (all 0 when omitted).
    principal_axes : sequence of (3, 3) arrays, optional
        Principal axes (columns) of each shape for the tanh inertia form.
    components : (N,) int array, optional
        Mixture component of each particle (mixture tracking); omitted: one component.
        The particles are reordered so that each component is contiguous.
    likelihood : {"gaussian", "student"}
        Measurement likelihood.
    nu : float
        Degrees of freedom of the Student-t likelihood.
    ess_threshold : float
        Resample / temper when ``ESS < ess_threshold · N``.
    bandwidth : float
        Shrink factor ``b`` of the roughening kernel (0 disables roughening).
    mode_angle, mode_rate : float
        Clustering radii for the roughening covariances and :meth:`modes` (rad, rad/s).
    max_clusters : int
        Most clusters seeded; further particles join the nearest one.
    max_step : float
        Largest RK4 step (s); 2 s keeps the RK4 error below 10⁻⁷ rad per step up to 5°/s.
    seed : int, optional
        Seed of the filter's torch generator.
    dtype : torch.dtype

    Attributes
    ----------
    q, omega, k, shape, component, log_weights : tensors
        The particles.
    n_components : int
        Number of mixture components.
    """

    def __init__(
        self,
        q: Any,
        omega: Any,
        inertias: Sequence[Any],
        *,
        log_weights: Any = None,
        k: Any = None,
        shape: Any = None,
        principal_axes: Sequence[Any] | None = None,
        components: Any = None,
        likelihood: str = "gaussian",
        nu: float = 4.0,
        ess_threshold: float = 0.5,
        bandwidth: float = 0.5,
        mode_angle: float = math.radians(10.0),
        mode_rate: float = math.radians(0.5),
        max_clusters: int = 32,
        max_step: float = 2.0,
        seed: int | None = None,
        dtype: torch.dtype = torch.float64,
    ) -> None:
        if likelihood not in ("gaussian", "student"):
            raise ValueError(f"likelihood must be 'gaussian' or 'student', got {likelihood!r}")
        self.dtype = dtype
        self.q = quaternion_normalize(torch.as_tensor(np.asarray(q), dtype=dtype))
        self.omega = torch.as_tensor(np.asarray(omega), dtype=dtype)
        n = len(self.q)
        self.k = None if k is None else torch.as_tensor(np.asarray(k), dtype=dtype)
        self.shape = (
            torch.zeros(n, dtype=torch.long)
            if shape is None
            else torch.as_tensor(np.asarray(shape), dtype=torch.long)
        )
        self.log_weights = (
            torch.zeros(n, dtype=dtype)
            if log_weights is None
            else torch.as_tensor(np.asarray(log_weights), dtype=dtype)
        )
        labels = np.zeros(n, dtype=np.int64) if components is None else np.asarray(components)
        if labels.shape != (n,):
            raise ValueError(f"components must have shape ({n},), got {labels.shape}")
        _, dense = np.unique(labels, return_inverse=True)
        self.component = torch.as_tensor(dense.reshape(n), dtype=torch.long)
        self.n_components = int(self.component.max()) + 1
        self._counts = torch.bincount(self.component).to(dtype)
        self._group_components()
        self._normalise()
        self.inertias = torch.as_tensor(np.stack([np.asarray(j) for j in inertias]), dtype=dtype)
        axes = principal_axes or [np.eye(3)] * len(inertias)
        self.axes = torch.as_tensor(np.stack([np.asarray(a) for a in axes]), dtype=dtype)
        self._principal = PrincipalInertia.from_inertia(self.inertias)
        self._tanh_frames = PrincipalInertia.from_tanh(np.zeros(2), self.axes)
        self.likelihood = likelihood
        self.nu = float(nu)
        self.ess_threshold = float(ess_threshold)
        self.bandwidth = float(bandwidth)
        self.mode_angle = float(mode_angle)
        self.mode_rate = float(mode_rate)
        self.max_clusters = int(max_clusters)
        self.max_step = float(max_step)
        self.generator = torch.Generator().manual_seed(0 if seed is None else int(seed))

    def __len__(self) -> int:
        return len(self.q)

    # ------------------------------------------------------------------ weights
    @property
    def weights(self) -> torch.Tensor:
        """Normalised weights (N,)."""
        return torch.exp(self.log_weights)

    @property
    def ess(self) -> float:
        """Effective sample size ``1/Σ w²``."""
        return float(1.0 / torch.sum(self.weights**2))

    def _normalise(self) -> float:
        """Normalise the log-weights; return the log of their previous sum."""
        total = torch.logsumexp(self.log_weights, dim=0)
        self.log_weights = self.log_weights - total
        return float(total)

    def component_weights(self) -> np.ndarray:
        """Weight ``π_c`` of each mixture component, shape (C,)."""
        return self._component_sums(self.weights).numpy()

    def _component_sums(self, values: torch.Tensor) -> torch.Tensor:
        if self.n_components == 1:
            return values.sum(dim=0, keepdim=True)
        return torch.zeros(self.n_components, dtype=values.dtype).index_add_(
            0, self.component, values
        )

    def _within_log_weights(self, log_weights: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Log-weights normalised within each component, and each component's log-mass."""
        if self.n_components == 1:
            total = torch.logsumexp(log_weights, dim=0)
            return log_weights - total, total[None]
        peak = torch.full((self.n_components,), -math.inf, dtype=log_weights.dtype)
        peak = peak.scatter_reduce(0, self.component, log_weights, reduce="amax")
        peak = torch.where(torch.isfinite(peak), peak, torch.zeros_like(peak))
        mass = self._component_sums(torch.exp(log_weights - peak[self.component]))
        log_mass = torch.log(mass) + peak
        return log_weights - log_mass[self.component], log_mass

    def _group_components(self) -> None:
        """Reorder the particles so that every component is a contiguous block."""
        order = torch.argsort(self.component, stable=True)
        self._take(order)
        self.component = self.component[order]

    def _take(self, index: torch.Tensor) -> None:
        """Keep the particles ``index`` (log-weights included, component labels not)."""
        self.q, self.omega, self.shape = self.q[index], self.omega[index], self.shape[index]
        self.log_weights = self.log_weights[index]
        if self.k is not None:
            self.k = self.k[index]

    def shape_probabilities(self, n_shapes: int) -> np.ndarray:
        """Posterior probability of each shape index, shape (n_shapes,)."""
        return (
            torch.zeros(n_shapes, dtype=self.dtype).index_add_(0, self.shape, self.weights).numpy()
        )

    # ------------------------------------------------------------------ dynamics
    def _inertia(self) -> PrincipalInertia:
        if self.k is None:
            shape = self.shape.numpy()
            if bool((shape == shape[0]).all()):
                return self._principal.select(shape[0])
            return self._principal.select(shape)
        frames = self._tanh_frames.select(self.shape.numpy())
        return frames._replace(ratios=ratios_from_tanh(self.k.numpy()))

    def predict(self, dt: float) -> None:
        """Propagate every particle over ``dt`` seconds (torque-free, deterministic)."""
        self.q, self.omega = propagate_torque_free(
            self.q, self.omega, self._inertia(), float(dt), self.max_step
        )

    # ------------------------------------------------------------------ update
    def log_likelihood(self, predicted: torch.Tensor, z: float, r: float) -> torch.Tensor:
        """Per-particle measurement log-likelihood (up to a constant common to all)."""
        nu2 = (predicted - z) ** 2 / r
        if self.likelihood == "gaussian":
            out = -0.5 * nu2 - 0.5 * math.log(2 * math.pi * r)
        else:
            nu = self.nu
            out = (
                -0.5 * (nu + 1.0) * torch.log1p(nu2 / nu)
                + math.lgamma(0.5 * (nu + 1.0))
                - math.lgamma(0.5 * nu)
                - 0.5 * math.log(nu * math.pi * r)
            )
        return torch.nan_to_num(out, nan=-math.inf)

    def update(
        self,
        z: float,
        r: float,
        measure: ParticleMeasure,
        move_target: MoveTarget | None = None,
        moves: int = 1,
        max_stages: int = 50,
    ) -> ParticleUpdate:
        """Weight the particles by one scalar measurement, tempering when needed.

        Parameters
        ----------
        z : float
            Measurement.
        r : float
            Its variance.
        measure : callable
            ``measure(q (N, 4), shape (N,)) → (N,)`` predictions at this epoch.
        move_target : callable, optional
            Log-target of the resample-move step (``None``: plain roughening).
        moves : int
            Metropolis–Hastings moves per resampling (with ``move_target``).
        max_stages : int
            Upper bound on tempering stages (the last one applies the rest at once).

        Returns
        -------
        ParticleUpdate
        """
        predicted = measure(self.q, self.shape)
        mean_prediction = float(torch.sum(self.weights * predicted))
        variance = float(torch.sum(self.weights * (predicted - mean_prediction) ** 2))
        loglik = self.log_likelihood(predicted, z, r)
        remaining, stages, resampled, evidence = 1.0, 0, 0, 0.0
        acceptance: list[float] = []
        while remaining > 0.0:
            stages += 1
            beta = remaining if stages >= max_stages else self._tempering_step(loglik, remaining)
            self.log_weights = self.log_weights + beta * loglik
            evidence += self._normalise()
            remaining = remaining - beta if beta < remaining else 0.0
            depleted = self._depleted(self.log_weights)
            if bool(depleted.any()):
                resampled += 1
                acceptance.extend(self._resample_move(depleted, move_target, moves))
                if remaining > 0.0:
                    loglik = self.log_likelihood(measure(self.q, self.shape), z, r)
        return ParticleUpdate(
            mean_prediction,
            variance,
            evidence,
            self.ess,
            stages,
            resampled,
            float(np.mean(acceptance)) if acceptance else math.nan,
        )

    def _component_ess(self, log_weights: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Effective sample size of every component over its particle count, and the
        log-mass of every component, both (C,)."""
        within, log_mass = self._within_log_weights(log_weights)
        squares = self._component_sums(torch.exp(2.0 * within))
        return torch.nan_to_num(1.0 / (squares * self._counts), nan=0.0), log_mass

    def _depleted(self, log_weights: torch.Tensor) -> torch.Tensor:
        """Components (C,) bool whose effective size is below the threshold; components
        without any weight left are never resampled."""
        fraction, log_mass = self._component_ess(log_weights)
        return (fraction < self.ess_threshold) & torch.isfinite(log_mass)

    def _tempering_step(self, loglik: torch.Tensor, remaining: float) -> float:
        """Smallest ``β ≤ remaining`` (to 2⁻¹⁵ of ``remaining``, bisection) that takes the
        weight-averaged effective fraction ``Σ_c π_c ESS_c/N_c`` below the threshold, so
        that the stage ends with resampling the components below it; ``remaining`` when
        the average stays above. With one component this is the usual ESS rule. Averaging
        over the components by their weight keeps one tempering stage — one render of all
        particles — per degeneracy event of the mixture instead of one per component."""

        def enough(beta: float) -> bool:
            fraction, log_mass = self._component_ess(self.log_weights + beta * loglik)
            mass = torch.softmax(log_mass, dim=0)
            return float(torch.nansum(mass * fraction)) >= self.ess_threshold

        if enough(remaining):
            return remaining
        low, high = 0.0, remaining
        for _ in range(15):
            mid = 0.5 * (low + high)
            if enough(mid):
                low = mid
            else:
                high = mid
        return high

    # ------------------------------------------------------------------ resample-move
    def _resample_move(
        self, depleted: torch.Tensor, move_target: MoveTarget | None, moves: int
    ) -> list[float]:
        """Resample the ``depleted`` components (C,) bool within themselves, then roughen
        (or move) their particles."""
        within_weights, log_mass = self._within_weights()
        kernel = None
        if self.bandwidth > 0.0:
            labels, centers = self._kernel_clusters(within_weights)
            kernel = self._kernel_covariance(labels, centers, within_weights)
        index, selected = self._resample_within(within_weights, log_mass, depleted)
        if kernel is None:
            return []
        # Symmetric square roots: a cluster of identical particles has a singular kernel,
        # where a Cholesky factorisation can fail on rounding. Particles of components not
        # resampled keep their place (a zero jitter).
        jitter = covariance_root(kernel)[labels[index]] * selected[:, None, None]
        if move_target is None:
            self.q, self.omega, self.k = jittered(
                self.q, self.omega, self.k, jitter, self.generator
            )
            return []
        rates = []
        current = move_target(self.q, self.omega, self.k, self.shape)
        for _ in range(moves):
            q, omega, k = jittered(self.q, self.omega, self.k, jitter, self.generator)
            proposed = move_target(q, omega, k, self.shape)
            log_u = torch.log(torch.rand(len(self), generator=self.generator, dtype=self.dtype))
            accept = (log_u < proposed - current) & selected
            self.q = torch.where(accept[:, None], q, self.q)
            self.omega = torch.where(accept[:, None], omega, self.omega)
            if k is not None:
                self.k = torch.where(accept[:, None], k, self.k)
            current = torch.where(accept, proposed, current)
            rates.append(float(accept[selected].to(self.dtype).mean()))
        return rates

    def _within_weights(self) -> tuple[torch.Tensor, torch.Tensor]:
        """Weights normalised within each component (0 in a component without weight) and
        the log-mass of every component."""
        within, log_mass = self._within_log_weights(self.log_weights)
        return torch.nan_to_num(torch.exp(within), nan=0.0), log_mass

    def _resample_within(
        self, within_weights: torch.Tensor, log_mass: torch.Tensor, depleted: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Systematic resampling inside every depleted component (one offset each); the
        resampled particles share their component's mass equally.

        Returns
        -------
        index : (N,) long tensor
            Source particle of every slot (itself outside the depleted components).
        selected : (N,) bool tensor
            Slots that were resampled.
        """
        c = self.component
        drawn = systematic_resample(within_weights, self.generator, self._counts)
        selected = depleted[c]
        index = torch.where(selected, drawn, torch.arange(len(self)))
        self._take(index)
        equal = (log_mass - torch.log(self._counts))[c]
        self.log_weights = torch.where(selected, equal, self.log_weights)
        return index, selected

    def _kernel_clusters(self, within_weights: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Clusters of the roughening kernel and their centre attitudes: the mixture
        components, each centred on its heaviest particle; with a single component, the
        greedy clusters of :meth:`_cluster` (per shape)."""
        if self.n_components == 1:
            return self._cluster(self.q, self.omega, self.shape, within_weights)
        c = self.component
        heaviest = torch.full((self.n_components,), -1.0, dtype=within_weights.dtype)
        heaviest = heaviest.scatter_reduce(0, c, within_weights, reduce="amax")
        slot = torch.where(within_weights == heaviest[c], torch.arange(len(self)), len(self))
        first = torch.full((self.n_components,), len(self), dtype=torch.long)
        first = first.scatter_reduce(0, c, slot, reduce="amin")
        return c, self.q[first]

    def _kernel_covariance(
        self, labels: torch.Tensor, centers: torch.Tensor, weights: torch.Tensor
    ) -> torch.Tensor:
        """Kernel covariance ``h² C_c`` of every cluster from the weighted particles before
        resampling, shape (C, d, d) (:func:`filters.roughening.kernel_covariance`)."""
        state = local_state(self.q, self.omega, self.k, centers[labels])
        return kernel_covariance(state, labels, len(centers), weights, self.bandwidth)

    def resample(self) -> None:
        """Systematic resampling to equal weights within every component (no roughening)."""
        within_weights, log_mass = self._within_weights()
        self._resample_within(within_weights, log_mass, torch.isfinite(log_mass))

    def _folded(self, fold: Callable) -> tuple[torch.Tensor, torch.Tensor]:
        """Particles folded onto the symmetry-equivalent closest to the heaviest one."""
        best = int(torch.argmax(self.log_weights))
        q, omega = fold(
            self.q[best].numpy(), self.q.numpy(), self.omega.numpy(), self.shape.numpy()
        )
        return torch.as_tensor(q, dtype=self.dtype), torch.as_tensor(omega, dtype=self.dtype)

    def _cluster(
        self, q: torch.Tensor, omega: torch.Tensor, shape: torch.Tensor, weights: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """:func:`filters.particle_modes.greedy_clusters` with this filter's radii."""
        return greedy_clusters(
            q,
            omega,
            shape,
            weights,
            angle=self.mode_angle,
            rate=self.mode_rate,
            max_clusters=self.max_clusters,
        )

    def modes(
        self,
        min_weight: float = 0.01,
        fold: Callable[[np.ndarray, np.ndarray, np.ndarray], tuple] | None = None,
    ) -> list[Mode]:
        """Clusters of particles, heaviest first.

        Parameters
        ----------
        min_weight : float
            Clusters lighter than this are not reported.
        fold : callable, optional
            ``fold(q_reference (4,), q (M, 4), ω (M, 3), shape (M,)) → (q', ω')`` maps
            particles to their symmetry-equivalent nearest a reference (a shape's symmetry
            group), so that equivalent attitudes form one mode.

        Returns
        -------
        list of Mode
        """
        q, omega = self._folded(fold) if fold is not None else (self.q, self.omega)
        labels, _ = self._cluster(q, omega, self.shape, self.weights)
        return weighted_modes(
            q, omega, self.shape, self.log_weights, labels, k=self.k, min_weight=min_weight
        )

    def estimate(self, fold: Callable | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Mean state of the heaviest mode and its covariance
        (:func:`filters.particle_modes.heaviest_mode`; ``fold`` as in :meth:`modes`).

        Returns
        -------
        q : (4,) numpy.ndarray
        omega : (3,) numpy.ndarray
            Rates (rad/s).
        covariance : (6, 6) numpy.ndarray
            Of ``[δθ, ω]`` (rad², rad²/s²).
        """
        q, omega = self._folded(fold) if fold is not None else (self.q, self.omega)
        weights = self.weights
        labels, _ = self._cluster(q, omega, self.shape, weights)
        return heaviest_mode(q, omega, weights, labels)
