"""Carrier-smoothed code: the Hatch filter on between-receiver single differences.

Hatch (1982), *The synergism of GPS code and carrier measurements* (Proc. 3rd International
Geodetic Symposium on Satellite Doppler Positioning, pp. 1213–1231): the carrier phase
``Φ = ρ + B + ε_Φ`` (m) follows the range to millimetres but carries an unknown constant
``B`` (ambiguity, initial phases); the code ``P = ρ + ε_P`` is unbiased but noisy. Their
difference ``P − Φ = −B + ε_P − ε_Φ`` is a constant plus noise, so averaging it and adding
back the current phase gives an unbiased, smoothed code, without any integer ambiguity:

``B̂_k = α_k (P_k − Φ_k) + (1 − α_k) B̂_{k−1}``,   ``P̄_k = Φ_k + B̂_k``,
``α_k = 1 / min(n_k, N)``,

with ``n_k`` the epochs since the channel's (re)start and ``N = window / Δt`` the smoothing
length. Up to ``N`` epochs ``B̂_k`` is the plain mean of the code-minus-carrier
differences; afterwards it is an exponential average (which bounds code–carrier divergence,
e.g. ionospheric, to the window).

**Variance model** (white code and phase noise of variances ``σ_P²``, ``σ_Φ²``, no
multipath): with ``β_k = B̂_k + B`` the error of the mean,

``V_k = var β_k = α_k² (σ_P² + σ_Φ²) + (1 − α_k)² V_{k−1}``,
``var(P̄_k − ρ_k) = α_k² σ_P² + (1 − α_k)² (σ_Φ² + V_{k−1})``,

exact for any sequence ``α_k``. Up to ``N`` epochs it is ``σ_P² / n + σ_Φ² (1 − 1/n)``: the
code variance shrinks as ``1/n``; in the exponential regime it levels off at about
``σ_P² / (2N − 1)``. The smoothed errors of one channel are correlated from epoch to epoch
(over about ``N`` epochs) and those of different channels are independent.

Each channel here is one satellite's between-receiver single difference (rover − base); its
code and carrier share the receiver clock difference, which cancels in ``P − Φ``. Smoothing
single rather than double differences makes the channels independent of the reference
satellite: a change of reference needs no reset, and a cycle slip or a loss of lock restarts
only the satellite concerned.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["CarrierSmoothing"]


class CarrierSmoothing:
    """Hatch filters of single differences, one channel per satellite (keyed by PRN).

    Parameters
    ----------
    window : float
        Smoothing window (s); ``0`` turns smoothing off (the output is the raw code).

    Examples
    --------
    >>> smoothing = CarrierSmoothing(100.0)
    >>> code, variance, epochs = smoothing.update(
    ...     t, prns, sd_code, sd_phase, continuous,
    ...     code_variance=code_variance, phase_variance=phase_variance)
    """

    def __init__(self, window: float) -> None:
        if not window >= 0:
            raise ValueError(f"smoothing window must be >= 0 s, got {window}")
        self.window = float(window)
        self.reset()

    def reset(self) -> None:
        """Restart every channel."""
        self.prn = np.zeros(0, dtype=int)
        self.bias = np.zeros(0)  # B̂: smoothed code minus carrier (m)
        self.bias_variance = np.zeros(0)  # V (m²)
        self.epochs = np.zeros(0, dtype=int)
        self.time: float | None = None

    def update(
        self,
        t: float,
        prn: Any,
        code: Any,
        phase: Any,
        continuous: Any,
        *,
        code_variance: float,
        phase_variance: float,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Smooth one epoch; channels not in ``prn`` are dropped.

        Parameters
        ----------
        t : float
            Epoch (s).
        prn : (m,) array_like of int
            Satellites of the epoch.
        code, phase : (m,) array_like
            Single-difference code and carrier phase, both in metres.
        continuous : (m,) array_like of bool
            Whether each satellite's carrier is continuous since the previous epoch (tracked
            by both receivers then and now, no cycle slip); ``False`` restarts its channel.
        code_variance, phase_variance : float
            Variances of the single-difference code and phase (m²).

        Returns
        -------
        smoothed : (m,) numpy.ndarray
            Carrier-smoothed single-difference code (m).
        variance : (m,) numpy.ndarray
            Its error variance (m²) from the model above.
        epochs : (m,) numpy.ndarray of int
            Epochs since each channel's (re)start, this one included (1 right after a
            restart); the average spans ``min(epochs, window / Δt)`` of them.
        """
        prn = np.asarray(prn, dtype=int)
        p = np.asarray(code, dtype=float)
        phi = np.asarray(phase, dtype=float)
        if self.time is not None and not t > self.time:
            raise ValueError(f"epochs must increase: {t} s after {self.time} s")
        # Carry the state of the satellites that have one and whose carrier is continuous.
        _, old, new = np.intersect1d(self.prn, prn, assume_unique=True, return_indices=True)
        epochs = np.zeros(len(prn), dtype=int)
        bias = np.zeros(len(prn))
        bias_variance = np.zeros(len(prn))
        epochs[new], bias[new], bias_variance[new] = (
            self.epochs[old],
            self.bias[old],
            self.bias_variance[old],
        )
        restart = ~np.asarray(continuous, dtype=bool) | (epochs == 0)
        epochs[restart], bias_variance[restart] = 0, 0.0
        epochs += 1
        length = 1.0 if self.time is None else max(1.0, self.window / (t - self.time))
        alpha = 1.0 / np.minimum(epochs, length)
        variance = alpha**2 * code_variance + (1.0 - alpha) ** 2 * (phase_variance + bias_variance)
        bias = alpha * (p - phi) + (1.0 - alpha) * bias
        bias_variance = (
            alpha**2 * (code_variance + phase_variance) + (1.0 - alpha) ** 2 * bias_variance
        )
        self.prn, self.bias, self.bias_variance, self.epochs = (
            prn.copy(),
            bias,
            bias_variance,
            epochs,
        )
        self.time = float(t)
        return phi + bias, variance, epochs
