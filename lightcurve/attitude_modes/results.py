"""Outcomes of the attitude-mode test: fitted hypotheses, weak offset axes, the verdict."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from lightcurve.attitude_modes.posterior import OffsetPosterior

#: Label of the torque-free hypothesis.
TUMBLING = "tumbling"


@dataclass
class WeakAxis:
    """A direction of a fitted offset that the light curve pins down poorly.

    The offset is ``δ = δ̂ + t u + (the other two components refitted)`` along the axis:
    ``u`` a unit eigenvector of the posterior covariance ``C`` (small-angle rotation axis,
    body axes of the profile frame); see :mod:`lightcurve.attitude_modes.weak_axes`.

    Attributes
    ----------
    axis : (3,) numpy.ndarray
        ``u`` (unit, body axes).
    sigma_deg : float
        Laplace 1σ along ``u`` (deg).
    interval_deg : (2,) numpy.ndarray
        ``[t_lo, t_hi]`` (deg, relative to the fitted offset): the stretch around the fit
        where the profile of ``−2 ln`` posterior stays within ``χ²₁(0.95) = 3.84`` of the
        fit's (the 95 % profile-likelihood interval, Wilks' theorem; not symmetric, and
        wider than ``±2σ`` where the ``χ²`` valley is flat-bottomed), walked in 0.25° steps
        and clipped to ``±3 σ_off``.
    """

    axis: np.ndarray
    sigma_deg: float
    interval_deg: np.ndarray

    def to_dict(self) -> dict[str, Any]:
        return {
            "axis": [float(v) for v in self.axis],
            "sigma_deg": float(self.sigma_deg),
            "interval_deg": [float(v) for v in self.interval_deg],
        }


@dataclass
class ModeHypothesis:
    """One fitted hypothesis.

    Attributes
    ----------
    mode : str
        ``tumbling`` or a key of :data:`~lightcurve.attitude_modes.MODE_HYPOTHESES`.
    shape : str
    chi2 : float
        ``Σ ((m̂ − m)/σ)²`` over all measurements at the best fit.
    n_params : int
    log_evidence : float
        Laplace ``ln Z`` (module doc; the constant ``−½ Σ ln 2πσ²`` left out).
    consistent : bool
        Passes the ``χ²`` consistency test.
    offsets_deg : (3,) numpy.ndarray or None
        ``[roll, pitch, yaw]`` (deg) of the fitted offset from the profile frame (for
        ``inertial``: of the fitted attitude from the inertial axes); None for tumbling.
    offset_sigma_deg : (3,) numpy.ndarray or None
        1σ of the offset's small-angle components (deg, body axes).
    weak_axes : list of WeakAxis
        Directions of the offset the light curve pins down worse than ``weak_sigma_deg``
        (empty for tumbling).
    quaternion : (4,) numpy.ndarray
        Attitude at the last epoch (inertial → body).
    omega_rad_s : (3,) numpy.ndarray
        Body rates at the last epoch (rad/s).
    posterior : OffsetPosterior or None
        Sampled posterior of the offset (set for the most probable stabilised hypothesis
        by :func:`~lightcurve.attitude_modes.identify_attitude_mode`; None otherwise).
    posterior_sampler : callable or None
        ``sampler(seed=…) → OffsetPosterior``: samples this hypothesis' offset posterior
        (:func:`~lightcurve.attitude_modes.posterior.sample_offset_posterior` on its fit;
        None for tumbling).
    """

    mode: str
    shape: str
    chi2: float
    n_params: int
    log_evidence: float
    consistent: bool
    offsets_deg: np.ndarray | None
    offset_sigma_deg: np.ndarray | None
    quaternion: np.ndarray
    omega_rad_s: np.ndarray
    weak_axes: list[WeakAxis] = field(default_factory=list)
    probability: float = 0.0
    posterior: OffsetPosterior | None = None
    posterior_sampler: Callable[..., OffsetPosterior] | None = field(
        default=None, repr=False, compare=False
    )

    def to_dict(self) -> dict[str, Any]:
        def listed(v: np.ndarray | None) -> list[float] | None:
            return None if v is None else [float(x) for x in v]

        return {
            "mode": self.mode,
            "shape": self.shape,
            "chi2": float(self.chi2),
            "n_params": int(self.n_params),
            "log_evidence": float(self.log_evidence),
            "consistent": bool(self.consistent),
            "probability": float(self.probability),
            "offsets_deg": listed(self.offsets_deg),
            "offset_sigma_deg": listed(self.offset_sigma_deg),
            "offset_weak_axes": [w.to_dict() for w in self.weak_axes],
        }


@dataclass
class ModeIdentification:
    """Outcome of :func:`~lightcurve.attitude_modes.identify_attitude_mode`.

    Attributes
    ----------
    mode : str
        Most probable mode: ``tumbling`` or a stabilised profile label.
    probability : float
        Its posterior probability (summed over shapes).
    probabilities : dict
        Mode → posterior probability.
    best : ModeHypothesis
        Most probable hypothesis of the most probable mode.
    hypotheses : list of ModeHypothesis
    none_fits : bool
        No hypothesis passes the consistency test.
    notes : list of str
    """

    mode: str
    probability: float
    probabilities: dict[str, float]
    best: ModeHypothesis
    hypotheses: list[ModeHypothesis]
    none_fits: bool
    notes: list[str] = field(default_factory=list)

    @property
    def offsets_deg(self) -> np.ndarray | None:
        """Fitted offsets of the best hypothesis (None when tumbling)."""
        return self.best.offsets_deg

    def summary(self) -> dict[str, Any]:
        """The summary keys ``attitude_mode``, ``attitude_mode_probability``,
        ``attitude_offsets_deg``, ``attitude_offset_sigma_deg``, ``attitude_offset_weak_axes``,
        the sampled posterior's ``attitude_offset_intervals_deg``,
        ``attitude_offset_region_rise``, ``attitude_offset_laplace_ok`` and
        ``attitude_offset_posterior`` (None for tumbling), and the details."""
        stabilised = self.mode != TUMBLING
        offsets = self.best.offsets_deg if stabilised else None
        sigma = self.best.offset_sigma_deg if stabilised else None
        posterior = self.best.posterior if stabilised else None
        return {
            "attitude_mode": self.mode,
            "attitude_mode_probability": float(self.probability),
            "attitude_offsets_deg": None if offsets is None else [float(v) for v in offsets],
            "attitude_offset_sigma_deg": None if sigma is None else [float(v) for v in sigma],
            "attitude_offset_weak_axes": [w.to_dict() for w in self.best.weak_axes]
            if stabilised
            else [],
            "attitude_offset_intervals_deg": None
            if posterior is None
            else {k: v.tolist() for k, v in posterior.intervals_deg.items()},
            "attitude_offset_region_rise": None
            if posterior is None
            else {k: float(v) for k, v in posterior.region_rise.items()},
            "attitude_offset_laplace_ok": None if posterior is None else posterior.laplace_ok,
            "attitude_offset_posterior": None if posterior is None else posterior.to_dict(),
            "attitude_mode_shape": self.best.shape,
            "attitude_mode_probabilities": {k: float(v) for k, v in self.probabilities.items()},
            "attitude_hypotheses": [h.to_dict() for h in self.hypotheses],
        }
