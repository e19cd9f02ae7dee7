"""Fisher-information observation planning (Li et al. 2024, sec. 2, eqs. 19–23).

After a filter update at step ``k`` the planner predicts ahead and picks the step ``k + s``,
``s ∈ [1, s_max]``, of the next observation; the estimator only propagates in between. The
estimator enters through a small protocol (:class:`PlanningModel`): one-step transition of the
mean with its linearisation ``(Φ, Q)`` and the Fisher information ``F = Hᵀ R⁻¹ H`` (eq. 20)
of an observation taken at a predicted state. The same planner therefore schedules landmark
images of a lander (:mod:`filters.lander`), keyframes of a monocular pipeline and epochs of a
light curve, given the model's callables.

Two pluggable criteria:

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

Offline sets for the covariance at the last step (keyframes of a recorded sequence, epochs of
a light curve) are chosen by :func:`greedy_schedule`: exact covariance reductions of every
candidate from one filter and one RTS smoother pass (:func:`final_covariance_reduction`),
greedy additions and exchange passes. :class:`MonocularKeyframeModel` and
:func:`monocular_keyframes` drive it from the monocular EKF of :mod:`filters.monocular`.

Arrays carry leading batch axes (independent Monte Carlo runs): means ``(B, …)`` are opaque to
the planner (only handed back to the model), covariances are ``(B, n, n)``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

__all__ = [
    "Criterion",
    "FisherTrace",
    "Forecast",
    "FunctionModel",
    "MonocularKeyframeModel",
    "ObservationPlanner",
    "PlanningModel",
    "PosteriorRollout",
    "Schedule",
    "covariance_measure",
    "final_covariance_reduction",
    "fisher_information",
    "forecast",
    "greedy_schedule",
    "monocular_keyframes",
    "plan_final_covariance",
    "plan_forecast",
    "plan_schedule",
    "posterior_covariance",
    "propagate_schedule",
    "select_keyframes",
    "uniform_steps",
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

    def select(self, runs: np.ndarray) -> Forecast:
        """The forecast of a subset of runs (index array over ``B``)."""
        return Forecast(
            self.step,
            self.covariance[runs],
            self.transition[:, runs],
            self.process_noise[:, runs],
            self.information[:, runs],
        )


def _propagate(p: np.ndarray, phi: np.ndarray, q: np.ndarray) -> np.ndarray:
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
        p = np.broadcast_to(forecast.covariance, (n_cand, *forecast.covariance.shape))
        cost = np.zeros((n_cand, batch))
        for j in range(length):
            p = _propagate(p, forecast.transition[j], forecast.process_noise[j])
            take = mask[:, :, j]
            if take.any():
                post = posterior_covariance(p, forecast.information[j])
                p = np.where(take[..., None, None], post, p)
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
    p = ahead.covariance
    for j in range(ahead.length):
        p = _propagate(p, ahead.transition[j], ahead.process_noise[j])
        prior[j] = p
        if taken[:, j].any():
            updated = posterior_covariance(p, ahead.information[j])
            p = np.where(taken[:, j, None, None], updated, p)
        post[j] = p
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
        (``tests/filters/test_planner.py``).

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
        cov = _propagate(cov, full.transition[j], full.process_noise[j])
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
    curve (:mod:`lightcurve.photometric_planning`), batched over runs.

    Parameters
    ----------
    full : Forecast
        Prediction over the candidate steps ``full.step + 1 … full.step + L``.
    count : int
        Observations to take (``1 … L``).
    s_max : int, optional
        Largest interval between observations (default: unlimited).
    indices : sequence of int, optional
        States whose final covariance is minimised (default: all).
    measure : {"trace", "logdet"}
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


def select_keyframes(
    information: np.ndarray,
    transition: np.ndarray,
    process_noise: np.ndarray,
    covariance: np.ndarray,
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
    """The monocular EKF of Deng et al. 2024 (:class:`filters.monocular.MonocularEKF`) as a
    :class:`PlanningModel` over a sequence of frames.

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
        """Model of a :class:`~filters.monocular.MonocularEKF` over frames at ``times``.

        Parameters
        ----------
        ekf : MonocularEKF
        times : (K,) array
            Frame times (s), the first being the EKF's current time.
        sigma : (K,) array, optional
            One-sigma rotation error per axis of each frame's attitude (rad), e.g.
            :attr:`filters.epipolar.AttitudeSequence.sigma`; ``R_k = (σ_k/2)² I₃``. Default:
            the EKF's ``R`` for every frame.
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
        from filters.monocular import inertia_form

        x = np.asarray(x, dtype=float)
        f = torque_free_derivative(inertia_form(self.form).tensor(x[..., 7:]))
        qw = rk4_step(f, x[..., :7], self.times[step + 1] - self.times[step])
        return np.concatenate([qw, x[..., 7:]], axis=-1)

    def linearize(self, x: Any, step: Any) -> tuple[np.ndarray, np.ndarray]:
        """The EKF's ``Φ`` and ``Q ΔT`` to the next frame."""
        from filters.attitude import error_state_matrix, transition_matrix
        from filters.monocular import inertia_form

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
