"""Offline observation schedules over a forecast window (Li et al. 2024; this project).

Sets of observations chosen ahead of time for the covariance at the last step (keyframes of a
recorded sequence, epochs of a light curve): :func:`greedy_schedule` takes exact covariance
reductions of every candidate from one filter and one RTS smoother pass
(:func:`final_covariance_reduction`), greedy additions and exchange passes;
:func:`plan_forecast` and :func:`plan_schedule` run a sequential planner of
:mod:`filters.planning.sequential` over a forecast; :func:`plan_final_covariance` picks
between them.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from filters.planning.information import (
    Forecast,
    PlanningModel,
    covariance_measure,
    forecast,
    posterior_covariance,
    predict_covariance,
)
from filters.planning.sequential import ObservationPlanner, PosteriorRollout

__all__ = [
    "Schedule",
    "final_covariance_reduction",
    "greedy_schedule",
    "plan_final_covariance",
    "plan_forecast",
    "plan_schedule",
    "propagate_schedule",
    "uniform_steps",
]


@dataclass(frozen=True)
class Schedule:
    """Observations planned offline and the covariance they lead to.

    Attributes
    ----------
    taken : (B, L) bool array
        ``taken[b, j − 1]``: observation at step ``start + j``.
    covariances : (L, B, n, n) array
        Covariance after each step (posterior where observed).
    """

    taken: np.ndarray
    covariances: np.ndarray


def propagate_schedule(ahead: Forecast, taken: np.ndarray) -> np.ndarray:
    """Covariances along a forecast for a given observation pattern.

    Parameters
    ----------
    ahead : Forecast
    taken : (B, L) bool array
        ``taken[b, j − 1]``: observation at ``k + j``.

    Returns
    -------
    (L, B, n, n) numpy.ndarray
        Covariance after each step.
    """
    return _filter_covariances(ahead, taken)[1]


def _filter_covariances(ahead: Forecast, taken: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Predicted and filtered covariances ``P_{j|j−1}``, ``P_{j|j}`` along a forecast."""
    prior = np.empty_like(ahead.transition)
    post = np.empty_like(ahead.transition)
    for j, (predicted, filtered) in enumerate(ahead.covariances(taken)):
        prior[j], post[j] = predicted, filtered
    return prior, post


def _final_cross_covariances(
    ahead: Forecast, prior: np.ndarray, post: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``Cov(x_j, x_L)`` and smoothed ``P_{j|L}`` given the observations (RTS smoother).

    With the smoother gain ``G_j = P_{j|j} Φ_{j+1}ᵀ P_{j+1|j}⁻¹`` (Rauch, Tung & Striebel
    1965): ``P_{j|L} = P_{j|j} + G_j (P_{j+1|L} − P_{j+1|j}) G_jᵀ`` and the cross-covariance
    with the last state ``Cov(x_j, x_L) = G_j Cov(x_{j+1}, x_L)``, both ending at ``P_{L|L}``.
    """
    gain_t = np.linalg.solve(prior[1:], ahead.transition[1:] @ post[:-1])  # G_jᵀ
    gain = np.swapaxes(gain_t, -1, -2)
    cross = np.empty_like(post)
    smooth = np.empty_like(post)
    cross[-1] = smooth[-1] = post[-1]
    for j in range(ahead.length - 2, -1, -1):
        cross[j] = gain[j] @ cross[j + 1]
        smooth[j] = post[j] + gain[j] @ (smooth[j + 1] - prior[j + 1]) @ gain_t[j]
    return cross, smooth


def _gap_need(gap: np.ndarray, s_max: int) -> np.ndarray:
    """Observations needed inside a gap of ``gap`` steps so that no interval exceeds ``s_max``."""
    return np.maximum(-(-gap // s_max) - 1, 0)


def _feasible(taken: np.ndarray, left: int, s_max: int) -> np.ndarray:
    """Candidates ``(B, L)`` after which ``left − 1`` more observations can keep every gap
    (from the start and between observations) at most ``s_max``."""
    batch, length = taken.shape
    steps = np.arange(1, length + 1)
    ok = np.zeros_like(taken)
    for b in range(batch):
        points = np.r_[0, steps[taken[b]]]
        need = int(_gap_need(np.diff(points), s_max).sum())
        at = np.searchsorted(points, steps)  # the gap (points[at − 1], points[at]) or the tail
        before = points[at - 1]
        inner = at < points.size
        after = points[np.minimum(at, points.size - 1)]
        delta = _gap_need(steps - before, s_max) + np.where(
            inner,
            _gap_need(after - steps, s_max) - _gap_need(after - before, s_max),
            0,
        )
        ok[b] = need + delta <= left - 1
    return ok & ~taken


def _information_root(information: np.ndarray) -> np.ndarray:
    """Symmetric square root ``W`` of each Fisher information (``F = W W``)."""
    eig, vec = np.linalg.eigh(information)
    return (vec * np.sqrt(np.clip(eig, 0.0, None))[..., None, :]) @ np.swapaxes(vec, -1, -2)


def final_covariance_reduction(
    full: Forecast,
    taken: np.ndarray,
    indices: Sequence[int] | None = None,
    measure: str = "trace",
) -> np.ndarray:
    """How much one more observation at each step would shrink the covariance at the last step.

    Given the observations ``taken``, adding the information ``F_j = W_j W_j`` at step ``j``
    updates the last state like a measurement of ``x_j``: with ``C_j = Cov(x_j, x_L)`` and the
    smoothed ``P_{j|L}`` (one filter and one RTS smoother pass for all ``j`` at once),

    ``P_L ← P_L − C_jᵀ W_j (I + W_j P_{j|L} W_j)⁻¹ W_j C_j``.

    Parameters
    ----------
    full : Forecast
        Prediction over the steps ``1 … L``.
    taken : (B, L) bool array
        Observations already planned.
    indices : sequence of int, optional
        States of the scored block (default: all).
    measure : {"trace", "logdet"}
        Drop of ``tr`` or of ``log det`` of the block.

    Returns
    -------
    (B, L) numpy.ndarray
        The drop per candidate step (also for steps already taken: a repeated observation).
    """
    covariance_measure(full.covariance[:1], indices, measure)  # validates the measure name
    idx = np.arange(full.covariance.shape[-1]) if indices is None else np.asarray(indices)
    block = (..., idx[:, None], idx[None, :])
    root = _information_root(full.information)
    prior, post = _filter_covariances(full, taken)
    cross, smooth = _final_cross_covariances(full, prior, post)
    u = np.swapaxes(cross, -1, -2) @ root
    inner = np.eye(root.shape[-1]) + root @ smooth @ root
    drop = (u @ np.linalg.solve(inner, np.swapaxes(u, -1, -2)))[block]
    if measure == "trace":
        gain = np.trace(drop, axis1=-2, axis2=-1)
    else:
        final = post[-1][block]
        gain = np.linalg.slogdet(final)[1] - np.linalg.slogdet(final - drop)[1]
    return gain.T


def greedy_schedule(
    full: Forecast,
    count: int,
    s_max: int | None = None,
    indices: Sequence[int] | None = None,
    measure: str = "trace",
    exchanges: int = 1,
) -> Schedule:
    """Greedy choice of ``count`` observations for the smallest covariance at the last step.

    One observation at a time, the step that shrinks the final covariance most given those
    already chosen (before and after it) is added, scored exactly for every candidate at once
    by :func:`final_covariance_reduction` (greedy A- or D-optimal sensor scheduling, e.g.
    Shamaiah, Banerjee & Vikalo 2010). Exchange passes then take out each observation in
    turn and put back the best one (a 1-opt local search; the cost never increases). With
    ``s_max``, only candidates that leave enough observations to keep every interval (from
    the start and between observations) at most ``s_max`` qualify.

    Parameters
    ----------
    full : Forecast
        Prediction over the candidate steps ``full.step + 1 … full.step + L``.
    count : int
        Observations to take (``1 … L``).
    s_max : int, optional
        Largest interval (steps); default unlimited.
    indices : sequence of int, optional
        States whose final covariance is minimised (default: all).
    measure : {"trace", "logdet"}
    exchanges : int
        Most exchange passes (stops earlier when a pass changes nothing). On ten random
        4-of-12 problems greedy alone is 1.09× the exhaustive optimum on average (worst
        1.47×), with one pass 1.02× (worst 1.16×, optimal in 8)
        (``tests/filters/planning/test_planner.py``).

    Returns
    -------
    Schedule
    """
    length, batch = full.length, full.covariance.shape[0]
    if not 0 < count <= length:
        raise ValueError(f"observation count must be in [1, {length}], got {count}")
    runs = np.arange(batch)
    taken = np.zeros((batch, length), dtype=bool)
    for chosen in range(count):
        gain = final_covariance_reduction(full, taken, indices, measure)
        allowed = ~taken if s_max is None else _feasible(taken, count - chosen, s_max)
        taken[runs, np.argmax(np.where(allowed, gain, -np.inf), axis=-1)] = True
    for _ in range(exchanges):
        changed = False
        for rank in range(count):
            # Take out each run's rank-th observation and put back the best one.
            out = np.flatnonzero(taken.ravel())[rank::count] - runs * length
            taken[runs, out] = False
            gain = final_covariance_reduction(full, taken, indices, measure)
            allowed = ~taken if s_max is None else _feasible(taken, 1, s_max)
            back = np.argmax(np.where(allowed, gain, -np.inf), axis=-1)
            taken[runs, back] = True
            changed |= bool(np.any(back != out))
        if not changed:
            break
    return Schedule(taken, propagate_schedule(full, taken))


def uniform_steps(length: int, count: int) -> np.ndarray:
    """Evenly spaced observation pattern: ``count`` of ``length`` steps, the last included.

    Returns
    -------
    (length,) bool numpy.ndarray
    """
    if not 0 <= count <= length:
        raise ValueError(f"count must be in [0, {length}], got {count}")
    taken = np.zeros(length, dtype=bool)
    if count:
        taken[np.round(np.arange(1, count + 1) * length / count).astype(int) - 1] = True
    return taken


def plan_schedule(
    model: PlanningModel,
    x: Any,
    p: np.ndarray,
    planner: ObservationPlanner,
    budget: int | None = None,
    start: int = 0,
) -> Schedule:
    """Plan observations offline along the predicted trajectory (keyframes, light-curve epochs).

    Without measurements the mean is not updated, so one forecast to the horizon serves every
    decision (:func:`plan_forecast`).

    Parameters
    ----------
    model : PlanningModel
    x : (B, …) array
        Mean at ``start``.
    p : (B, n, n) array
        Covariance at ``start`` (after any observation there).
    planner : ObservationPlanner
    budget : int, optional
        Observations allowed after ``start`` (required by :class:`PosteriorRollout`).
    start : int

    Returns
    -------
    Schedule
    """
    return plan_forecast(forecast(model, x, p, start, planner.horizon - start), planner, budget)


def plan_forecast(
    full: Forecast, planner: ObservationPlanner, budget: int | None = None
) -> Schedule:
    """Plan observations along a given forecast (no mean updates).

    The planner decides at ``full.step``, then after every planned observation, with the
    covariance following ``P⁺ = (P⁻⁻¹ + F)⁻¹`` at the chosen steps.

    Parameters
    ----------
    full : Forecast
        Prediction from the current step to the planner's horizon.
    planner : ObservationPlanner
    budget : int, optional
        Observations allowed (required by :class:`PosteriorRollout`).

    Returns
    -------
    Schedule
    """
    batch = full.covariance.shape[0]
    taken = np.zeros((batch, full.length), dtype=bool)
    covariances = np.empty_like(full.transition)
    remaining = None if budget is None else np.full(batch, int(budget))
    cov = full.covariance
    decide = np.ones(batch, dtype=bool)
    next_at = np.zeros(batch, dtype=int)
    for j in range(full.length):
        if decide.any():
            idx = np.flatnonzero(decide)
            ahead = full.tail(j, cov).select(idx)
            offsets = planner.choose(ahead, None if remaining is None else remaining[idx])
            next_at[idx] = np.where(offsets > 0, j + offsets, -1)
        cov = predict_covariance(cov, full.transition[j], full.process_noise[j])
        decide = next_at == j + 1
        if decide.any():
            post = posterior_covariance(cov, full.information[j])
            cov = np.where(decide[:, None, None], post, cov)
            taken[:, j] = decide
            if remaining is not None:
                remaining = remaining - decide
        covariances[j] = cov
    return Schedule(taken, covariances)


def plan_final_covariance(
    full: Forecast,
    count: int,
    s_max: int | None = None,
    indices: Sequence[int] | None = None,
    measure: str = "trace",
    method: str = "greedy",
) -> Schedule:
    """Choose ``count`` observations along a forecast that minimise the covariance at its end.

    Used for keyframes of a recorded sequence (:func:`select_keyframes`) and epochs of a light
    curve (:mod:`lightcurve.analysis.photometric_planning`), batched over runs.

    Parameters
    ----------
    full, count, s_max, indices, measure
        As in :func:`greedy_schedule`.
    method : {"greedy", "rollout"}
        :func:`greedy_schedule` (the whole set, in any order), or the sequential
        :class:`PosteriorRollout` planner with its window on the last step (what an online
        planner decides, one observation after the other).

    Returns
    -------
    Schedule
    """
    if method == "greedy":
        return greedy_schedule(full, count, s_max, indices, measure)
    if method != "rollout":
        raise ValueError(f"method must be 'greedy' or 'rollout', got {method!r}")
    if not 0 < count <= full.length:
        raise ValueError(f"observation count must be in [1, {full.length}], got {count}")
    horizon = full.step + full.length
    criterion = PosteriorRollout(indices=indices, measure=measure, settle_step=horizon)
    return plan_forecast(full, ObservationPlanner(criterion, s_max or full.length, horizon), count)
