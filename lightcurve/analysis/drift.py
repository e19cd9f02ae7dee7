"""Spin-rate evolution: a period's drift over nights or months.

Each file (night) gets its own period search (:func:`~lightcurve.analysis.period.
period_search`, or the two-period :func:`~lightcurve.analysis.tumbling.tumbling_search`
for a tumbler), which gives ``P_n ± σ_n`` at the night's mean epoch ``t_n``. The drift is
the weighted least-squares polynomial ::

    P(t) = P_0 + Ṗ (t − t̄) [+ ½ P̈ (t − t̄)²]

with ``t̄`` the weighted mean epoch (where P_0 and Ṗ are uncorrelated), each night weighted
by ``1/(σ_n² + s_n²)``, ``s_n`` its systematic (below). The covariance is ``(AᵀWA)⁻¹``
scaled by the reduced χ² when that exceeds 1 (nights scattering more than their errors
say: the Birge ratio, Birge 1932, Phys. Rev. 40, 207), plus the nights' common systematic
(:func:`fit_drift`). This is the spin-down monitoring of e.g. Hall et al. (2007, AMOS) on
IMAGE: a series of nightly periods and a trend through them; no cycle count across the
gaps between nights is needed, so daily aliases of a coherent multi-night fit cannot
corrupt it.

The sidereal periods of a known pole (``night_periods(..., pole=...)``) carry the error of
the phase-angle-bisector (PAB) approximation, of the size ``s_n`` of the night's
correction. Where the correction changes fast from night to night (a pole near the
bisector's path) it is a night's own error, and the weights keep such nights from pulling
the line. Mostly, though, it follows the geometry, which moves little from one night to
the next: a smooth curve through the season, common to neighbouring nights, which no
weighting averages down (it leaves the reduced χ² below 1 and still tilts the line).
``fit_drift`` therefore also counts it as the polynomial ``S Σ_k z_k ((t − t̄)/T)^k`` of
the fit's degree, ``z_k ~ N(0, 1)``, over the span T of the nights, S the weighted mean
``s_n``. The line cannot tell such a curve from a drift, so it adds ``(S k!/T^k)²`` to the
variance of the k-th coefficient: the systematic may change by its own size over the
nights.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from lightcurve.analysis.period import pab_rate, period_search
from lightcurve.analysis.tumbling import tumbling_search
from lightcurve.io.observations import Observations

__all__ = ["DriftResult", "NightPeriod", "fit_drift", "night_periods", "period_drift"]

SECONDS_PER_DAY = 86400.0
#: 1σ of the nights' sidereal periods from the phase-angle-bisector approximation, as a
#: fraction of each night's synodic–sidereal correction ``P² |Λ̇| / 2π``: a systematic
#: common to the nights (module docstring).
PAB_SYSTEMATIC = 1.0


@dataclass(frozen=True)
class NightPeriod:
    """The period of one file: ``mjd`` (mean epoch), ``period_h`` and ``sigma_h`` (1σ of the
    fit), ``systematic_h`` (1σ of the geometry's effect, :func:`night_periods`, common to
    neighbouring nights; 0 when not estimated) and ``series`` (``"period"``, or
    ``"shorter"``/``"longer"`` of a two-period fit)."""

    file: str
    series: str
    mjd: float
    period_h: float
    sigma_h: float
    systematic_h: float = 0.0

    @property
    def total_sigma_h(self) -> float:
        """The fit's and the geometry's 1σ in quadrature (h): the night's weight in the drift
        fit and its error bar in plots."""
        return math.hypot(self.sigma_h, self.systematic_h)


@dataclass(frozen=True)
class DriftResult:
    """A drift fit to per-night periods.

    Attributes
    ----------
    series : str
        Which period (``"period"``, ``"shorter"``, ``"longer"``).
    reference_mjd : float
        ``t̄``.
    period_h, sigma_h : float
        ``P_0`` at ``t̄`` and its 1σ (h).
    period_derivative_s_per_day, derivative_sigma_s_per_day : float
        ``Ṗ`` and its 1σ (s/day).
    second_derivative_s_per_day2, second_derivative_sigma_s_per_day2 : float or None
        ``P̈`` and its 1σ (s/day²) of the quadratic fit (None for a linear one).
    reduced_chi2 : float
        Of the fit (NaN with as many nights as parameters).
    """

    series: str
    reference_mjd: float
    period_h: float
    sigma_h: float
    period_derivative_s_per_day: float
    derivative_sigma_s_per_day: float
    second_derivative_s_per_day2: float | None
    second_derivative_sigma_s_per_day2: float | None
    reduced_chi2: float

    def summary(self) -> dict:
        return {
            "series": self.series,
            "reference_mjd": self.reference_mjd,
            "period_h": self.period_h,
            "sigma_h": self.sigma_h,
            "period_derivative_s_per_day": {
                "value": self.period_derivative_s_per_day,
                "sigma": self.derivative_sigma_s_per_day,
            },
            "period_second_derivative_s_per_day2": None
            if self.second_derivative_s_per_day2 is None
            else {
                "value": self.second_derivative_s_per_day2,
                "sigma": self.second_derivative_sigma_s_per_day2,
            },
            "reduced_chi2": self.reduced_chi2,
        }


def fit_drift(nights: Sequence[NightPeriod], *, quadratic: bool = False) -> DriftResult:
    """Weighted polynomial fit of per-night periods (module docstring).

    The nights are weighted by their fits' and systematic σ in quadrature
    (:attr:`NightPeriod.total_sigma_h`). The systematic is also common to the nights: ``S``,
    the weighted mean of their ``systematic_h``, adds ``(S k!/T^k)²`` to the variance of the
    k-th coefficient (``P_0``, ``Ṗ``, ``P̈``), T the span of the nights.

    Parameters
    ----------
    nights : sequence of NightPeriod
        One series; at least 2 nights (3 for ``quadratic``) with finite, positive σ.
    quadratic : bool
        Fit ``P̈`` as well.

    Returns
    -------
    DriftResult

    Raises
    ------
    ValueError
        Too few nights, nights on one epoch, or a non-finite period or σ (naming the file).
    """
    degree = 2 if quadratic else 1
    if len(nights) < degree + 1:
        raise ValueError(
            f"a {'quadratic' if quadratic else 'linear'} drift needs at least {degree + 1} "
            f"files (nights), got {len(nights)}"
        )
    for night in nights:
        if not (math.isfinite(night.period_h) and math.isfinite(night.sigma_h)) or not (
            night.sigma_h > 0
        ):
            raise ValueError(
                f"{night.file}: the night's period {night.period_h} ± {night.sigma_h} h is not "
                "usable for a drift fit"
            )
    days = np.array([n.mjd for n in nights])
    period_s = np.array([n.period_h for n in nights]) * 3600.0
    sigma_s = np.array([n.total_sigma_h for n in nights]) * 3600.0
    w = 1.0 / sigma_s**2
    reference = float(np.sum(w * days) / np.sum(w))
    x = days - reference
    span = float(np.ptp(x))
    if span <= 0:
        raise ValueError("all files have the same epoch: a drift needs nights apart in time")
    design = np.column_stack([x**p / math.factorial(p) for p in range(degree + 1)])
    normal = design.T @ (design * w[:, None])
    covariance = np.linalg.inv(normal)
    coefficients = covariance @ (design.T @ (w * period_s))
    dof = len(nights) - degree - 1
    reduced = (
        float(np.sum(w * (period_s - design @ coefficients) ** 2) / dof) if dof > 0 else math.nan
    )
    if dof > 0 and reduced > 1.0:
        covariance = covariance * reduced
    systematic_s = float(np.sum(w * [n.systematic_h for n in nights]) / np.sum(w)) * 3600.0
    common = [systematic_s * math.factorial(k) / span**k for k in range(degree + 1)]
    sigma = np.sqrt(np.diag(covariance) + np.square(common))
    return DriftResult(
        series=nights[0].series,
        reference_mjd=reference,
        period_h=float(coefficients[0] / 3600.0),
        sigma_h=float(sigma[0] / 3600.0),
        period_derivative_s_per_day=float(coefficients[1]),
        derivative_sigma_s_per_day=float(sigma[1]),
        second_derivative_s_per_day2=float(coefficients[2]) if quadratic else None,
        second_derivative_sigma_s_per_day2=float(sigma[2]) if quadratic else None,
        reduced_chi2=reduced,
    )


def night_periods(
    observations: Sequence[Observations],
    period_range_h: tuple[float, float] | None = None,
    *,
    tumbling: bool = False,
    pole: tuple[float, float] | None = None,
) -> list[NightPeriod]:
    """The period (or the two periods) of each file.

    Parameters
    ----------
    observations : sequence of Observations
        One file per night (or per group of nights).
    period_range_h : (float, float), optional
        Trial periods (h); a narrow range around the expected period keeps every night on
        the same alias.
    tumbling : bool
        Fit two periods per night (:func:`~lightcurve.analysis.tumbling.tumbling_search`):
        the shorter and the longer each make a series.
    pole : (λ, β), optional
        Spin axis (rad, the files' inertial frame) of a principal-axis rotator: sidereal
        nightly periods (:func:`~lightcurve.analysis.period.period_search`), free of the
        synodic offset, which drifts with the geometry from night to night.

    Returns
    -------
    list of NightPeriod
        In file order (the two series interleaved for ``tumbling``).
    """
    out = []
    for obs in observations:
        mjd = float(np.mean(obs.mjd))
        name = str(obs.source)
        if tumbling:
            result = tumbling_search(obs, period_range_h, model_reading=False)
            for series, p, s in zip(
                ("shorter", "longer"), result.periods_h, result.sigmas_h, strict=True
            ):
                out.append(NightPeriod(name, series, mjd, float(p), float(s)))
        else:
            result = period_search(obs, period_range_h, pole=pole)
            systematic = 0.0
            if pole is not None:
                rate = pab_rate(obs.mjd, obs.sun_vectors, obs.observer_vectors, pole)
                systematic = PAB_SYSTEMATIC * result.period_h**2 * abs(rate) / (2 * math.pi)
            out.append(
                NightPeriod(name, "period", mjd, result.period_h, result.sigma_h, systematic)
            )
    return out


def period_drift(
    observations: Sequence[Observations],
    period_range_h: tuple[float, float] | None = None,
    *,
    quadratic: bool = False,
    tumbling: bool = False,
    pole: tuple[float, float] | None = None,
) -> tuple[list[NightPeriod], list[DriftResult]]:
    """Per-night periods and the drift of each series (module docstring).

    Parameters
    ----------
    observations : sequence of Observations
        One file per night.
    period_range_h : (float, float), optional
        Trial periods (h) of every night.
    quadratic : bool
        Fit the second derivative too.
    tumbling : bool
        Two periods per night, each series fitted.
    pole : (λ, β), optional
        Spin axis (rad) for sidereal nightly periods (:func:`night_periods`).

    Returns
    -------
    nights : list of NightPeriod
    drifts : list of DriftResult
        One per series.
    """
    nights = night_periods(observations, period_range_h, tumbling=tumbling, pole=pole)
    series = dict.fromkeys(n.series for n in nights)
    drifts = [
        fit_drift([n for n in nights if n.series == name], quadratic=quadratic) for name in series
    ]
    return nights, drifts
