"""Laplace evidence of a fitted hypothesis, its ``χ²`` consistency test, and the posterior
probabilities of the attitude modes (see :mod:`lightcurve.attitude_modes`)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy.stats import chi2 as chi2_distribution

from lightcurve.attitude_modes.results import TUMBLING, ModeHypothesis

#: ``ln 8π²``: the volume of SO(3) in small-angle coordinates (rotation vectors).
LOG_SO3_VOLUME = math.log(8.0 * math.pi**2)
#: Precision (rad⁻²) that bounds the Laplace determinant of an attitude along directions
#: the data do not see: a 1σ of π rad, the width of SO(3).
ATTITUDE_PRECISION = 1.0 / math.pi**2


def log_evidence(chi2: float, log_prior: float, hessian: np.ndarray) -> float:
    """Laplace ``ln Z = −½ χ² + ln p(θ̂) + (k/2) ln 2π − ½ ln det H`` (MacKay 2003,
    "Information Theory, Inference, and Learning Algorithms", ch. 28), ``H = JᵀJ + P``.

    Parameters
    ----------
    chi2 : float
        Data ``χ²`` at the best fit.
    log_prior : float
        ``ln p(θ̂)``, the prior density at the best fit (in the units of ``θ``).
    hessian : (k, k) numpy.ndarray
        ``JᵀJ + P`` (whitened Jacobian, prior precision).

    Returns
    -------
    float
        ``ln Z`` without the constant ``−½ Σ ln 2πσ²``; ``−inf`` when ``H`` is not
        positive definite.
    """
    sign, log_det = np.linalg.slogdet(hessian)
    if sign <= 0:
        return -math.inf
    return -0.5 * chi2 + log_prior + 0.5 * len(hessian) * math.log(2 * math.pi) - 0.5 * log_det


def offset_log_prior(delta: np.ndarray, prior_sigma: float) -> float:
    """``ln`` of the isotropic normal prior (``prior_sigma`` rad per axis) at the offset
    ``delta`` (rad, small-angle rotation vector)."""
    return -1.5 * math.log(2 * math.pi * prior_sigma**2) - 0.5 * float(delta @ delta) / (
        prior_sigma**2
    )


def attitude_log_prior(symmetry_order: int) -> float:
    """``ln`` of the uniform attitude density ``G/(8π²)`` (``G`` the order of the shape's
    rotational symmetry group, whose equivalent attitudes all fit alike)."""
    return math.log(symmetry_order) - LOG_SO3_VOLUME


def consistent(chi2: float, n: int, k: int, level: float) -> bool:
    """``χ²`` at most the ``level`` quantile of ``χ²`` with ``n − k`` degrees of freedom."""
    return bool(chi2 <= chi2_distribution.ppf(level, max(n - k, 1)))


def mode_probabilities(
    hypotheses: Sequence[ModeHypothesis], labels: Sequence[str], n_shapes: int
) -> dict[str, float]:
    """Set every hypothesis' posterior ``probability`` and return the modes' (summed over
    shapes).

    Prior: ½ for tumbling, ½ shared equally by the stabilised ``labels``, shapes equally
    likely. A stabilised hypothesis that fails the consistency test gets no weight (the
    tumbling one is never discarded); when every hypothesis is discarded the evidences
    alone decide.
    """
    log_prior = {TUMBLING: math.log(0.5)}
    log_prior.update({label: math.log(0.5 / len(labels)) for label in labels})
    log_shape = -math.log(n_shapes)
    scores = np.array(
        [
            h.log_evidence + log_prior[h.mode] + log_shape
            if (h.consistent or h.mode == TUMBLING)
            else -math.inf
            for h in hypotheses
        ]
    )
    if not np.isfinite(scores).any():
        scores = np.array([h.log_evidence for h in hypotheses])
    weights = np.exp(scores - scores.max())
    weights /= weights.sum()
    probabilities: dict[str, float] = {}
    for h, w in zip(hypotheses, weights, strict=True):
        h.probability = float(w)
        probabilities[h.mode] = probabilities.get(h.mode, 0.0) + h.probability
    return probabilities
