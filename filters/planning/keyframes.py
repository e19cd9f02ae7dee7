"""Keyframe selection for a recorded frame sequence (the monocular pipeline of Deng et al. 2024).

:func:`select_keyframes` chooses the frames that minimise the final covariance from per-frame
Fisher information and the filter's transition; :class:`MonocularKeyframeModel` and
:func:`monocular_keyframes` drive it from the monocular EKF of
:mod:`filters.navigation.monocular`. The sets are planned by
:func:`filters.planning.schedule.plan_final_covariance`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from filters.planning.information import Forecast, forecast
from filters.planning.schedule import greedy_schedule, plan_final_covariance

__all__ = [
    "MonocularKeyframeModel",
    "monocular_keyframes",
    "select_keyframes",
]


def select_keyframes(
    information: np.ndarray,
    transition: np.ndarray,
    process_noise: np.ndarray,
    covariance: np.ndarray,
    *,
    count: int,
    s_max: int | None = None,
    indices: Sequence[int] | None = None,
    measure: str = "trace",
    method: str = "greedy",
) -> np.ndarray:
    """Choose ``count`` keyframes of a recorded sequence that minimise the final covariance.

    For the monocular pipeline (or any filter over a frame sequence): ``information[j]`` is
    the Fisher information ``Hᵀ R⁻¹ H`` of frame ``j + 1`` (from its features' geometry and
    pixel noise), ``transition``/``process_noise`` the filter's ``Φ``/``Q`` between frames.
    :func:`plan_final_covariance` plans the set.

    Parameters
    ----------
    information, transition, process_noise : (T, n, n) arrays
        Frames ``1 … T`` after the current one (frame 0).
    covariance : (n, n) array
        Covariance at frame 0.
    count : int
        Number of keyframes to take among frames ``1 … T``.
    s_max : int, optional
        Largest gap between keyframes (default: unlimited).
    indices : sequence of int, optional
        States whose final covariance is minimised (default: all).
    measure : {"trace", "logdet"}
    method : {"greedy", "rollout"}
        See :func:`plan_final_covariance`.

    Returns
    -------
    (count,) int numpy.ndarray
        Selected frame numbers in ``1 … T``.
    """
    full = Forecast(
        0,
        np.asarray(covariance, dtype=float)[None],
        np.asarray(transition, dtype=float)[:, None],
        np.asarray(process_noise, dtype=float)[:, None],
        np.asarray(information, dtype=float)[:, None],
    )
    schedule = plan_final_covariance(full, count, s_max, indices, measure, method)
    return np.flatnonzero(schedule.taken[0]) + 1


@dataclass(frozen=True)
class MonocularKeyframeModel:
    """The monocular EKF of Deng et al. 2024 as a planning model over a sequence of frames.

    :class:`filters.navigation.monocular.MonocularEKF` as a
    :class:`~filters.planning.information.PlanningModel`.

    Means are the EKF's nominal states ``[q, ω, p]``; step ``k`` is frame ``times[k]``. The
    prediction is the EKF's (RK4 with the inertia fixed over the step, ``Φ = exp(C ΔT)``,
    ``Q ΔT``); an attitude measurement at frame ``k`` (``H = [I₃ 0]``, eq. 35) carries
    ``F_k = Hᵀ R_k⁻¹ H``.

    Parameters
    ----------
    times : (K,) array
        Frame times (s).
    process_noise : (n, n) array
        The EKF's process-noise spectral density ``Q`` (per second).
    measurement_noise : (K, 3, 3) array
        Covariance of each frame's ``δq_v`` measurement (half-angle units, rad²/4).
    form : {"L", "k"}
        Inertia parameterisation.
    """

    times: np.ndarray
    process_noise: np.ndarray
    measurement_noise: np.ndarray
    form: str = "L"

    @classmethod
    def from_filter(cls, ekf: Any, times: Any, sigma: Any = None) -> MonocularKeyframeModel:
        """Model of a :class:`~filters.navigation.monocular.MonocularEKF` over frames at ``times``.

        Parameters
        ----------
        ekf : MonocularEKF
        times : (K,) array
            Frame times (s), the first being the EKF's current time.
        sigma : (K,) array, optional
            One-sigma rotation error per axis of each frame's attitude (rad), e.g.
            :attr:`filters.navigation.epipolar.AttitudeSequence.sigma`;
            ``R_k = (σ_k/2)² I₃``. Default: the EKF's ``R`` for every frame.
        """
        times = np.asarray(times, dtype=float)
        if sigma is None:
            r = np.broadcast_to(ekf.R, (times.size, 3, 3))
        else:
            r = (np.asarray(sigma, dtype=float) / 2)[:, None, None] ** 2 * np.eye(3)
        return cls(times, np.asarray(ekf.Q, dtype=float), r, ekf.form.name)

    def predict(self, x: Any, step: int) -> np.ndarray:
        """Nominal state at the next frame (the EKF's RK4 step)."""
        from filters.attitude import rk4_step, torque_free_derivative
        from filters.navigation.monocular import inertia_form

        x = np.asarray(x, dtype=float)
        f = torque_free_derivative(inertia_form(self.form).tensor(x[..., 7:]))
        qw = rk4_step(f, x[..., :7], self.times[step + 1] - self.times[step])
        return np.concatenate([qw, x[..., 7:]], axis=-1)

    def linearize(self, x: Any, step: Any) -> tuple[np.ndarray, np.ndarray]:
        """The EKF's ``Φ`` and ``Q ΔT`` to the next frame."""
        from filters.attitude import error_state_matrix, transition_matrix
        from filters.navigation.monocular import inertia_form

        x = np.asarray(x, dtype=float)
        dt = np.broadcast_to(self.times[np.asarray(step) + 1] - self.times[step], x.shape[:1])
        c = error_state_matrix(x[..., 4:7], x[..., 7:], inertia_form(self.form).name)
        phi = transition_matrix(c * dt[:, None, None], 1.0)
        return phi, self.process_noise * dt[:, None, None]

    def information(self, x: Any, step: Any) -> np.ndarray:
        """``Hᵀ R_k⁻¹ H`` of the frame's attitude measurement."""
        n = np.asarray(x).shape[-1] - 1
        step = np.broadcast_to(np.asarray(step), np.asarray(x).shape[:1])
        f = np.zeros((step.size, n, n))
        f[:, :3, :3] = np.linalg.inv(self.measurement_noise[step])
        return f


def monocular_keyframes(
    ekf: Any,
    times: Any,
    count: int,
    sigma: Any = None,
    s_max: int | None = None,
    indices: Sequence[int] | None = (0, 1, 2),
) -> np.ndarray:
    """Keyframes for the monocular EKF: ``count`` of the frames ``1 … K − 1`` that minimise
    its predicted final covariance (attitude by default), from its current state.

    Parameters
    ----------
    ekf : MonocularEKF
        At the time of frame 0 (state ``x``, covariance ``P``; batch dimensions allowed).
    times : (K,) array
        Frame times (s).
    count : int
        Keyframes to process.
    sigma : (K,) array, optional
        Per-frame attitude noise (rad, see :meth:`MonocularKeyframeModel.from_filter`).
    s_max : int, optional
        Largest gap between keyframes (frames), e.g. to keep features matched.
    indices : sequence of int, optional
        Error states whose final covariance is minimised.

    Returns
    -------
    (B, count) int numpy.ndarray
        Selected frame numbers per filter (sorted), ``B = 1`` for an unbatched EKF.
    """
    model = MonocularKeyframeModel.from_filter(ekf, times, sigma)
    x = np.asarray(ekf.x, dtype=float).reshape(-1, ekf.x.shape[-1])
    p = np.asarray(ekf.P, dtype=float).reshape(-1, ekf.dim, ekf.dim)
    full = forecast(model, x, p, 0, len(model.times) - 1)
    taken = greedy_schedule(full, count, s_max, indices).taken
    return np.stack([np.flatnonzero(row) + 1 for row in taken])
