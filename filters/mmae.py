"""Multiple-model adaptive estimation: a bank of attitude UKFs, one per candidate model.

Each model ``j`` (a candidate shape with its materials and inertia) runs its own
:class:`~filters.ukf.AttitudeUKF`. After every measurement the posterior model
probabilities follow Bayes' rule with the filters' innovation likelihoods
``p(z_k | M_j) = N(ν_j; 0, S_j)`` (Magill 1965; Linares et al. 2013 for light curves):

``p_j ← p_j N(ν_j; 0, S_j) / Σ_i p_i N(ν_i; 0, S_i)``,

computed in logarithms, then floored, ``p_j ← max(p_j, p_floor)`` and renormalised, so
that a model cannot be locked out by a transient (a glint its filter has not yet learnt to
predict) and recover later.

The bank reports the fused estimate — the probability-weighted quaternion average
(Markley et al. 2007, :func:`filters.attitude.quaternion_mean`; never a linear blend of
components), the weighted rates, and the mixture covariance
``Σ p_j (P_j + δx_j δx_jᵀ)`` with ``δx_j`` the deviation of model ``j``'s estimate from
the fused one — and a **consistency test** that flags when no candidate fits: over a
sliding window of the last ``W`` measurements, a consistent filter's normalised innovations
squared ``ν²/S`` average ``χ²(W)/W``; a model whose windowed mean exceeds the upper
``level`` quantile of that distribution does not fit, and when none fits the bank says so
(``none_fits``) instead of returning the least-bad model. Gated measurements count with
their NIS (capped at ``nis_cap`` so one glint does not dominate the window).

filterpy 2.0.0's ``MMAEFilterBank`` is not used: its ``predict()`` does not propagate
UKFs (it passes ``dt = 0``), its blended covariance omits the spread of the means, its
probabilities have no floor, and it blends quaternions linearly.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence
from typing import Any

import numpy as np

from filters.attitude import (
    quaternion_conjugate,
    quaternion_mean,
    quaternion_multiply,
    quaternion_to_grp,
)
from filters.kalman import chi2_band
from filters.ukf import AttitudeUKF, Measurement, UpdateResult

__all__ = ["MultipleModelBank"]


class MultipleModelBank:
    """A bank of single-member :class:`~filters.ukf.AttitudeUKF`, one per model.

    Parameters
    ----------
    filters : sequence of AttitudeUKF
        One filter (one member) per model.
    names : sequence of str
        Model names.
    log_prior : (M,) array, optional
        Initial log-probabilities (uniform when omitted), e.g. ``−½ χ²`` of each model's
        initial fit.
    floor : float
        Probability floor ``p_floor``.
    window : int
        Measurements in the consistency window ``W``.
    level : float
        Quantile of ``χ²(W)/W`` above which a model does not fit.
    nis_cap : float
        NIS values are capped at this in the window.
    """

    def __init__(
        self,
        filters: Sequence[AttitudeUKF],
        names: Sequence[str],
        log_prior: Any = None,
        floor: float = 1e-3,
        window: int = 60,
        level: float = 0.99,
        nis_cap: float = 25.0,
    ) -> None:
        if len(filters) != len(names) or not filters:
            raise ValueError("one filter per model name, at least one")
        if any(len(f) != 1 for f in filters):
            raise ValueError("each model's filter must hold exactly one member")
        if not 0.0 <= floor * len(filters) < 1.0:
            raise ValueError(f"probability floor {floor} is too large for {len(filters)} models")
        self.filters = list(filters)
        self.names = list(names)
        self.floor = float(floor)
        self.window = int(window)
        self.nis_cap = float(nis_cap)
        self.bound = chi2_band(1, self.window, 1.0 - 2.0 * (1.0 - level))[1]
        log_p = np.zeros(len(filters)) if log_prior is None else np.asarray(log_prior, float)
        self.probabilities = self._floored(np.exp(log_p - np.max(log_p)))
        self._nis: list[deque[float]] = [deque(maxlen=self.window) for _ in filters]

    def __len__(self) -> int:
        return len(self.filters)

    def _floored(self, p: np.ndarray) -> np.ndarray:
        p = p / p.sum()
        p = np.maximum(p, self.floor)
        return p / p.sum()

    def predict(self, dt: float) -> None:
        """Propagate every model's filter over ``dt`` seconds."""
        for f in self.filters:
            f.predict(dt)

    def update(
        self, z: float, r: float, hx: Sequence[Measurement], use: bool = True
    ) -> list[UpdateResult]:
        """Update every filter and the model probabilities with one measurement.

        Parameters
        ----------
        z, r : float
            Measurement and its variance.
        hx : sequence of callables
            Each model's measurement function (see :meth:`AttitudeUKF.update`).
        use : bool
            False: only evaluate the innovations (no filter or probability update, no
            consistency sample), e.g. for measurements already used by an initial fit.

        Returns
        -------
        list of UpdateResult
            One per model.
        """
        results = [
            f.update(z, r, h) if use else f.evaluate(z, r, h)
            for f, h in zip(self.filters, hx, strict=True)
        ]
        if use:
            log_l = np.array([float(res.log_likelihood[0]) for res in results])
            log_l = np.nan_to_num(log_l, nan=-np.inf)
            if np.isfinite(log_l).any():
                with np.errstate(divide="ignore"):
                    log_post = np.log(self.probabilities) + log_l
                self.probabilities = self._floored(np.exp(log_post - np.max(log_post)))
            for window, res in zip(self._nis, results, strict=True):
                nis = float(res.nis[0])
                if math.isfinite(nis):
                    window.append(min(nis, self.nis_cap))
        return results

    @property
    def windowed_nis(self) -> np.ndarray:
        """Mean NIS of each model over its window (NaN before any sample)."""
        return np.array([np.mean(w) if w else math.nan for w in self._nis])

    @property
    def consistent(self) -> np.ndarray:
        """Models whose windowed mean NIS is within the bound (True until the window is
        full)."""
        full = np.array([len(w) == self.window for w in self._nis])
        return ~full | (self.windowed_nis <= self.bound)

    @property
    def none_fits(self) -> bool:
        """No model passes the consistency test."""
        return not bool(self.consistent.any())

    @property
    def best(self) -> int:
        """Index of the most probable model."""
        return int(np.argmax(self.probabilities))

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
        """
        p = self.probabilities
        qs = np.stack([f.q[0] for f in self.filters])
        ws = np.stack([f.omega[0] for f in self.filters])
        q = quaternion_mean(qs, p)
        omega = p @ ws
        dx = np.concatenate(
            [quaternion_to_grp(quaternion_multiply(qs, quaternion_conjugate(q))), ws - omega], 1
        )
        covariance = sum(
            pj * (f.P[0, :6, :6] + np.outer(d, d))
            for pj, f, d in zip(p, self.filters, dx, strict=True)
        )
        return q, omega, covariance
