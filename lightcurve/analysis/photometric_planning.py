"""Photometric observation scheduling: which epochs of a light curve carry attitude information.

The observation planner of :mod:`filters.planning` (Li et al. 2024) applied to the light curve
of a tumbling object: :class:`PhotometricPlanningModel` is a
:class:`~filters.planning.information.PlanningModel`
whose observation is one magnitude at a candidate epoch of a geometry table and whose error
state is the attitude-error + rate state of the attitude core's EKFs,

``δx = [δq_v, δω]`` (6 states), or ``[δq_v, δω, δl]`` (11 states, inertia ``L = J/Jzz``
estimated too),

with the multiplicative error ``q = δq ⊗ q̂``, ``δq ≈ [δq_v, 1]`` (half the small body-frame
rotation, :mod:`filters.attitude.jacobians`).

Measurement (Gou et al. 2016, sec. 2.3; ``docs/rendering.md``):
``m_k = −26.74 − 2.5 log10 I(A(q_k) ŝ_k, A(q_k) ô_k)`` rendered by
:class:`~lightcurve.photometry.render.Renderer`. Its row Jacobian ``h_k = ∂m_k/∂δx = [∂m_k/∂δq_v, 0,
0]`` is taken by torch autograd through the renderer (a magnitude depends on the attitude at its
epoch only; the rates enter through the dynamics). The Fisher information of the epoch is
``F_k = h_kᵀ h_k / σ_k²`` (Li et al. 2024, eq. 20), a rank-one matrix: one magnitude never
bounds the attitude alone, so Li et al.'s ``min tr F⁻¹`` does not apply and a budget of
epochs is chosen for the smallest final attitude covariance
(:func:`~filters.planning.schedule.greedy_schedule` with an exchange pass, via
:func:`~filters.planning.schedule.plan_final_covariance`; the sequential
:class:`~filters.planning.sequential.PosteriorRollout` on request).
Dark epochs (no lit facet visible, infinite magnitude) carry no information.

Dynamics: torque-free motion propagated with the attitude core's RK4
(:func:`~filters.attitude.rk4_step`) in substeps of at most ``max_substep``; the error-state
transition and process noise over a substep of length ``h`` come from the Van Loan matrix
(Van Loan 1978)

``exp([[−C, Q_c], [0, Cᵀ]] h) = [[·, Φ⁻¹ Q_d], [0, Φᵀ]]``,

with ``C`` the attitude core's :func:`~filters.attitude.error_state_matrix` averaged over the
substep's end points (second-order Magnus) and exponentiated by
:func:`~filters.attitude.transition_matrix`. ``Q_c = diag(0, q_ω I₃, 0)``: white angular
acceleration noise of spectral density ``q_ω = rate_noise²`` (rad²/s³, unmodelled torques).
The product over substeps is checked against the autograd Jacobian of the RK4 map in
``tests/lightcurve/analysis/test_photometric_planning.py``.

Example
-------
>>> model = PhotometricPlanningModel.from_observations(geometry, shape, 0.03)  # doctest: +SKIP
>>> x0 = model.state(q0, omega0, shape.inertia)  # (B, 12)  # doctest: +SKIP
>>> compare_schedules(model, x0, p0, budget=24).ratio()  # planned / uniform  # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from filters.attitude import (
    error_state_matrix,
    inertia_from_normalized,
    normalized_from_inertia,
    quaternion_multiply,
    quaternion_normalize,
    rk4_step,
    torque_free_derivative,
    transition_matrix,
)
from filters.planning.information import Forecast, covariance_measure, forecast
from filters.planning.schedule import plan_final_covariance, propagate_schedule, uniform_steps
from lightcurve.io.observations import Observations
from lightcurve.photometry.render import Renderer
from shapes import FacetModel

__all__ = [
    "ATTITUDE",
    "PhotometricPlanningModel",
    "ScheduleComparison",
    "compare_schedules",
    "largest_information_steps",
]

#: Indices of the attitude error ``δq_v`` in the error state.
ATTITUDE = (0, 1, 2)


@dataclass(frozen=True)
class PhotometricPlanningModel:
    """The planner's model of a tumbling object observed in magnitudes at candidate epochs.

    Means are ``x = [q (4), ω (3, rad/s), l (5)]`` with ``l`` the free entries of
    ``L = J/Jzz`` (:func:`filters.attitude.normalized_from_inertia`), batched ``(B, 12)``;
    step ``k`` is epoch ``times[k]``.

    Parameters
    ----------
    renderer : Renderer
        Forward model of the shape (torch autograd flows through it).
    times : (K,) array
        Candidate epochs (s), strictly increasing.
    sun, observer : (K, 3) arrays
        Object → Sun and object → observer vectors, inertial frame (m).
    sigma_mag : (K,) array
        One-sigma magnitude noise of an observation at each epoch (mag).
    rate_noise : float
        Square root of the angular-acceleration noise spectral density (rad s⁻³ᐟ²).
    estimate_inertia : bool
        Error state with the five inertia parameters (11 states) or without (6).
    max_substep : float
        Longest RK4 substep (and transition-matrix factor) within a candidate interval (s).
        ``Φ`` converges as its square: relative error 2.3e-3 at 13° of rotation per
        substep, 5.8e-4 at 6.5°.
    """

    renderer: Renderer
    times: np.ndarray
    sun: np.ndarray
    observer: np.ndarray
    sigma_mag: np.ndarray
    rate_noise: float = 0.0
    estimate_inertia: bool = False
    max_substep: float = 2.5

    def __post_init__(self) -> None:
        k = len(self.times)
        if k < 2 or np.any(np.diff(self.times) <= 0):
            raise ValueError("candidate epochs must be at least two, strictly increasing")
        if self.sun.shape != (k, 3) or self.observer.shape != (k, 3):
            raise ValueError(f"sun and observer vectors must have shape ({k}, 3)")
        if self.sigma_mag.shape != (k,) or not np.all(self.sigma_mag > 0):
            raise ValueError(f"sigma_mag must be {k} positive magnitudes")
        if not self.max_substep > 0:
            raise ValueError(f"max_substep must be positive, got {self.max_substep}")

    @classmethod
    def from_observations(
        cls,
        observations: Observations,
        shape: FacetModel,
        sigma_mag: float | None = None,
        *,
        shadows: str = "auto",
        **options: Any,
    ) -> PhotometricPlanningModel:
        """Model over the epochs of an observation or geometry table.

        Parameters
        ----------
        observations : Observations
            Epochs and geometry; its ``mag_err`` is the noise unless ``sigma_mag`` is given.
        shape : FacetModel
        sigma_mag : float, optional
            Magnitude noise (mag), required for geometry-only tables.
        shadows : str
            Renderer shadow mode.
        **options
            ``rate_noise``, ``estimate_inertia``, ``max_substep``.
        """
        if sigma_mag is None:
            if not observations.has_magnitudes:
                raise ValueError(
                    f"{observations.source or observations.name}: a geometry-only table "
                    "needs sigma_mag (no mag_err column)"
                )
            sigma = observations.magnitude_errors
        else:
            sigma = np.full(len(observations), float(sigma_mag))
        return cls(
            Renderer(shape, shadows=shadows),
            observations.times,
            observations.sun_vectors,
            observations.observer_vectors,
            sigma,
            **options,
        )

    @property
    def n_states(self) -> int:
        """Error-state dimension (6 or 11)."""
        return 11 if self.estimate_inertia else 6

    @property
    def n_epochs(self) -> int:
        """Number of candidate epochs ``K`` (steps ``0 … K − 1``)."""
        return len(self.times)

    @staticmethod
    def state(q: Any, omega: Any, inertia: Any) -> np.ndarray:
        """Mean layout ``[q, ω, l]`` from attitudes ``(B, 4)``, rates ``(B, 3)`` and ``J``."""
        q = quaternion_normalize(np.atleast_2d(np.asarray(q, dtype=float)))
        omega = np.broadcast_to(np.asarray(omega, dtype=float), (len(q), 3))
        l = np.broadcast_to(normalized_from_inertia(np.asarray(inertia, dtype=float)), (len(q), 5))
        return np.concatenate([q, omega, l], axis=-1)

    # ------------------------------------------------------------------ PlanningModel
    def predict(self, x: np.ndarray, step: int) -> np.ndarray:
        """Mean at ``step + 1`` (RK4 substeps of at most ``max_substep``)."""
        x = np.asarray(x, dtype=float)
        count = int(self._substeps(np.array([step]))[0])
        h = (self.times[step + 1] - self.times[step]) / count
        derivative = torque_free_derivative(inertia_from_normalized(x[..., 7:]))
        qw = x[..., :7]
        for _ in range(count):
            qw = rk4_step(derivative, qw, h)
        return np.concatenate([qw, x[..., 7:]], axis=-1)

    def linearize(self, x: np.ndarray, step: Any) -> tuple[np.ndarray, np.ndarray]:
        """Transition ``Φ`` and process noise ``Q`` from ``step`` to ``step + 1``, ``(N, n, n)``."""
        x = np.asarray(x, dtype=float)
        step = np.broadcast_to(np.asarray(step), x.shape[:1])
        counts = self._substeps(step)
        phi = np.empty((len(x), self.n_states, self.n_states))
        q = np.empty_like(phi)
        for count in np.unique(counts):
            rows = counts == count
            h = (self.times[step[rows] + 1] - self.times[step[rows]]) / count
            phi[rows], q[rows] = self._transition(x[rows], h, int(count))
        return phi, q

    def _substeps(self, step: np.ndarray) -> np.ndarray:
        """Number of substeps of each candidate interval."""
        dt = self.times[step + 1] - self.times[step]
        return np.maximum(np.ceil(dt / self.max_substep - 1e-9), 1).astype(int)

    def _transition(self, x: np.ndarray, h: np.ndarray, count: int) -> tuple[np.ndarray, ...]:
        """Product of ``count`` Van Loan substeps of lengths ``h`` ``(N,)`` along the mean."""
        n = self.n_states
        h_b = h[:, None, None]
        derivative = torque_free_derivative(inertia_from_normalized(x[..., 7:]))
        noise = np.zeros((len(x), n, n))
        noise[:, 3:6, 3:6] = self.rate_noise**2 * np.eye(3)
        van_loan = np.zeros((len(x), 2 * n, 2 * n))
        van_loan[:, :n, n:] = noise * h_b
        phi = np.broadcast_to(np.eye(n), (len(x), n, n))
        q = np.zeros((len(x), n, n))
        qw = x[..., :7]
        c_start = self._system_matrix(qw[..., 4:], x[..., 7:])
        for _ in range(count):
            qw = rk4_step(derivative, qw, h[:, None])
            c_end = self._system_matrix(qw[..., 4:], x[..., 7:])
            c = 0.5 * (c_start + c_end) * h_b
            van_loan[:, :n, :n] = -c
            van_loan[:, n:, n:] = np.swapaxes(c, -1, -2)
            e = transition_matrix(van_loan, 1.0)
            phi_sub = np.swapaxes(e[:, n:, n:], -1, -2)
            phi = phi_sub @ phi
            q = phi_sub @ q @ np.swapaxes(phi_sub, -1, -2) + phi_sub @ e[:, :n, n:]
            c_start = c_end
        return phi, 0.5 * (q + np.swapaxes(q, -1, -2))

    def information(self, x: np.ndarray, step: Any) -> np.ndarray:
        """Fisher information ``F = hᵀ h / σ²`` ``(N, n, n)`` of a magnitude at ``step``."""
        _, jac = self.magnitude_jacobian(x, step)
        sigma = self.sigma_mag[np.broadcast_to(np.asarray(step), jac.shape[:1])]
        h = jac / sigma[:, None]
        return h[:, :, None] * h[:, None, :]

    # ------------------------------------------------------------------ forward model
    def magnitude_jacobian(self, x: np.ndarray, step: Any) -> tuple[np.ndarray, np.ndarray]:
        """Magnitude and its error-state Jacobian (torch autograd through the renderer).

        Parameters
        ----------
        x : (N, 12) array
            Means.
        step : int or (N,) int array
            Epoch index of each mean.

        Returns
        -------
        magnitude : (N,) numpy.ndarray
            ``inf`` at dark epochs.
        jacobian : (N, n) numpy.ndarray
            ``∂m/∂δx``; zero rows at dark epochs.
        """
        x = np.asarray(x, dtype=float)
        step = np.broadcast_to(np.asarray(step), x.shape[:1])
        delta = torch.zeros(len(x), 3, dtype=torch.float64, requires_grad=True)
        magnitude = self._render(delta, x, step)
        (grad,) = torch.autograd.grad(magnitude.sum(), delta)
        jac = np.zeros((len(x), self.n_states))
        jac[:, :3] = grad.numpy()
        m = magnitude.detach().numpy()
        jac[~np.isfinite(m) | ~np.all(np.isfinite(jac), axis=-1)] = 0.0
        return m, jac

    def magnitude_at(self, x: np.ndarray, step: Any, delta: Any = None) -> np.ndarray:
        """Magnitudes at ``[δq_v, √(1 − |δq_v|²)] ⊗ q`` (numpy; for finite differences)."""
        x = np.asarray(x, dtype=float)
        step = np.broadcast_to(np.asarray(step), x.shape[:1])
        d = torch.zeros(len(x), 3, dtype=torch.float64)
        if delta is not None:
            d = d + torch.as_tensor(np.asarray(delta, dtype=float))
        return self._render(d, x, step).numpy()

    def _render(self, delta: torch.Tensor, x: np.ndarray, step: np.ndarray) -> torch.Tensor:
        scalar = torch.sqrt(1.0 - (delta * delta).sum(-1, keepdim=True))
        q = quaternion_multiply(torch.cat([delta, scalar], -1), torch.as_tensor(x[:, :4]))
        return self.renderer.magnitude(
            q, torch.as_tensor(self.sun[step]), torch.as_tensor(self.observer[step])
        )

    def _system_matrix(self, omega: np.ndarray, l: np.ndarray) -> np.ndarray:
        """``C`` of the error dynamics, cut to the model's states."""
        n = self.n_states
        return error_state_matrix(omega, l)[..., :n, :n]


def largest_information_steps(ahead: Forecast, count: int) -> np.ndarray:
    """The ``count`` steps with the largest ``tr F`` (a baseline that ignores the dynamics).

    Returns
    -------
    (B, L) bool numpy.ndarray
    """
    score = np.trace(ahead.information, axis1=-2, axis2=-1).T  # (B, L)
    top = np.argsort(-score, axis=-1, kind="stable")[:, :count]
    taken = np.zeros(score.shape, dtype=bool)
    np.put_along_axis(taken, top, True, axis=-1)
    return taken


@dataclass(frozen=True)
class ScheduleComparison:
    """Planned vs uniform (and two other) epoch sets at one budget, per run ``B``.

    Attributes
    ----------
    budget : int
        Epochs observed among the candidate steps ``1 … L``.
    taken : dict of str to (B, L) bool arrays
        ``"planned"`` (:func:`~filters.planning.schedule.greedy_schedule`), ``"uniform"``,
        ``"largest_information"`` (:func:`largest_information_steps`) and, if asked,
        ``"rollout"`` (the sequential
        :class:`~filters.planning.sequential.PosteriorRollout` planner).
    covariances : dict of str to (L, B, n, n) arrays
        Covariance after each step under each schedule (the same recursion for all).
    forecast : Forecast
        Transition, process noise and information along the predicted mean.
    """

    budget: int
    taken: dict[str, np.ndarray]
    covariances: dict[str, np.ndarray]
    forecast: Forecast

    def final_trace(self, indices: Sequence[int] | None = ATTITUDE) -> dict[str, np.ndarray]:
        """Trace of the final covariance block (default: attitude ``δq_v``, rad²/4), ``(B,)``."""
        return {name: covariance_measure(p[-1], indices) for name, p in self.covariances.items()}

    def ratio(self, name: str = "planned", indices: Sequence[int] | None = ATTITUDE) -> np.ndarray:
        """Final trace of schedule ``name`` over that of uniform spacing, ``(B,)``."""
        traces = self.final_trace(indices)
        return traces[name] / traces["uniform"]


def compare_schedules(
    model: Any,
    x0: np.ndarray,
    p0: np.ndarray,
    *,
    budget: int,
    s_max: int | None = None,
    indices: Sequence[int] = ATTITUDE,
    measure: str = "trace",
    ahead: Forecast | None = None,
    rollout: bool = False,
) -> ScheduleComparison:
    """Plan ``budget`` epochs for the smallest final attitude covariance; compare to uniform.

    Every schedule goes through the same covariance recursion (predict with ``Φ``, ``Q``;
    update with ``F`` at the chosen epochs) along one forecast of the mean from step 0.

    Parameters
    ----------
    model : PlanningModel
        E.g. :class:`PhotometricPlanningModel`.
    x0 : (B, …) array
        Means at step 0 (one per run).
    p0 : (n, n) or (B, n, n) array
        Covariance at step 0.
    budget : int
        Epochs to observe among steps ``1 … K − 1``.
    s_max : int, optional
        Largest gap between planned epochs (steps); default unlimited.
    indices : sequence of int
        States whose final covariance is minimised (default: the attitude).
    measure : {"trace", "logdet"}
    ahead : Forecast, optional
        A forecast already made from ``x0``, ``p0`` (reused across budgets).
    rollout : bool
        Also plan with the sequential rollout (``O(budget L²)``: slow for long nights).

    Returns
    -------
    ScheduleComparison
    """
    x0 = np.asarray(x0, dtype=float)
    if ahead is None:
        p0 = np.broadcast_to(np.asarray(p0, dtype=float), (len(x0), model.n_states, model.n_states))
        ahead = forecast(model, x0, p0, 0, model.n_epochs - 1)
    batch, length = ahead.covariance.shape[0], ahead.length
    taken = {
        "planned": plan_final_covariance(ahead, budget, s_max, indices, measure).taken,
        "uniform": np.broadcast_to(uniform_steps(length, budget), (batch, length)),
        "largest_information": largest_information_steps(ahead, budget),
    }
    if rollout:
        taken["rollout"] = plan_final_covariance(
            ahead, budget, s_max, indices, measure, "rollout"
        ).taken
    covariances = {name: propagate_schedule(ahead, pattern) for name, pattern in taken.items()}
    return ScheduleComparison(budget, taken, covariances, ahead)
