"""Two-period analysis of tumbling (non-principal-axis) rotators.

A torque-free tumbler's brightness is a function of its precession angle φ and rotation
angle ψ about the angular momentum (:mod:`filters.attitude.torque_free_periods`), so its light
curve is quasi-periodic in two frequencies. It is fitted with the two-dimensional Fourier
series (Kaasalainen 2001, A&A 376, 302, eq. 9; Pravec et al. 2005, Icarus 173, 108,
eq. 1) ::

    m(t) = m_c + Σ_{(j,k)} [C_jk cos(2π(j f1 + k f2) t) + S_jk sin(2π(j f1 + k f2) t)]

over ``0 ≤ j ≤ m``, ``−m ≤ k ≤ m``, ``|j| + |k| ≤ m``, ``(j, k) ≠ (0, 0)`` and one of
``±(j, k)`` (:func:`two_period_combinations`), where ``m_c`` is, per light curve, a
Legendre polynomial of degree ``TREND_DEGREE`` in its scaled time (the mean brightness
follows range and phase angle over a night or a pass), and terms slower than
``MIN_SEPARATION_CYCLES`` per span are left out (they would duplicate it). At fixed
(f1, f2) the fit is linear (:class:`~lightcurve.analysis.period.FourierDesign`, batched
over trial pairs); the order m is chosen by the BIC ``χ² + p ln N``, ``p`` counting the
coefficients, the trend terms and the two frequencies.

The one-period rival has the same trend and three forms, all judged by the BIC: fixed
coefficients; coefficients that change within each curve as Legendre polynomials of degree
``MODULATION_DEGREE`` (the light curve's shape follows the aspect); and the latter with the
phase ``2π f t − Λ_p(t)``, Λ_p the phase-angle-bisector longitude about a trial pole p
(the synodic drift of a rotator's phase as the geometry moves: Harris et al. 1984, Icarus
57, 251; Pravec et al. 2005, sec. 2), over a lattice of trial poles
(:func:`~lightcurve.analysis.rotator_rival.rotator_bic`).

The search (:func:`tumbling_search`):

1. the single-period search (:func:`~lightcurve.analysis.period.period_search`, one order)
   gives the dominant frequency f0;
2. coarse scan: f1 over f0, f0/2, 2 f0 and the ``_EXTRA_FIRST`` next deepest one-period
   minima (and their halves; each once, to a grid step), leaving out minima whose harmonics
   up to the one-period scan's order pass the Nyquist frequency of the median cadence (on
   a regular cadence Δ, ``k f`` near ``1/Δ`` samples as the slow ``1/Δ − k f``: an alias of
   a real term, not a first frequency), f2 over the whole grid of step
   ``1/(oversample · T)`` within
   ``[f0/RATIO_SPAN, RATIO_SPAN · f0]`` and the period range, at order 2, on at most
   ``max_coarse_points`` points drawn at random (a fixed seed: irregular sampling has no
   aliases of the regular cadence, which a strided subset would fold into the band);
3. refinement: the best coarse pairs are taken to their local minima (Nelder–Mead) on the
   coarse points; each, with its unimodular re-bases ``(f1 ± f2, f2)``, ``(f1, f2 ± f1)``
   and halves (the same lattice of combinations written with other generators), is judged
   at every order by the BIC on all points; the winner is taken to its minimum on all
   points, where the Hessian ``H`` of χ² (central differences) gives the covariance
   ``2 χ²_ν H⁻¹`` of (f1, f2);
4. the verdict: **tumbling** when the two-period fit beats the one-period rival by
   ``ΔBIC = BIC₁ − BIC₂ > SIGNIFICANT_DELTA_BIC + 2 ln M`` (M the independent trial
   second frequencies, the band times T:
   :func:`~lightcurve.analysis.rotator_rival.search_penalty`) and the two frequencies are resolved
   (``|q f2 − p f1| ≥ MIN_SEPARATION_CYCLES / T`` for ``(p, q)`` in ``RESOLVED_RATIOS``)
   and not commensurate (``|q f2 − p f1| < COMMENSURATE_RESOLUTION / T`` for some
   ``p, q ≤ COMMENSURATE_MAX`` makes the second "period" a harmonic of a single one),
   and, where the phase angle or the bisector moves by more than 30° over the arc, not
   within ``MIN_SEPARATION_CYCLES / T`` of a ratio p:q ≤ 4 (a changing one-period light
   curve, :func:`~lightcurve.analysis.rotator_rival.geometry_explains_pair`).

Interpretation (``precession_period_h``, ``rotation_period_h``, ``mode``,
:func:`euler_reading`). Two generators of the same lattice of combination frequencies are
equally valid (``(f_φ, f_ψ)`` and ``(f_φ ± f_ψ, f_φ)`` fit the same light curve); the BIC
prefers the pair in which the power sits in the fewest low-order terms, and ``periods_h``
is that pair. Which is the precession is not determined by the light curve alone
(Kaasalainen 2001, sec. 3; Pravec et al. 2005, sec. 2). The reading used here: an elongated
body's brightness is dominated by the second harmonic of its spin about ``L``, at the rate
of φ + ψ, i.e. ``f_s = f_φ − f_ψ`` in a SAM (ψ turns backwards relative to φ there) and
``f_s = f_φ + f_ψ`` in a LAM; in the simulated tumblers the BIC's pair is mostly
``(f_s, f_ψ)`` in a SAM and ``(f_s, f_φ)`` in a LAM. A SAM always has ``P_φ < P_ψ/2``, a
LAM mostly ``P_φ < P_ψ`` (both checked over random states in the tests), which splits the
two readings at ``f_s = 2x`` (:func:`euler_reading`). This is a heuristic whose success
rate the benchmark measures, not a theorem; ``periods_h`` and ``combinations`` are the
model-free result. A tumbler's pair is read by a convex facet model instead
(:mod:`~lightcurve.analysis.tumbling_reading`) unless its two best readings are close.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from lightcurve.analysis.period import (
    PeriodResult,
    StackedLightCurves,
    period_search,
)
from lightcurve.analysis.rotator_rival import geometry_explains_pair, rotator_bic, search_penalty
from lightcurve.analysis.tumbling_reading import ConvexDecision, decide_reading
from lightcurve.analysis.two_period_series import (
    MIN_SEPARATION_CYCLES,
    TwoPeriodFit,
    chi2_hessian,
    local_minimum,
    two_period_combinations,
)
from lightcurve.io.observations import Observations

__all__ = [
    "COMMENSURATE_RESOLUTION",
    "SIGNIFICANT_DELTA_BIC",
    "TumblingResult",
    "euler_reading",
    "tumbling_search",
    "two_period_combinations",
]

#: ΔBIC (one-period minus two-period) above which the second frequency is significant
#: ("very strong" evidence, Kass & Raftery 1995, J. Am. Stat. Assoc. 90, 773).
SIGNIFICANT_DELTA_BIC = 10.0
#: Degree of each light curve's Legendre polynomial in time in both series: the slow change
#: of the mean brightness with range and phase angle over a night or a pass.
TREND_DEGREE = 3
#: Two frequencies with ``|q f2 − p f1| < COMMENSURATE_RESOLUTION / T`` (p, q ≤
#: ``COMMENSURATE_MAX``) are harmonics of one period, not two periods (T: the time span).
COMMENSURATE_RESOLUTION = 0.25
#: The ratios ``(p, q)`` of that test, ``|q f2 − p f1| ≥ MIN_SEPARATION_CYCLES / T``.
RESOLVED_RATIOS = ((1, 1), (1, 2), (2, 1))
#: Largest numerator and denominator of the commensurability test.
COMMENSURATE_MAX = 6
#: The second frequency is searched within this factor of the dominant one.
RATIO_SPAN = 8.0
#: The one-period minima (besides f0, f0/2, 2 f0) tried as the first frequency: the
#: dominant term of a tumbler (the second harmonic of its spin about ``L``) is often only
#: the one-period scan's fourth or fifth deepest minimum.
_EXTRA_FIRST = 4
#: Coarse pairs refined.
_REFINED = 3


@dataclass
class TumblingResult:
    """Outcome of :func:`tumbling_search`.

    Attributes
    ----------
    periods_h, sigmas_h : (2,) numpy.ndarray
        The two fundamental periods (h, shorter first) and their 1σ.
    order : int
        Order m of the best two-period series.
    chi2 : float
        Its χ².
    n_points : int
    delta_bic : float
        BIC of the best one-period fit minus that of the two-period fit (> 0: two periods
        are preferred).
    tumbling : bool
        The verdict (module docstring).
    commensurate : bool
        Whether the two frequencies are harmonics of one (``|q f2 − p f1|`` small).
    combinations : list of dict
        ``j``, ``k`` (of the shorter and the longer period), ``period_h`` of
        ``j f1 + k f2`` and ``amplitude_mag`` ``√(C² + S²)``, largest first.
    single : PeriodResult
        The one-period search.
    scan_periods_h : (n,) numpy.ndarray
        Trial second periods of the coarse scan.
    scan_first_h : (r,) numpy.ndarray
        First periods of the coarse scan.
    scan_chi2 : (r, n) numpy.ndarray
        Order-2 χ² of the coarse scan (on the coarse points).
    convex : ConvexDecision or None
        The convex model's reading of a tumbler's pair (None: not tumbling, or not run).
    """

    periods_h: np.ndarray
    sigmas_h: np.ndarray
    order: int
    chi2: float
    n_points: int
    delta_bic: float
    tumbling: bool
    commensurate: bool
    combinations: list[dict]
    single: PeriodResult
    scan_periods_h: np.ndarray = field(default_factory=lambda: np.zeros(0))
    scan_first_h: np.ndarray = field(default_factory=lambda: np.zeros(0))
    scan_chi2: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    convex: ConvexDecision | None = None

    @property
    def reading(self) -> dict:
        """The convex model's reading of the two periods, else :func:`euler_reading`."""
        if self.convex is not None and not self.convex.ambiguous:
            return {**self.convex.periods(self.periods_h, self.sigmas_h), "method": "convex"}
        return {**euler_reading(self.periods_h, self.sigmas_h, self.combinations), "method": "rule"}

    def summary(self) -> dict:
        """JSON-ready: the keys documented in ``docs/formats.md``."""
        reading = self.reading
        return {
            "tumbling": self.tumbling,
            "delta_bic": self.delta_bic,
            "periods_h": [
                {"period_h": float(p), "sigma_h": float(s)}
                for p, s in zip(self.periods_h, self.sigmas_h, strict=True)
            ],
            "precession_period_h": reading["precession_period_h"],
            "rotation_period_h": reading["rotation_period_h"],
            "mode": reading["mode"],
            "reading_method": reading["method"],
            "reading_delta_chi2": None if self.convex is None else self.convex.delta_chi2,
            "combinations": self.combinations,
            "two_period_order": self.order,
            "two_period_chi2": self.chi2,
            "commensurate": self.commensurate,
        }


def euler_reading(
    periods_h: Sequence[float], sigmas_h: Sequence[float], combinations: Sequence[dict]
) -> dict:
    """Precession and rotation periods and the mode implied by two fundamental periods
    (module docstring).

    The generator whose second harmonic ((2, 0) or (0, 2)) is the stronger is read as the
    body's spin about ``L``, ``f_s``; the other is ``x``. With ``f_s > 2x``: a SAM with
    ``f_ψ = x``, ``f_φ = f_s + x`` (``f_s = f_φ − f_ψ``). With ``x < f_s < 2x``: a LAM with
    ``f_φ = x``, ``f_ψ = f_s − x`` (``f_s = f_φ + f_ψ``). With ``x > f_s``: ``f_φ = x``,
    ``f_ψ = x − f_s``, a SAM when ``P_φ < P_ψ/2`` (every SAM has it), else undetermined.
    σ(f) of a sum adds the two frequency variances (their correlation ignored).

    Parameters
    ----------
    periods_h, sigmas_h : (2,) float
        The two periods (h) and their 1σ, in the order of the combinations' (j, k).
    combinations : sequence of dict
        ``j``, ``k`` and ``amplitude_mag`` of the series' terms.

    Returns
    -------
    dict
        ``precession_period_h``, ``rotation_period_h`` (each ``{"period_h", "sigma_h"}``)
        and ``mode``.
    """
    f = 1.0 / np.asarray(periods_h, float)
    sigma_f = np.asarray(sigmas_h, float) * f**2
    second = {(c["j"], c["k"]): c["amplitude_mag"] for c in combinations}
    spin = 0 if second.get((2, 0), 0.0) >= second.get((0, 2), 0.0) else 1
    f_s, x = f[spin], f[1 - spin]
    sigma_s, sigma_x = sigma_f[spin], sigma_f[1 - spin]
    both = math.hypot(sigma_s, sigma_x)
    if f_s > 2 * x:
        mode, (f_phi, s_phi), (f_psi, s_psi) = "SAM", (f_s + x, both), (x, sigma_x)
    elif f_s > x:
        mode, (f_phi, s_phi), (f_psi, s_psi) = "LAM", (x, sigma_x), (f_s - x, both)
    else:
        f_phi, s_phi, f_psi, s_psi = x, sigma_x, x - f_s, both
        mode = "SAM" if f_psi < 0.5 * f_phi else "undetermined"
    return {
        "precession_period_h": {"period_h": float(1.0 / f_phi), "sigma_h": float(s_phi / f_phi**2)},
        "rotation_period_h": {"period_h": float(1.0 / f_psi), "sigma_h": float(s_psi / f_psi**2)},
        "mode": mode,
    }


def _thinned(
    observations: Observations | Sequence[Observations], fraction: float
) -> list[Observations]:
    """A random ``fraction`` of the rows of each file (:func:`_subset`), in time order."""
    obs_list = [observations] if isinstance(observations, Observations) else list(observations)
    return [
        Observations(
            o.table.iloc[_subset(len(o), fraction)].reset_index(drop=True), o.meta, o.source
        )
        for o in obs_list
    ]


def _subset(n: int, fraction: float) -> np.ndarray:
    """Sorted indices of ``ceil(fraction · n)`` of ``n`` rows, drawn with the seed ``n``
    (the same rows on every call)."""
    size = math.ceil(fraction * n)
    return np.sort(np.random.default_rng(n).choice(n, size, replace=False))


def _rebases(pair: np.ndarray) -> list[np.ndarray]:
    """The pair and its unimodular re-bases and halves (module docstring)."""
    f1, f2 = pair
    options = [
        (f1, f2),
        (abs(f1 - f2), f2),
        (f1, abs(f2 - f1)),
        (f1 + f2, f2),
        (f1, f1 + f2),
        (f1 / 2, f2),
        (f1, f2 / 2),
    ]
    return [np.array(o) for o in options if min(o) > 0 and abs(o[0] - o[1]) > 1e-3 * max(o)]


def _commensurate(pair: np.ndarray, span_s: float) -> bool:
    f1, f2 = pair
    tolerance = COMMENSURATE_RESOLUTION / span_s
    return any(
        abs(q * f2 - p * f1) < tolerance
        for p in range(1, COMMENSURATE_MAX + 1)
        for q in range(1, COMMENSURATE_MAX + 1)
    )


def _admissible(pair: np.ndarray, span_s: float) -> bool:
    """Two frequencies that can be two periods: each apart from the other and from its
    double and half by ``MIN_SEPARATION_CYCLES / T`` (``|q f2 − p f1|`` for ``(p, q)`` in
    ``RESOLVED_RATIOS``), and not commensurate."""
    f1, f2 = pair
    return all(
        abs(q * f2 - p * f1) * span_s >= MIN_SEPARATION_CYCLES for p, q in RESOLVED_RATIOS
    ) and not _commensurate(pair, span_s)


def tumbling_search(
    observations: Observations | Sequence[Observations],
    period_range_h: tuple[float, float] | None = None,
    *,
    orders: Sequence[int] = (2, 3, 4, 5, 6),
    single_orders: Sequence[int] = (4,),
    oversample: float = 3.0,
    max_coarse_points: int = 2000,
    trend_degree: int = TREND_DEGREE,
    model_reading: bool = True,
    progress: Callable[[int, int], None] | None = None,
) -> TumblingResult:
    """Two-period (tumbling) analysis of one or more observation files (module docstring).

    Parameters
    ----------
    observations : Observations or sequence of them
        Magnitudes with ``mag_err``; each light curve has its own zero point.
    period_range_h : (float, float), optional
        Trial periods (h) of both searches; default from four sampling intervals (≥ 1 s) to
        half the time span (two cycles).
    orders : sequence of int
        Two-period orders m tried (BIC chooses).
    single_orders : sequence of int
        Harmonic orders of the one-period scan that gives the dominant frequency (one order
        keeps it fast; the one-period rival is judged at more,
        :func:`~lightcurve.analysis.rotator_rival.rotator_bic`).
    oversample : float
        Coarse-scan frequency step ``1/(oversample · T)``.
    max_coarse_points : int
        Points of the coarse scan (a seeded random subset); the refinement uses all.
    trend_degree : int
        Degree of each light curve's polynomial in time, in both series (module docstring).
    model_reading : bool
        Read a tumbler's pair by the convex model (:func:`decide_reading`).
    progress : callable, optional
        ``progress(rows_done, rows_total)`` over the coarse scan's rows.

    Returns
    -------
    TumblingResult

    Raises
    ------
    ValueError
        Too few points, a bad range, or an empty second-period grid.
    """
    data = StackedLightCurves.of(observations)
    span = float(data.times.max() - data.times.min())
    n = len(data.times)
    if n < 2 * len(two_period_combinations(max(orders))) + 5 or span <= 0:
        raise ValueError(f"too few points ({n}) for a two-period search of order {max(orders)}")
    if period_range_h is None:
        cadence = float(np.median(np.diff(np.sort(data.times))))
        period_range_h = (max(4 * cadence, 1.0) / 3600.0, span / 7200.0)
    fraction = min(1.0, max_coarse_points / n)
    single = period_search(
        _thinned(observations, fraction),
        period_range_h,
        orders=single_orders,
        oversample=oversample,
        trend_degree=trend_degree,
    )
    low, high = sorted(float(v) for v in period_range_h)
    f_min, f_max = 1.0 / (high * 3600.0), 1.0 / (low * 3600.0)
    f0 = 1.0 / (single.period_h * 3600.0)
    step = 1.0 / (oversample * span)
    lo, hi = max(f_min, f0 / RATIO_SPAN), min(f_max, f0 * RATIO_SPAN)
    second = np.arange(lo, hi + 0.5 * step, step)
    if len(second) < 3:
        raise ValueError(
            f"the second-period grid over {1 / hi / 3600:.3g}-{1 / lo / 3600:.3g} h is empty "
            "at this time span: widen the period range or use a longer light curve"
        )
    # One-period minima whose harmonics pass the Nyquist frequency of the median cadence are
    # the cadence's aliases of slower terms, not first frequencies of their own.
    nyquist = 0.5 / float(np.median(np.diff(np.sort(data.times))))
    peaks = [
        f
        for f in (1.0 / (a["period_h"] * 3600.0) for a in single.aliases if a["kind"] == "peak")
        if max(single_orders) * f < nyquist
    ]
    kept: list[float] = []
    for f in [f0, f0 / 2, 2 * f0, *(g for p in peaks[:_EXTRA_FIRST] for g in (p, p / 2))]:
        # A first frequency within a grid step of one already kept would repeat its row.
        if f_min <= f <= f_max and all(abs(f - g) > step for g in kept):
            kept.append(f)
    first = np.array(kept)
    coarse = TwoPeriodFit(data, trend_degree, _subset(n, fraction))
    scan = np.empty((len(first), len(second)))
    allowed = np.zeros(scan.shape, bool)
    for row, f1 in enumerate(first):
        pairs = np.column_stack([np.full(len(second), f1), second])
        scan[row] = coarse.chi2(pairs, min(orders))
        # A second frequency on (a harmonic of) the first adds nothing: keep it out.
        allowed[row] = [_admissible(p, span) for p in pairs]
        if progress is not None:
            progress(row + 1, len(first))
    # Starts among the admissible pairs (all pairs when none is: a one-period light curve).
    ranked = np.where(allowed, scan, np.inf) if allowed.any() else scan
    starts: list[np.ndarray] = []
    for flat in np.argsort(ranked, axis=None):
        row, col = np.unravel_index(int(flat), scan.shape)
        pair = np.array([first[row], second[col]])
        if np.isfinite(ranked[row, col]) and all(
            np.max(np.abs(pair - s)) > 2 * step for s in starts
        ):
            starts.append(pair)
        if len(starts) >= _REFINED:
            break
    # Local minima on the coarse points; every re-base of each (the same lattice, so the
    # same minimum) and order judged by BIC on all points; the winner refined there.
    full = TwoPeriodFit(data, trend_degree)
    # Admissible options first (when there are any), then by BIC.
    options = [
        (
            not _admissible(pair, span),
            full.bic(float(full.chi2(pair, order)[0]), order),
            order,
            pair,
        )
        for start in starts
        for order in orders
        for pair in _rebases(local_minimum(coarse, start, order, step, tolerance=1e-2))
        if f_min - step <= pair.min() and pair.max() <= f_max + step
    ]
    if not options:
        raise ValueError(
            f"no pair of trial periods within {low:g}-{high:g} h fits a two-period series over "
            f"a {span / 3600:.3g}-h span: widen the period range or use a longer light curve"
        )
    _, _, order, pair = min(options, key=lambda option: option[:2])
    pair = local_minimum(full, pair, order, 0.25 * step, tolerance=1e-4)
    h = 0.05 * step
    axes = [pair[d] + h * np.arange(-1, 2) for d in range(2)]
    stencil = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 2)
    local = full.chi2(stencil, order).reshape(3, 3)
    hessian = chi2_hessian(local, h)
    chi2 = float(local[1, 1])
    best_bic = full.bic(chi2, order)
    # f0 is the one-period search's own (in the range even where rounding puts it at the
    # edge); its half only where the range reaches it.
    single_bic = rotator_bic(
        data,
        [f0, *([f0 / 2] if f0 / 2 >= f_min else [])],
        step,
        trend_degree=trend_degree,
        orders=single_orders,
    )
    delta_bic = float(single_bic - best_bic)
    swap = bool(pair[0] < pair[1])
    pair = np.sort(pair)[::-1]  # higher frequency (shorter period) first
    reduced = max(chi2 / max(n - 2 * len(two_period_combinations(order)) - 3, 1), 1.0)
    try:
        covariance = 2.0 * reduced * np.linalg.inv(hessian)
        sigma_f = np.sqrt(np.clip(np.diag(covariance), 0.0, None))
    except np.linalg.LinAlgError:
        sigma_f = np.full(2, math.inf)
    if swap:
        sigma_f = sigma_f[::-1]
    periods_h = 1.0 / pair / 3600.0
    sigmas_h = sigma_f / pair**2 / 3600.0
    commensurate = _commensurate(pair, span)
    coefficients = full.coefficients(pair, order)
    combos = two_period_combinations(order)
    amplitude = np.hypot(coefficients[: len(combos)], coefficients[len(combos) :])
    combinations = [
        {
            "j": int(combos[i, 0]),
            "k": int(combos[i, 1]),
            "period_h": float(1.0 / abs(combos[i] @ pair) / 3600.0)
            if combos[i] @ pair != 0
            else None,
            "amplitude_mag": float(amplitude[i]),
        }
        for i in np.argsort(-amplitude)[:10]
    ]
    result = TumblingResult(
        periods_h=periods_h,
        sigmas_h=sigmas_h,
        order=order,
        chi2=chi2,
        n_points=n,
        delta_bic=delta_bic,
        tumbling=bool(
            # The second frequency was searched over len(second) / oversample independent
            # trials.
            delta_bic > SIGNIFICANT_DELTA_BIC + search_penalty(len(second) / oversample)
            and _admissible(pair, span)
            and not geometry_explains_pair(
                pair, span, data.sun, data.observer, resolution_cycles=MIN_SEPARATION_CYCLES
            )
        ),
        commensurate=commensurate,
        combinations=combinations,
        single=single,
        scan_periods_h=1.0 / second / 3600.0,
        scan_first_h=1.0 / first / 3600.0,
        scan_chi2=np.where(allowed, scan, np.inf),
    )
    result.convex = (
        decide_reading(observations, pair) if result.tumbling and model_reading else None
    )
    return result
