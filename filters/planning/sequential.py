"""Sequential observation planning: after each update, when to observe next (Li et al. 2024).

After a filter update at step ``k`` the planner predicts ahead (:func:`~filters.planning.
information.forecast`) and picks the step ``k + s``, ``s ∈ [1, s_max]``, of the next
observation; the estimator only propagates in between (Li et al. 2024, fig. 2). Two pluggable
criteria:

:class:`FisherTrace` (Li et al. 2024, eq. 23)
    ``s = argmin tr(F_{k+s}⁻¹)``: the Cramér–Rao bound (eqs. 21–22) of the observation alone,
    on a block of states the observation measures (``F`` is singular on the full ``[r, ṙ]``
    state because an image carries no velocity information).
:class:`PosteriorRollout` (this project)
    Accounts for the information already held: the covariance after an observation is
    ``P⁺ = (P⁻⁻¹ + F)⁻¹`` and its trace (or log-determinant) is what the filter will have. A
    myopic ``min tr(P⁺_{k+s})`` always picks ``s = 1``, so the criterion is posed under an
    image budget: the cost of ``s`` is the predicted posterior covariance summed over the
    evaluation window ``[settle, horizon]`` when the next image is at ``k + s`` and the
    remaining budget is then spread evenly (a one-step rollout of the uniform policy,
    Bertsekas 2005, *Dynamic Programming*, sec. 6.4).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from filters.planning.information import (
    Forecast,
    PlanningModel,
    covariance_measure,
    forecast,
)

__all__ = [
    "Criterion",
    "FisherTrace",
    "ObservationPlanner",
    "PosteriorRollout",
]


class Criterion(Protocol):
    """A planning criterion: a cost per candidate offset ``s = 1 … S`` and run."""

    def lookahead(self, s_max: int, steps_left: int) -> int:
        """How many steps ahead the criterion needs predicted."""
        ...

    def costs(self, forecast: Forecast, s_max: int, remaining: np.ndarray | None) -> np.ndarray:
        """Cost ``(S, B)`` of taking the next observation at ``k + s``."""
        ...


def _block(f: np.ndarray, indices: Sequence[int] | None) -> np.ndarray:
    if indices is None:
        return f
    idx = np.asarray(indices)
    return f[..., idx[:, None], idx[None, :]]


@dataclass(frozen=True)
class FisherTrace:
    """Li et al.'s criterion ``min tr(F_{k+s}⁻¹)`` (eq. 23).

    Parameters
    ----------
    indices : sequence of int, optional
        States on which the Fisher information is inverted (default: all). The information of
        one image on ``[r, ṙ]`` is singular (no velocity columns in ``H``), so the lander uses
        the position (and attitude) block: the Cramér–Rao bound of the image alone.
    tolerance : float
        Eigenvalues below ``tolerance × largest`` count as zero: the bound is then infinite.
    """

    indices: Sequence[int] | None = None
    tolerance: float = 1e-12

    def lookahead(self, s_max: int, steps_left: int) -> int:
        """Li et al. predict ``s_max`` steps ahead."""
        return min(s_max, steps_left)

    def costs(self, forecast: Forecast, s_max: int, remaining: np.ndarray | None) -> np.ndarray:
        """``tr(F⁻¹)`` at ``k + 1 … k + S`` (``inf`` where ``F`` is singular)."""
        f = _block(forecast.information[: min(s_max, forecast.length)], self.indices)
        eig = np.linalg.eigvalsh(f)
        floor = self.tolerance * np.maximum(eig[..., -1:], np.finfo(float).tiny)
        safe = np.where(eig > floor, eig, 1.0)
        return np.where(np.all(eig > floor, axis=-1), np.sum(1.0 / safe, axis=-1), np.inf)


@dataclass(frozen=True)
class PosteriorRollout:
    """Improved criterion: predicted posterior covariance under an image budget.

    For each candidate ``s`` the covariance is propagated to the horizon with the next image at
    ``k + s`` followed by a base schedule for the remaining ``b − 1`` images: every ``s_max``
    steps until ``settle_step`` (images before the evaluation window only keep the features
    matched), the rest spread evenly up to the horizon. Every image applies
    ``P⁺ = (P⁻⁻¹ + F)⁻¹``. The cost is ``Σ_t w_t m(P_t)`` with ``m`` the trace or
    log-determinant of the block ``indices`` and ``w_t = 1`` from ``settle_step`` on
    (``pre_settle_weight`` before). Choosing the best ``s`` against this base schedule is a
    one-step rollout (Bertsekas 2005, sec. 6.4): never worse than the base schedule in the
    predicted cost. Needs a budget (:class:`ObservationPlanner` ``remaining``).

    Parameters
    ----------
    indices : sequence of int, optional
        States whose covariance is scored (default: all).
    measure : {"trace", "logdet"}
    settle_step : int
        First step of the evaluation window.
    pre_settle_weight : float
        Weight of the steps before ``settle_step``.
    """

    indices: Sequence[int] | None = None
    measure: str = "trace"
    settle_step: int = 0
    pre_settle_weight: float = 0.0

    def lookahead(self, s_max: int, steps_left: int) -> int:
        """The rollout predicts to the horizon."""
        return steps_left

    def costs(self, forecast: Forecast, s_max: int, remaining: np.ndarray | None) -> np.ndarray:
        """Rollout cost of ``s = 1 … S``, shape ``(S, B)``."""
        if remaining is None:
            raise ValueError("PosteriorRollout needs an image budget (remaining images per run)")
        length = forecast.length
        n_cand = min(s_max, length)
        batch = forecast.covariance.shape[0]
        remaining = np.broadcast_to(np.asarray(remaining), (batch,))
        # mask[s-1, b, j-1]: image at k + j under candidate s for run b.
        mask = np.zeros((n_cand, batch, length), dtype=bool)
        settle = self.settle_step - forecast.step
        for s in range(1, n_cand + 1):
            for left in np.unique(remaining):
                runs = remaining == left
                mask[s - 1, runs] = _base_schedule(s, length, int(left), s_max, settle)
        steps = forecast.step + np.arange(1, length + 1)
        weights = np.where(steps >= self.settle_step, 1.0, self.pre_settle_weight)
        cost = np.zeros((n_cand, batch))
        for j, (_, p) in enumerate(forecast.covariances(mask)):
            if weights[j] != 0:
                cost += weights[j] * covariance_measure(p, self.indices, self.measure)
        return cost


def _base_schedule(first: int, length: int, budget: int, s_max: int, settle: int) -> np.ndarray:
    """Offsets ``1 … length`` imaged by the rollout's base schedule (bool ``(length,)``).

    An image at ``first``; then every ``s_max`` before ``settle``; the rest of ``budget``
    spread evenly over the remaining offsets.
    """
    taken = np.zeros(length, dtype=bool)
    if budget < 1:
        return taken
    taken[first - 1] = True
    pre = np.arange(first + s_max, min(settle, length + 1), s_max)[: budget - 1]
    taken[pre - 1] = True
    last = int(pre[-1]) if pre.size else first
    rest = min(budget - 1 - pre.size, length - last)
    if rest > 0:
        spots = last + np.round(np.arange(1, rest + 1) * (length - last) / rest).astype(int)
        taken[spots - 1] = True
    return taken


@dataclass(frozen=True)
class ObservationPlanner:
    """Choose the next observation step (Li et al. 2024, fig. 2) with a pluggable criterion.

    Parameters
    ----------
    criterion : Criterion
        :class:`FisherTrace` (seed) or :class:`PosteriorRollout` (improved).
    s_max : int
        Largest interval in steps (the view must not change too much for feature matching).
    horizon : int
        Last step at which an observation may be taken.
    """

    criterion: Criterion
    s_max: int
    horizon: int

    def __post_init__(self) -> None:
        if self.s_max < 1:
            raise ValueError(f"s_max must be >= 1, got {self.s_max}")

    def next_offset(
        self,
        model: PlanningModel,
        x: Any,
        p: np.ndarray,
        step: int,
        remaining: np.ndarray | None = None,
    ) -> np.ndarray:
        """Offsets ``s`` (``(B,)`` int) of the next observation after ``step``; 0 = none.

        Parameters
        ----------
        model : PlanningModel
        x : (B, …) array
            Mean after the update at ``step``.
        p : (B, n, n) array
            Covariance after that update.
        step : int
            Current step ``k``.
        remaining : (B,) int array, optional
            Images left in each run's budget (``None``: unlimited).

        Returns
        -------
        (B,) numpy.ndarray of int
        """
        p = np.asarray(p, dtype=float)
        steps_left = self.horizon - step
        if steps_left < 1:
            return np.zeros(p.shape[0], dtype=int)
        length = self.criterion.lookahead(self.s_max, steps_left)
        return self.choose(forecast(model, x, p, step, length), remaining)

    def choose(self, ahead: Forecast, remaining: np.ndarray | None = None) -> np.ndarray:
        """Offsets ``s`` from a forecast made at ``ahead.step`` (see :meth:`next_offset`)."""
        batch = ahead.covariance.shape[0]
        steps_left = self.horizon - ahead.step
        if steps_left < 1:
            return np.zeros(batch, dtype=int)
        ahead = ahead.head(self.criterion.lookahead(self.s_max, steps_left))
        cost = self.criterion.costs(ahead, self.s_max, remaining)
        # Ties go to the longest interval (fewest images); cost has shape (S, B).
        offsets = cost.shape[0] - np.argmin(cost[::-1], axis=0)
        if remaining is not None:
            offsets = np.where(np.broadcast_to(np.asarray(remaining), (batch,)) > 0, offsets, 0)
        return offsets.astype(int)
