"""Fisher information and covariance forecasts for observation planning (Li et al. 2024, sec. 2).

The estimator enters through a small protocol (:class:`PlanningModel`): one-step transition of
the mean with its linearisation ``(Φ, Q)`` and the Fisher information ``F = Hᵀ R⁻¹ H``
(eq. 20) of an observation taken at a predicted state. :func:`forecast` evaluates a whole
look-ahead window in one call; the planners of :mod:`filters.planning.sequential` and
:mod:`filters.planning.schedule` work on the :class:`Forecast` only, so they schedule landmark
images of a lander, keyframes of a monocular pipeline and epochs of a light curve alike.

Arrays carry leading batch axes (independent Monte Carlo runs): means ``(B, …)`` are opaque
to the planner (only handed back to the model), covariances are ``(B, n, n)``.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

__all__ = [
    "Forecast",
    "FunctionModel",
    "PlanningModel",
    "covariance_measure",
    "fisher_information",
    "forecast",
    "posterior_covariance",
    "predict_covariance",
]


class PlanningModel(Protocol):
    """What the planner needs from an estimator (all batched over runs ``B``).

    ``predict(x, step)``
        Predicted mean at ``step + 1`` from the mean ``x`` at ``step`` (same layout).
    ``linearize(x, step)``
        Transition matrix ``Φ`` and discrete process noise ``Q`` of the error state from
        ``step`` to ``step + 1`` at the mean ``x``, each ``(B, n, n)``.
    ``information(x, step)``
        Fisher information ``F = Hᵀ R⁻¹ H`` ``(B, n, n)`` (Li et al. 2024, eq. 20) of an
        observation taken at ``step`` with the mean ``x``.

    ``linearize`` and ``information`` also receive ``step`` as an int array ``(B,)`` (one step
    per batch element), so the planner evaluates a whole forecast in one call.
    """

    def predict(self, x: Any, step: int) -> Any: ...

    def linearize(self, x: Any, step: Any) -> tuple[np.ndarray, np.ndarray]: ...

    def information(self, x: Any, step: Any) -> np.ndarray: ...


@dataclass(frozen=True)
class FunctionModel:
    """A :class:`PlanningModel` made of plain callables (to drive any estimator).

    Parameters
    ----------
    predict_fn : callable ``(x, step) -> x_next``
    linearize_fn : callable ``(x, step) -> (Φ, Q)``
    information_fn : callable ``(x, step) -> F``
    """

    predict_fn: Callable[[Any, int], Any]
    linearize_fn: Callable[[Any, Any], tuple[np.ndarray, np.ndarray]]
    information_fn: Callable[[Any, Any], np.ndarray]

    def predict(self, x: Any, step: int) -> Any:
        """Predicted mean (see :class:`PlanningModel`)."""
        return self.predict_fn(x, step)

    def linearize(self, x: Any, step: Any) -> tuple[np.ndarray, np.ndarray]:
        """``Φ`` and ``Q`` (see :class:`PlanningModel`)."""
        return self.linearize_fn(x, step)

    def information(self, x: Any, step: Any) -> np.ndarray:
        """Fisher information of an observation (see :class:`PlanningModel`)."""
        return self.information_fn(x, step)


def fisher_information(h: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Fisher information ``F = Hᵀ R⁻¹ H`` of a linearised Gaussian measurement.

    Li et al. 2024, eq. 20.

    Parameters
    ----------
    h : (..., m, n) array
        Measurement Jacobian.
    r : (..., m, m) array
        Measurement noise covariance.

    Returns
    -------
    (..., n, n) numpy.ndarray
    """
    h = np.asarray(h, dtype=float)
    r_inv_h = np.linalg.solve(np.asarray(r, dtype=float), h)
    f = np.swapaxes(h, -1, -2) @ r_inv_h
    return 0.5 * (f + np.swapaxes(f, -1, -2))


def posterior_covariance(prior: np.ndarray, information: np.ndarray) -> np.ndarray:
    """Covariance after an observation, ``(P⁻¹ + F)⁻¹ = (I + P F)⁻¹ P``.

    The second form needs no inverse of ``P`` (valid for singular priors) and equals the
    Kalman update ``P − P Hᵀ (H P Hᵀ + R)⁻¹ H P`` for ``F = Hᵀ R⁻¹ H``.

    Parameters
    ----------
    prior : (..., n, n) array
    information : (..., n, n) array

    Returns
    -------
    (..., n, n) numpy.ndarray
    """
    prior = np.asarray(prior, dtype=float)
    n = prior.shape[-1]
    post = np.linalg.solve(np.eye(n) + prior @ information, prior)
    return 0.5 * (post + np.swapaxes(post, -1, -2))


def covariance_measure(
    p: np.ndarray, indices: Sequence[int] | None = None, measure: str = "trace"
) -> np.ndarray:
    """Scalar size of covariance blocks: ``tr P[idx, idx]`` or ``log det P[idx, idx]``.

    Parameters
    ----------
    p : (..., n, n) array
    indices : sequence of int, optional
        States of the block (default: all).
    measure : {"trace", "logdet"}

    Returns
    -------
    (...) numpy.ndarray
    """
    if indices is not None:
        idx = np.asarray(indices)
        p = p[..., idx[:, None], idx[None, :]]
    if measure == "trace":
        return np.trace(p, axis1=-2, axis2=-1)
    if measure == "logdet":
        return np.linalg.slogdet(p)[1]
    raise ValueError(f"measure must be 'trace' or 'logdet', got {measure!r}")


@dataclass(frozen=True)
class Forecast:
    """Prediction of the model ahead of step ``step`` without observations.

    Attributes
    ----------
    step : int
        Current step ``k`` (the covariance is the posterior there).
    covariance : (B, n, n) array
        ``P_k``.
    transition, process_noise : (L, B, n, n) arrays
        ``Φ`` and ``Q`` from ``k + j − 1`` to ``k + j``, ``j = 1 … L``.
    information : (L, B, n, n) array
        ``F_{k+j}`` at the predicted states.
    """

    step: int
    covariance: np.ndarray
    transition: np.ndarray
    process_noise: np.ndarray
    information: np.ndarray

    @property
    def length(self) -> int:
        """Number of predicted steps ``L``."""
        return self.transition.shape[0]

    def head(self, length: int) -> Forecast:
        """The first ``length`` predicted steps."""
        return Forecast(
            self.step,
            self.covariance,
            self.transition[:length],
            self.process_noise[:length],
            self.information[:length],
        )

    def tail(self, offset: int, covariance: np.ndarray) -> Forecast:
        """The forecast seen from ``step + offset`` where the covariance is ``covariance``."""
        return Forecast(
            self.step + offset,
            covariance,
            self.transition[offset:],
            self.process_noise[offset:],
            self.information[offset:],
        )

    def covariances(self, taken: np.ndarray) -> Iterator[tuple[np.ndarray, np.ndarray]]:
        """Predicted and filtered covariances ``P_{k+j|k+j−1}``, ``P_{k+j|k+j}``, ``j = 1 … L``,
        given the observations ``taken`` (each applies ``P⁺ = (P⁻⁻¹ + F)⁻¹``).

        Parameters
        ----------
        taken : (..., B, L) bool array
            ``taken[..., b, j − 1]``: run ``b`` observes at step ``k + j``; leading axes (e.g.
            candidate schedules) broadcast against the runs.

        Yields
        ------
        prior, posterior : (..., B, n, n) numpy.ndarray
            Step by step, the covariance before and after the step's observation.
        """
        runs = np.broadcast_shapes(taken.shape[:-1], self.covariance.shape[:-2])
        p = np.broadcast_to(self.covariance, (*runs, *self.covariance.shape[-2:]))
        for j in range(self.length):
            p = predict_covariance(p, self.transition[j], self.process_noise[j])
            prior = p
            observed = taken[..., j]
            if observed.any():
                updated = posterior_covariance(p, self.information[j])
                p = np.where(observed[..., None, None], updated, p)
            yield prior, p

    def select(self, runs: np.ndarray) -> Forecast:
        """The forecast of a subset of runs (index array over ``B``)."""
        return Forecast(
            self.step,
            self.covariance[runs],
            self.transition[:, runs],
            self.process_noise[:, runs],
            self.information[:, runs],
        )


def predict_covariance(p: np.ndarray, phi: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Predicted covariance ``Φ P Φᵀ + Q``, broadcast over leading axes."""
    p = phi @ p @ np.swapaxes(phi, -1, -2) + q
    return 0.5 * (p + np.swapaxes(p, -1, -2))


def forecast(model: PlanningModel, x: Any, p: np.ndarray, step: int, length: int) -> Forecast:
    """Predict ``length`` steps ahead of ``step`` (Li et al. 2024, eqs. 9 and 13, no updates).

    The means are propagated one step at a time; ``Φ``, ``Q`` and ``F`` of all predicted
    steps are then evaluated in one batched call each.

    Parameters
    ----------
    model : PlanningModel
    x : (B, …) array
        Current mean (model layout).
    p : (B, n, n) array
        Current covariance.
    step : int
        Current step ``k``.
    length : int
        Steps to predict (``≥ 1``).

    Returns
    -------
    Forecast
    """
    if length < 1:
        raise ValueError(f"forecast length must be >= 1, got {length}")
    p = np.asarray(p, dtype=float)
    batch = p.shape[0]
    means = [x]
    for j in range(length):
        means.append(model.predict(means[-1], step + j))
    stacked = np.stack(means)  # (L + 1, B, …)
    steps = np.repeat(step + np.arange(length + 1), batch)
    flat = stacked.reshape(((length + 1) * batch, *stacked.shape[2:]))
    phi, q = model.linearize(flat[:-batch], steps[:-batch])
    info = model.information(flat[batch:], steps[batch:])
    shape = (length, batch, p.shape[-1], p.shape[-1])
    return Forecast(step, p, phi.reshape(shape), q.reshape(shape), info.reshape(shape))
