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

**Model error** (``adaptive=True``). A candidate that is close to the object but not exact
(dimensions, materials, mass distribution) predicts every measurement with an error the
measurement variance ``R`` does not hold; its filter then grows over-confident and its gate
rejects most of the data. Each model keeps a model-error variance ``σ_m²`` estimated by
covariance matching over the last ``W`` innovations of its heaviest hypothesis (Mehra 1970;
Mohamed & Schwarz 1999): a consistent filter has ``E[ν²] = S = S_x + R + σ_m²``, so

``σ_m² = max(0, mean(ν² − S_x) − mean(R))``,

and every update of the model uses ``R + σ_m²``. Each sample is capped at ``nis_cap`` times
its ``S`` (a glint does not inflate the variance), gated measurements included (a model
that rejects everything still learns its error). The consistency windows keep testing
against the measurement variance alone.

**Diverged filters.** A hypothesis whose filter diverges (:attr:`AttitudeUKF.divergence`)
gets weight zero; a model whose every hypothesis has diverged is dropped: probability 0
(below the floor: a filter that cannot be evaluated has no likelihood to recover with),
excluded from the consistency test, its reason in :attr:`MultipleModelBank.dropped`.
When every model has diverged the probabilities are left as they were, the estimates are
the last finite ones, and the bank reports that no model fits.

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
from filters.consistency import NISWindow
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
    adaptive : bool
        Estimate each model's model-error variance (see the module notes).

    Attributes
    ----------
    ukf : AttitudeUKF
        The stacked filter: the members of model ``j`` are ``ukf.x[members[j]]`` etc.
    members : list of slice
        Each model's members in :attr:`ukf`.
    dropped : dict of str to str
        Models whose every hypothesis diverged, with the reason of the first member.
    """

    def __init__(
        self,
        filters: Sequence[AttitudeUKF],
        names: Sequence[str],
        *,
        log_prior: Sequence[Any] | None = None,
        floor: float = 1e-3,
        window: int = 60,
        level: float = 0.99,
        nis_cap: float = 25.0,
        residual_factor: float = 4.0,
        adaptive: bool = False,
    ) -> None:
        if len(filters) != len(names) or not filters:
            raise ValueError("one filter per model name, at least one")
        if not 0.0 <= floor * len(filters) < 1.0:
            raise ValueError(f"probability floor {floor} is too large for {len(filters)} models")
        self.ukf = AttitudeUKF.stack(filters)
        bounds = np.cumsum([0, *(len(f) for f in filters)])
        self.members = [slice(int(a), int(b)) for a, b in itertools.pairwise(bounds)]
        self.names = list(names)
        self.dropped: dict[str, str] = {}
        self.floor = float(floor)
        self.window = int(window)
        self.nis_cap = float(nis_cap)
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
        # Per model: the windowed NIS ν²/S and the windowed ν²/R of its heaviest hypothesis.
        self._nis = [NISWindow(self.window, level, self.nis_cap) for _ in filters]
        self._misfit = [NISWindow(self.window, level, self.nis_cap) for _ in filters]
        self.bound = self._nis[0].bound
        self.adaptive = bool(adaptive)
        self._matching: list[deque[tuple[float, float]]] = [
            deque(maxlen=self.window) for _ in filters
        ]
        self.model_variance = np.zeros(len(filters))

    def __len__(self) -> int:
        return len(self.members)

    @property
    def alive(self) -> np.ndarray:
        """(models,) bool: the models not dropped for divergence."""
        return np.array([name not in self.dropped for name in self.names], dtype=bool)

    @property
    def all_diverged(self) -> bool:
        """Every model has been dropped for divergence."""
        return len(self.dropped) == len(self)

    def _floored(self, p: np.ndarray) -> np.ndarray:
        alive = self.alive
        p = np.where(alive, p, 0.0)
        p = p / p.sum()
        p = np.where(alive, np.maximum(p, self.floor), 0.0)
        return p / p.sum()

    def _drop_diverged(self) -> None:
        """Weight zero for diverged hypotheses; drop the models with none left."""
        diverged = self.ukf.diverged
        if not diverged[np.isfinite(self._log_w)].any():
            return
        joint = np.where(diverged, -np.inf, self._log_w)
        model_log = self._model_log(joint)
        for j, s in enumerate(self.members):
            if self.names[j] not in self.dropped and diverged[s].all():
                self.dropped[self.names[j]] = str(self.ukf.divergence[s][0])
        left = np.isfinite(model_log)
        self._log_w = np.where(
            left[self._model], joint - np.where(left, model_log, 0.0)[self._model], joint
        )
        if not self.all_diverged:
            self.probabilities = self._floored(self.probabilities)

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
        self._drop_diverged()

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
        r_total = r + self.model_variance[self._model]
        if use:
            result = self.ukf.update(z, r_total, stacked)
        else:
            result = self.ukf.evaluate(z, r_total, stacked)
        results = [_members(result, s) for s in self.members]
        if not use:
            return results
        self._drop_diverged()
        log_l = np.where(np.isnan(result.log_likelihood), -np.inf, result.log_likelihood)
        model_log = self._model_log(self._log_w + log_l)
        informed = np.logical_or.reduceat(np.isfinite(log_l), self._starts)
        model_log = np.where(informed, model_log, -np.inf)
        with np.errstate(invalid="ignore"):  # −∞ − (−∞) of dropped models, not taken
            self._log_w = np.where(
                informed[self._model], self._log_w + log_l - model_log[self._model], self._log_w
            )
        if np.isfinite(model_log).any() and not self.all_diverged:
            with np.errstate(divide="ignore"):
                log_post = np.log(self.probabilities) + model_log
            self.probabilities = self._floored(np.exp(log_post - np.max(log_post)))
        for window, misfit, res, lead, alive in zip(
            self._nis, self._misfit, results, leaders, self.alive, strict=True
        ):
            nis = float(res.nis[lead])
            if alive and math.isfinite(nis):
                window.add(nis)
                misfit.add(float(res.innovation[lead]) ** 2 / r)
        if self.adaptive:
            self._match(results, leaders, r)
        return results

    def _match(self, results: Sequence[UpdateResult], leaders: Sequence[int], r: float) -> None:
        """Covariance matching of every live model's model-error variance (module notes)."""
        for j, (res, lead) in enumerate(zip(results, leaders, strict=True)):
            s, nu = float(res.variance[lead]), float(res.innovation[lead])
            if not (self.alive[j] and math.isfinite(s) and math.isfinite(nu)):
                continue
            s_state = s - r - self.model_variance[j]
            self._matching[j].append((min(nu * nu, self.nis_cap * s) - s_state, r))
            if len(self._matching[j]) < min(10, self.window):
                continue
            excess, measured = np.mean(np.asarray(self._matching[j]), axis=0)
            self.model_variance[j] = max(0.0, float(excess - measured))

    @property
    def model_error(self) -> np.ndarray:
        """Each model's estimated model-error 1σ ``σ_m`` (units of the measurement; zero
        without ``adaptive``)."""
        return np.sqrt(self.model_variance)

    def evaluate(self, z: float, r: float, hx: Measurement, model: int) -> UpdateResult:
        """Innovation statistics of one model's hypotheses for a measurement, without using
        it (``hx`` is that model's measurement function)."""
        return self.ukf.evaluate(z, r, hx, members=self.members[model])

    @property
    def windowed_nis(self) -> np.ndarray:
        """Mean NIS of each model over its window (NaN before any sample)."""
        return np.array([w.mean for w in self._nis])

    @property
    def windowed_misfit(self) -> np.ndarray:
        """Mean ``ν²/R`` of each model over its window (NaN before any sample)."""
        return np.array([w.mean for w in self._misfit])

    @property
    def consistent(self) -> np.ndarray:
        """Models whose windowed mean NIS is within the bound and whose windowed mean
        ``ν²/R`` is within ``residual_factor`` times it (True until the window is full);
        never a dropped model."""
        full = np.array([w.full for w in self._nis])
        fits = (self.windowed_nis <= self.bound) & (
            self.windowed_misfit <= self.residual_factor * self.bound
        )
        return (~full | fits) & self.alive

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
