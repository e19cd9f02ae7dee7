"""Multiple-model adaptive estimation: a bank of attitude UKFs, one per candidate model.

Each model ``j`` (a candidate shape with its materials and inertia) runs its own
:class:`~filters.ukf.AttitudeUKF`. After every measurement the posterior model
probabilities follow Bayes' rule with the filters' innovation likelihoods
``p(z_k | M_j) = N(ν_j; 0, S_j)`` (Magill 1965; Linares et al. 2013 for light curves):

``p_j ← p_j p(z_k | M_j) / Σ_i p_i p(z_k | M_i)``,

computed in logarithms, then floored, ``p_j ← max(p_j, p_floor)`` and renormalised, so
that a model cannot be locked out by a transient (a burst of outliers its filter is too
confident to explain) and must climb back from 10⁻¹⁰⁰.

**Hypotheses within a model.** Light curves are ambiguous: a short arc is often fitted
equally well by distinct attitude–rate states (the mirror ambiguity of mirror-symmetric
shapes, see :meth:`filters.symmetry.SymmetryGroup.mirror_twin`). A model's filter may
therefore hold several members — hypotheses ``h`` with weights ``w_jh`` — run in one batched
call (Wetterer et al. 2014's multiple-hypothesis UKF). The model's likelihood is then the
Gaussian sum ``p(z | M_j) = Σ_h w_jh N(ν_jh; 0, S_jh)`` and the weights follow Bayes' rule
without a floor: the data decide between hypotheses, which are not separate models. The
model's estimate is its heaviest hypothesis.

The bank reports the fused estimate — the probability-weighted quaternion average
(Markley et al. 2007, :func:`filters.attitude.quaternion_mean`; never a linear blend of
components) of the models' estimates, the weighted rates, and the mixture covariance
``Σ p_j (P_j + δx_j δx_jᵀ)`` with ``δx_j`` the deviation of model ``j``'s estimate from
the fused one — and a **consistency test** that flags when no candidate fits: over a
sliding window of the last ``W`` measurements, a consistent filter's normalised innovations
squared ``ν²/S`` average ``χ²(W)/W``; a model whose windowed mean (of its heaviest
hypothesis) exceeds the upper ``level`` quantile of that distribution does not fit, and
when none fits the bank says so (``none_fits``) instead of returning the least-bad model.
Gated measurements count with their NIS (capped at ``nis_cap`` so one glint does not
dominate the window). The NIS alone cannot see a filter that has lost track and grown a
huge innovation variance (``S ≫ ν²`` however wrong the predictions): a second window holds
the residuals normalised by the measurement variance only, ``ν²/R``, and a model whose
windowed mean exceeds ``residual_factor`` times the same bound (default 4: an RMS misfit
of twice the measurement errors) does not fit either.

filterpy 2.0.0's ``MMAEFilterBank`` is not used: its ``predict()`` does not propagate
UKFs (it passes ``dt = 0``), its blended covariance omits the spread of the means, its
probabilities have no floor, and it blends quaternions linearly.
"""

from __future__ import annotations

import itertools
import math
from collections import deque
from collections.abc import Sequence
from dataclasses import fields
from typing import Any

import numpy as np

from filters.attitude import (
    quaternion_conjugate,
    quaternion_mean,
    quaternion_multiply,
    quaternion_to_grp,
)
from filters.gaussian import chi2_band
from filters.ukf import AttitudeUKF, Measurement, UpdateResult

__all__ = ["MultipleModelBank"]


class MultipleModelBank:
    """A bank of :class:`~filters.ukf.AttitudeUKF`, one per model, each with one or more
    hypotheses (members).

    The filters are stacked into one (:meth:`AttitudeUKF.stack`, each member keeping its
    model's dynamics), so every cycle runs the sigma points, the propagation and the
    unscented transforms of the whole bank in one batched call; only the measurement
    functions are called model by model.

    Parameters
    ----------
    filters : sequence of AttitudeUKF
        One filter per model (same state dimension and filter settings).
    names : sequence of str
        Model names.
    log_prior : sequence, optional
        Initial log-weights of every hypothesis, one array per model (or one number per
        model for single-member filters), e.g. ``−½ χ²`` of each initial fit. The model
        prior is the log-sum of its hypotheses'. Uniform when omitted.
    floor : float
        Model probability floor ``p_floor``.
    window : int
        Measurements in the consistency window ``W``.
    level : float
        Quantile of ``χ²(W)/W`` above which a model does not fit.
    nis_cap : float
        NIS values (and ``ν²/R``) are capped at this in the windows.
    residual_factor : float
        A model also fails when its windowed mean ``ν²/R`` exceeds this times the bound.

    Attributes
    ----------
    ukf : AttitudeUKF
        The stacked filter: the members of model ``j`` are ``ukf.x[members[j]]`` etc.
    members : list of slice
        Each model's members in :attr:`ukf`.
    """

    def __init__(
        self,
        filters: Sequence[AttitudeUKF],
        names: Sequence[str],
        log_prior: Sequence[Any] | None = None,
        floor: float = 1e-3,
        window: int = 60,
        level: float = 0.99,
        nis_cap: float = 25.0,
        residual_factor: float = 4.0,
    ) -> None:
        if len(filters) != len(names) or not filters:
            raise ValueError("one filter per model name, at least one")
        if not 0.0 <= floor * len(filters) < 1.0:
            raise ValueError(f"probability floor {floor} is too large for {len(filters)} models")
        self.ukf = AttitudeUKF.stack(filters)
        bounds = np.cumsum([0, *(len(f) for f in filters)])
        self.members = [slice(int(a), int(b)) for a, b in itertools.pairwise(bounds)]
        self.names = list(names)
        self.floor = float(floor)
        self.window = int(window)
        self.nis_cap = float(nis_cap)
        self.bound = chi2_band(1, self.window, 1.0 - 2.0 * (1.0 - level))[1]
        if log_prior is None:
            log_prior = [np.zeros(len(f)) for f in filters]
        self._model = np.repeat(np.arange(len(filters)), [len(f) for f in filters])
        self._starts = bounds[:-1]
        joint = np.concatenate(
            [
                np.broadcast_to(np.asarray(lp, dtype=float), (len(f),))
                for f, lp in zip(filters, log_prior, strict=True)
            ]
        )
        model_log = self._model_log(joint)
        self._log_w = joint - model_log[self._model]
        self.probabilities = self._floored(np.exp(model_log - np.max(model_log)))
        self.residual_factor = float(residual_factor)
        self._nis: list[deque[float]] = [deque(maxlen=self.window) for _ in filters]
        self._misfit: list[deque[float]] = [deque(maxlen=self.window) for _ in filters]

    def __len__(self) -> int:
        return len(self.members)

    def _floored(self, p: np.ndarray) -> np.ndarray:
        p = p / p.sum()
        p = np.maximum(p, self.floor)
        return p / p.sum()

    @property
    def log_weights(self) -> list[np.ndarray]:
        """Log-weights of every model's hypotheses (each list entry log-sums to 0)."""
        return [self._log_w[s] for s in self.members]

    def _model_log(self, joint: np.ndarray) -> np.ndarray:
        """``log Σ_h exp(joint_h)`` over each model's hypotheses (−inf for none finite)."""
        peak = np.maximum.reduceat(joint, self._starts)
        peak = np.where(np.isfinite(peak), peak, 0.0)
        with np.errstate(divide="ignore"):
            return peak + np.log(np.add.reduceat(np.exp(joint - peak[self._model]), self._starts))

    def hypotheses(self, model: int) -> int:
        """Number of hypotheses (members) of a model."""
        s = self.members[model]
        return s.stop - s.start

    def leader(self, model: int) -> int:
        """Index of the heaviest hypothesis of a model (within the model)."""
        return int(np.argmax(self._log_w[self.members[model]]))

    def predict(self, dt: float) -> None:
        """Propagate every model's filter over ``dt`` seconds."""
        self.ukf.predict(dt)

    def _stacked(self, hx: Sequence[Measurement]) -> Measurement:
        """One measurement function over the stacked members from one per model."""
        if len(hx) != len(self):
            raise ValueError(f"one measurement function per model ({len(self)}), got {len(hx)}")

        def stacked(q: np.ndarray, theta: np.ndarray) -> np.ndarray:
            return np.concatenate(
                [
                    np.asarray(h(q[s], theta[s]), dtype=float).reshape(s.stop - s.start, -1)
                    for h, s in zip(hx, self.members, strict=True)
                ]
            )

        return stacked

    def update(
        self, z: float, r: float, hx: Sequence[Measurement], use: bool = True
    ) -> list[UpdateResult]:
        """Update every filter, the hypothesis weights and the model probabilities.

        Parameters
        ----------
        z, r : float
            Measurement and its variance.
        hx : sequence of callables
            Each model's measurement function (see :meth:`AttitudeUKF.update`).
        use : bool
            False: only evaluate the innovations (no filter, weight or probability update,
            no consistency sample), e.g. for measurements already used by an initial fit.

        Returns
        -------
        list of UpdateResult
            One per model (arrays over its hypotheses).
        """
        leaders = [self.leader(j) for j in range(len(self))]
        stacked = self._stacked(hx)
        result = self.ukf.update(z, r, stacked) if use else self.ukf.evaluate(z, r, stacked)
        results = [_members(result, s) for s in self.members]
        if not use:
            return results
        log_l = np.nan_to_num(result.log_likelihood, nan=-np.inf)
        model_log = self._model_log(self._log_w + log_l)
        informed = np.logical_or.reduceat(np.isfinite(log_l), self._starts)
        model_log = np.where(informed, model_log, -np.inf)
        self._log_w = np.where(
            informed[self._model], self._log_w + log_l - model_log[self._model], self._log_w
        )
        if np.isfinite(model_log).any():
            with np.errstate(divide="ignore"):
                log_post = np.log(self.probabilities) + model_log
            self.probabilities = self._floored(np.exp(log_post - np.max(log_post)))
        for window, misfit, res, lead in zip(
            self._nis, self._misfit, results, leaders, strict=True
        ):
            nis = float(res.nis[lead])
            if math.isfinite(nis):
                window.append(min(nis, self.nis_cap))
                misfit.append(min(float(res.innovation[lead]) ** 2 / r, self.nis_cap))
        return results

    def evaluate(self, z: float, r: float, hx: Measurement, model: int) -> UpdateResult:
        """Innovation statistics of one model's hypotheses for a measurement, without using
        it (``hx`` is that model's measurement function)."""
        return self.ukf.evaluate(z, r, hx, members=self.members[model])

    @property
    def windowed_nis(self) -> np.ndarray:
        """Mean NIS of each model over its window (NaN before any sample)."""
        return np.array([np.mean(w) if w else math.nan for w in self._nis])

    @property
    def windowed_misfit(self) -> np.ndarray:
        """Mean ``ν²/R`` of each model over its window (NaN before any sample)."""
        return np.array([np.mean(w) if w else math.nan for w in self._misfit])

    @property
    def consistent(self) -> np.ndarray:
        """Models whose windowed mean NIS is within the bound and whose windowed mean
        ``ν²/R`` is within ``residual_factor`` times it (True until the window is full)."""
        full = np.array([len(w) == self.window for w in self._nis])
        fits = (self.windowed_nis <= self.bound) & (
            self.windowed_misfit <= self.residual_factor * self.bound
        )
        return ~full | fits

    @property
    def none_fits(self) -> bool:
        """No model passes the consistency test."""
        return not bool(self.consistent.any())

    @property
    def best(self) -> int:
        """Index of the most probable model."""
        return int(np.argmax(self.probabilities))

    def estimate(self, model: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Attitude, rates and covariance of ``[δp, ω(, θ)]`` of a model's heaviest
        hypothesis."""
        i = self.members[model].start + self.leader(model)
        return self.ukf.q[i], self.ukf.omega[i], self.ukf.P[i]

    def parameters(self, model: int) -> np.ndarray:
        """Parameter estimates ``θ`` of a model's heaviest hypothesis."""
        return self.ukf.params[self.members[model].start + self.leader(model)]

    def fused(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Probability-weighted attitude, rates and mixture covariance of ``[δp, ω]``.

        Returns
        -------
        q : (4,) numpy.ndarray
            Weighted quaternion average (sign-canonical).
        omega : (3,) numpy.ndarray
            Weighted mean rates (rad/s).
        covariance : (6, 6) numpy.ndarray
            ``Σ p_j (P_j + δx_j δx_jᵀ)`` with ``δx_j = [GRP(q_j ⊗ q⁻¹), ω_j − ω]``.

        Notes
        -----
        The floor guards against lock-out; it is not evidence. The fusion weights are the
        probabilities above it, ``p_j − p_floor`` (renormalised), so that models held at
        the floor do not spread the fused covariance over their (unrelated) attitudes.
        """
        p = np.clip(self.probabilities - self.floor, 0.0, None)
        p = self.probabilities if p.sum() <= 0.0 else p / p.sum()
        leaders = [s.start + self.leader(j) for j, s in enumerate(self.members)]
        qs, ws, ps = self.ukf.q[leaders], self.ukf.omega[leaders], self.ukf.P[leaders, :6, :6]
        q = quaternion_mean(qs, p)
        omega = p @ ws
        dx = np.concatenate(
            [quaternion_to_grp(quaternion_multiply(qs, quaternion_conjugate(q))), ws - omega], 1
        )
        covariance = np.einsum("j,jab->ab", p, ps + dx[:, :, None] * dx[:, None, :])
        return q, omega, covariance


def _members(result: UpdateResult, members: slice) -> UpdateResult:
    """The part of an update's outcome that belongs to some members."""
    return UpdateResult(*(getattr(result, f.name)[members] for f in fields(result)))
