"""Rotation-period search: multi-harmonic Fourier periodogram, aliases, sidereal correction.

Gou et al. 2016, sec. 2.1 (phase-angle methods): the light curve's periodic content gives the
rotation period. Each light curve ``c`` (one night, its own zero point) is modelled as ::

    m(t) = m_c + Σ_{k=1..K} [a_k cos(k ψ(t)) + b_k sin(k ψ(t))],     ψ(t) = 2π f t

(Harris et al. 1989, Icarus 77, 171, eq. 1), a weighted linear least-squares problem at
every trial frequency f; χ²(f) is the periodogram. The offsets ``m_c`` make relative light
curves from many nights usable together. The order K (2–6) is chosen by the Bayesian
information criterion ``χ² + p ln N``.

* Aliases are reported, not hidden: half and double the period (a double-peaked asteroid
  curve fits almost as well at P/2), and the daily aliases ``f ± k/day`` of nightly
  sampling, each with its χ² and Δχ².
* The 1σ period error comes from the curvature of χ²(f) at the minimum,
  ``σ_f² = 2 χ²_ν / (∂²χ²/∂f²)`` (Δχ² = χ²_ν), i.e. ``σ_P = σ_f P²``.
* Lomb–Scargle (astropy) gives a quick first look (one harmonic).
* Synodic → sidereal: the epoch method's correction. The light curve follows the body's
  rotation relative to the phase-angle bisector (PAB), so the observed (synodic) phase is
  ``ω t − Λ(t)`` with Λ the PAB longitude about the pole; ``1/P_sid = 1/P_syn + Λ̇/2π``.
  With a pole given, the periodogram uses ``ψ(t) = 2π f t − Λ(t)`` and scans the
  sidereal frequency directly over data from many apparitions.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from filters.attitude import rotate
from lightcurve.analysis.fourier_design import FourierDesign
from lightcurve.analysis.spin import pole_quaternion
from lightcurve.io.observations import Observations
from lightcurve.sky.geometry import phase_angle_bisector

__all__ = [
    "FourierDesign",
    "PeriodResult",
    "StackedLightCurves",
    "fourier_chi2",
    "lomb_scargle_period",
    "pab_longitude",
    "pab_rate",
    "period_search",
    "synodic_to_sidereal",
]

SECONDS_PER_DAY = 86400.0
SIDEREAL_DAY_S = 86164.0905
MAX_FREQUENCIES = 400_000
#: Trial frequencies between two progress reports (a multiple of the solver's 256-chunk).
_PROGRESS_BLOCK = 8192


@dataclass
class PeriodResult:
    """Outcome of :func:`period_search`.

    Attributes
    ----------
    period_h, sigma_h : float
        Best period and its 1σ error (h).
    order : int
        Harmonic order K of the best model.
    chi2 : float
        χ² of the best model.
    aliases : list of dict
        ``period_h``, ``chi2``, ``delta_chi2``, ``delta_bic``, ``order`` and ``kind``
        (``"half"``, ``"double"``, ``"daily+k"``, ``"peak"``), sorted by χ².
    periods_h, chi2_curve : (n,) float
        The periodogram of the chosen order.
    lomb_scargle_h : float
        Lomb–Scargle best period (first look).
    sidereal : bool
        Whether the scan was PAB-corrected (sidereal).
    double_peaked_h : float
        The shortest of P/2, P and 2P that fits within 10 % of the best χ² while its
        half-period fits clearly worse (ΔBIC > 10): the period whose two half-cycles
        differ, the usual reading of an elongated body's double-peaked light curve (NaN if
        none).
    """

    period_h: float
    sigma_h: float
    order: int
    chi2: float
    n_points: int
    aliases: list[dict] = field(default_factory=list)
    periods_h: np.ndarray = field(default_factory=lambda: np.zeros(0))
    chi2_curve: np.ndarray = field(default_factory=lambda: np.zeros(0))
    lomb_scargle_h: float = float("nan")
    sidereal: bool = False
    double_peaked_h: float = float("nan")

    def summary(self) -> dict:
        """JSON-ready: ``period_h``, ``sigma_h``, ``aliases`` and the details."""
        return {
            "period_h": self.period_h,
            "sigma_h": self.sigma_h,
            "aliases": self.aliases,
            "order": self.order,
            "chi2": self.chi2,
            "reduced_chi2": self.chi2 / max(self.n_points - self.n_parameters, 1),
            "n_points": self.n_points,
            "lomb_scargle_period_h": self.lomb_scargle_h,
            "sidereal": self.sidereal,
            "double_peaked_period_h": None
            if math.isnan(self.double_peaked_h)
            else self.double_peaked_h,
        }

    @property
    def n_parameters(self) -> int:
        return 2 * self.order + 1


@dataclass(frozen=True)
class StackedLightCurves:
    """The points of one or more observation files, stacked for a period search.

    Attributes
    ----------
    mjd : (N,) float
    times : (N,) float
        Seconds since the first epoch.
    magnitudes, sigma : (N,) float
        ``mag`` and its 1σ error.
    curve : (N,) int
        Light-curve index (each file's ``lightcurve_id`` kept apart).
    sun, observer : (N, 3) float
        Object → Sun and object → observer (inertial, km).
    """

    mjd: np.ndarray
    times: np.ndarray
    magnitudes: np.ndarray
    sigma: np.ndarray
    curve: np.ndarray
    sun: np.ndarray
    observer: np.ndarray

    @classmethod
    def of(cls, observations: Observations | Sequence[Observations]) -> StackedLightCurves:
        """Stack one file or a sequence of files."""
        obs_list = [observations] if isinstance(observations, Observations) else list(observations)
        mjd = np.concatenate([o.mjd for o in obs_list])
        return cls(
            mjd=mjd,
            times=(mjd - mjd.min()) * SECONDS_PER_DAY,
            magnitudes=np.concatenate([o.magnitudes for o in obs_list]),
            sigma=np.concatenate([o.magnitude_errors for o in obs_list]),
            curve=np.concatenate([o.lightcurve_ids + 100_000 * i for i, o in enumerate(obs_list)]),
            sun=np.concatenate([o.sun_vectors for o in obs_list]),
            observer=np.concatenate([o.observer_vectors for o in obs_list]),
        )


def pab_longitude(sun: np.ndarray, observer: np.ndarray, pole: tuple[float, float]) -> np.ndarray:
    """Longitude Λ (rad) of the phase-angle bisector about a pole, measured in the pole's
    equatorial frame ``R_y(90° − β) R_z(λ)`` (:mod:`lightcurve.analysis.spin`).

    Parameters
    ----------
    sun, observer : (n, 3) float
        Object → Sun and object → observer vectors (inertial).
    pole : (λ, β)
        Pole longitude and latitude (rad) in the same inertial frame.

    Returns
    -------
    (n,) float
        In ``(−π, π]``.
    """
    h = phase_angle_bisector(np.asarray(sun, float), np.asarray(observer, float))
    in_pole_frame = np.asarray(rotate(pole_quaternion(pole[0], pole[1]), h))
    return np.arctan2(in_pole_frame[:, 1], in_pole_frame[:, 0])


def pab_rate(
    mjd: np.ndarray, sun: np.ndarray, observer: np.ndarray, pole: tuple[float, float]
) -> float:
    """Mean rate Λ̇ (rad/h) of the PAB longitude about a pole over the epochs: the
    least-squares slope of the unwrapped :func:`pab_longitude` (0 for a single epoch).

    Parameters
    ----------
    mjd : (n,) float
    sun, observer : (n, 3) float
        Object → Sun and object → observer vectors (inertial).
    pole : (λ, β)
        Pole (rad); a positive rotation about it.
    """
    order = np.argsort(mjd)
    longitude = np.unwrap(pab_longitude(sun[order], observer[order], pole))
    hours = (np.asarray(mjd)[order] - mjd[order][0]) * 24.0
    return float(np.polyfit(hours, longitude, 1)[0]) if len(hours) > 1 else 0.0


def synodic_to_sidereal(
    period_h: float,
    mjd: np.ndarray,
    sun: np.ndarray,
    observer: np.ndarray,
    pole: tuple[float, float],
) -> float:
    """Sidereal period from a synodic one: ``1/P_sid = 1/P_syn + Λ̇/2π`` (:func:`pab_rate`).

    Parameters
    ----------
    period_h : float
        Synodic period (h).
    mjd : (n,) float
    sun, observer : (n, 3) float
        Object → Sun and object → observer vectors (inertial).
    pole : (λ, β)
        Pole (rad); a positive rotation about it.

    Returns
    -------
    float
        Sidereal period (h).
    """
    return 1.0 / (1.0 / period_h + pab_rate(mjd, sun, observer, pole) / (2 * math.pi))


def fourier_chi2(
    times: np.ndarray,
    values: np.ndarray,
    sigma: np.ndarray,
    curve: np.ndarray,
    frequencies: np.ndarray,
    *,
    order: int,
    phase_offset: np.ndarray | None = None,
    chunk: int = 256,
) -> np.ndarray:
    """χ² of the K-harmonic Fourier model with per-curve offsets at each trial frequency.

    Parameters
    ----------
    times : (N,) float
        Seconds (any origin).
    values : (N,) float
        Magnitudes.
    sigma : (N,) float
        1σ errors (> 0).
    curve : (N,) int
        Light-curve index of each point; every curve has its own offset.
    frequencies : (n,) float
        Trial rotation frequencies (Hz).
    order : int
        Harmonic order K ≥ 1.
    phase_offset : (N,) float, optional
        Subtracted from the phase ``2π f t`` (the PAB longitude for sidereal scans).
    chunk : int
        Frequencies per vectorised block.

    Returns
    -------
    (n,) float
    """
    design = FourierDesign(times, values, sigma, curve, phase_offset)
    frequencies = np.atleast_1d(np.asarray(frequencies, float))
    return np.concatenate(
        [
            design.solve(frequencies[i : i + chunk], order)[1]
            for i in range(0, len(frequencies), chunk)
        ]
    )


def lomb_scargle_period(
    times: np.ndarray, values: np.ndarray, sigma: np.ndarray, curve, frequencies
) -> float:
    """Best period (s) of the astropy Lomb–Scargle periodogram of curve-demeaned data.

    One harmonic only: a double-peaked light curve shows at half its period.
    """
    from astropy.timeseries import LombScargle

    _, index = np.unique(curve, return_inverse=True)
    w = 1.0 / np.asarray(sigma) ** 2
    means = np.bincount(index, w * values) / np.bincount(index, w)
    power = LombScargle(times, values - means[index], sigma).power(frequencies)
    return float(1.0 / frequencies[int(np.argmax(power))])


def _parabola_minimum(f: np.ndarray, c: np.ndarray) -> tuple[float, float, float]:
    """Vertex (f, χ²) and curvature ∂²χ²/∂f² of the parabola through three points; the
    vertex is kept within the points' span."""
    a, b, c0 = np.polyfit(f - f[1], c, 2)
    if a <= 0:
        return float(f[1]), float(c[1]), 0.0
    vertex = float(np.clip(-b / (2 * a), f[0] - f[1], f[2] - f[1]))
    return float(f[1] + vertex), float(np.polyval([a, b, c0], vertex)), float(2 * a)


def period_search(
    observations: Observations | Sequence[Observations],
    period_range_h: tuple[float, float] | None = None,
    *,
    orders: Sequence[int] = (2, 3, 4, 5, 6),
    oversample: float = 10.0,
    pole: tuple[float, float] | None = None,
    n_peaks: int = 5,
    trend_degree: int = 0,
    progress: Callable[[int, int], None] | None = None,
) -> PeriodResult:
    """Search the rotation period of one or more observation files.

    Parameters
    ----------
    observations : Observations or sequence of them
        Magnitudes with ``mag_err``; ``lightcurve_id`` separates nights (each file's curves
        are kept apart).
    period_range_h : (float, float), optional
        Trial periods (h); default from four times the median sampling interval (at least
        1 s) to the whole time span.
    orders : sequence of int
        Harmonic orders tried (BIC chooses).
    oversample : float
        Frequency step ``1/(oversample · T)`` with T the time span.
    pole : (λ, β), optional
        Spin axis (rad, same inertial frame as the geometry): scan the sidereal period with
        the PAB-corrected phase.
    n_peaks : int
        Other periodogram minima reported besides the structural aliases.
    trend_degree : int
        Degree of each curve's Legendre polynomial in time (0: a zero point only), the slow
        change of the mean brightness with the geometry (:class:`FourierDesign`).
    progress : callable, optional
        Called as ``progress(trials_done, trials_total)`` while the χ² curves are computed
        (one trial per frequency and harmonic order).

    Returns
    -------
    PeriodResult

    Raises
    ------
    ValueError
        Bad range, too few points, or a frequency grid above 400 000 trials (narrow the
        range: a long time span needs a fine grid).
    """
    data = StackedLightCurves.of(observations)
    times, mags, sigma, curve = data.times, data.magnitudes, data.sigma, data.curve
    sun, observer = data.sun, data.observer
    span = float(times.max() - times.min())
    if len(times) < 2 * max(orders) + 3 or span <= 0:
        raise ValueError(f"too few points ({len(times)}) for a period search")
    if period_range_h is None:
        step = np.median(np.diff(np.sort(times)))
        period_range_h = (max(4 * float(step), 1.0) / 3600.0, span / 3600.0)
    low, high = sorted(float(v) for v in period_range_h)
    if not (low > 0 and high > low):
        raise ValueError(f"period range must be 0 < A < B hours, got {period_range_h}")
    f_min, f_max = 1.0 / (high * 3600.0), 1.0 / (low * 3600.0)
    step = 1.0 / (oversample * span)
    count = math.ceil((f_max - f_min) / step) + 1
    if count < 3:  # the refinement around the best trial would leave the range
        raise ValueError(
            f"the period range {low:g}-{high:g} h is narrower than the periodogram's resolution "
            f"over a {span / 3600:.3g}-h span (trial frequencies {step * 3600:.3g} per hour "
            "apart): widen --range or use a longer light curve"
        )
    if count > MAX_FREQUENCIES:
        raise ValueError(
            f"the period range {low}-{high} h needs {count} trial frequencies over a "
            f"{span / 86400:.1f}-day span (limit {MAX_FREQUENCIES}): narrow --range"
        )
    frequencies = np.linspace(f_min, f_max, count)
    offset = None if pole is None else pab_longitude(sun, observer, pole)

    design = FourierDesign(times, mags, sigma, curve, offset, trend_degree=trend_degree)

    def chi2(freqs: np.ndarray, order: int) -> np.ndarray:
        freqs = np.atleast_1d(freqs)
        return np.concatenate(
            [design.solve(freqs[i : i + 256], order)[1] for i in range(0, len(freqs), 256)]
        )

    n_nuisance = design.n_nuisance
    n = len(times)

    def bic(c: float, order: int) -> float:
        return c + (2 * order + n_nuisance + 1) * math.log(n)

    curves = {}
    for done, order in enumerate(orders):
        blocks = []
        for i in range(0, len(frequencies), _PROGRESS_BLOCK):
            blocks.append(chi2(frequencies[i : i + _PROGRESS_BLOCK], order))
            if progress is not None:
                trials = done * len(frequencies) + min(i + _PROGRESS_BLOCK, len(frequencies))
                progress(trials, len(orders) * len(frequencies))
        curves[order] = np.concatenate(blocks)

    def refine(f0: float, order: int) -> tuple[float, float, float]:
        """Local minimum of χ²(f) near f0 (parabola through a fine grid's best triple)."""
        fine = f0 + np.linspace(-step, step, 21)
        fine = fine[fine > 0]
        values = chi2(fine, order)
        i = int(np.clip(np.argmin(values), 1, len(fine) - 2))
        return _parabola_minimum(fine[i - 1 : i + 2], values[i - 1 : i + 2])

    # Best (frequency, order) by BIC, then its structural aliases judged by BIC as well.
    candidates = []
    for order, c in curves.items():
        f0, c0, _ = refine(frequencies[int(np.argmin(c))], order)
        candidates.append((bic(c0, order), f0, order))
    f_best = min(candidates)[1]

    def best_order_at(f0: float) -> tuple[float, float, int, float]:
        """(BIC, f, order, χ²) of the best order for a local minimum near f0."""
        options = []
        for order in orders:
            f1, c1, _ = refine(f0, order)
            options.append((bic(c1, order), f1, order, c1))
        return min(options)

    entries = {"best": best_order_at(f_best)}
    for kind, factor in (("half", 2.0), ("double", 0.5)):
        if f_min / 1.5 < f_best * factor < f_max * 1.5:
            entries[kind] = best_order_at(f_best * factor)
    for k in (-2, -1, 1, 2):
        alias = f_best + k / SIDEREAL_DAY_S
        if span > 0.5 * SECONDS_PER_DAY and f_min <= alias <= f_max:
            entries[f"daily{k:+d}"] = best_order_at(alias)
    # The chosen period: the lowest BIC among the structural candidates.
    kind_best = min(
        ("best", "half", "double"), key=lambda k: entries[k][0] if k in entries else math.inf
    )
    b0, f0, order0, c0 = entries[kind_best]
    _, _, curvature = refine(f0, order0)
    reduced = max(c0 / max(n - 2 * order0 - n_nuisance, 1), 1.0)
    sigma_f = math.sqrt(2.0 * reduced / curvature) if curvature > 0 else float("inf")
    period_h = 1.0 / f0 / 3600.0
    sigma_h = sigma_f / f0**2 / 3600.0

    # Other deep minima of the chosen order's periodogram.
    c = curves[order0]
    is_min = np.r_[False, (c[1:-1] <= c[:-2]) & (c[1:-1] <= c[2:]), False]
    peaks = np.flatnonzero(is_min)
    peaks = peaks[np.argsort(c[peaks])]
    aliases = []
    for kind, (b, f, order, cc) in entries.items():
        if kind == kind_best:
            continue
        label = kind if kind.startswith("daily") else _ratio_name(f0 / f)
        aliases.append(_alias(f, cc, c0, b - b0, order, label))
    for index in peaks:
        f = frequencies[index]
        known = [1 / (a["period_h"] * 3600.0) for a in aliases] + [f0]
        if all(abs(f - g) > 2 * step for g in known):
            aliases.append(_alias(f, c[index], c0, bic(c[index], order0) - b0, order0, "peak"))
        if sum(a["kind"] == "peak" for a in aliases) >= n_peaks:
            break
    aliases.sort(key=lambda a: a["chi2"])
    # The double-peaked reading: the shortest of P/2, P, 2P that fits within 10 % of the
    # best χ² while its own half fits clearly worse (ΔBIC > 10).
    ladder = [best_order_at(f0 * factor) for factor in (4.0, 2.0)]
    ladder += [entries[kind_best], best_order_at(f0 * 0.5)]
    double_peaked = float("nan")
    for shorter, candidate in itertools.pairwise(ladder):
        if shorter[0] - candidate[0] > 10.0 and candidate[3] <= 1.1 * c0:
            double_peaked = 1.0 / candidate[1] / 3600.0
            break
    ls = lomb_scargle_period(times, mags, sigma, curve, frequencies) / 3600.0
    return PeriodResult(
        period_h=period_h,
        sigma_h=sigma_h,
        order=order0,
        chi2=c0,
        n_points=n,
        aliases=aliases,
        periods_h=1.0 / frequencies / 3600.0,
        chi2_curve=c,
        lomb_scargle_h=ls,
        sidereal=pole is not None,
        double_peaked_h=double_peaked,
    )


def _ratio_name(ratio: float) -> str:
    """Name of a period ratio P_alias/P: ``half``, ``double``, or ``x<ratio>``."""
    for value, name in ((0.5, "half"), (2.0, "double"), (0.25, "quarter"), (4.0, "quadruple")):
        if abs(ratio - value) < 0.02 * value:
            return name
    return f"x{ratio:.3g}"


def _alias(
    f: float, chi2: float, chi2_best: float, delta_bic: float, order: int, kind: str
) -> dict:
    return {
        "period_h": 1.0 / f / 3600.0,
        "chi2": float(chi2),
        "delta_chi2": float(chi2 - chi2_best),
        "delta_bic": float(delta_bic),
        "order": int(order),
        "kind": kind,
    }
