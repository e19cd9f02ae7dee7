"""Glint (specular flash) detection: the baseline, the calibrated threshold, flash fits.

Gou et al. 2016, sec. 2.2 (extremum methods): a flat panel flashes when its normal points along the
phase-angle bisector ``h = (ŝ + ô)/|ŝ + ô|`` (Sun and observer unit vectors from the
object). The epoch of a flash therefore measures the panel normal's direction at that
instant; several flashes of a stabilised object give the normal by least squares, and the
spacing of a tumbler's flashes gives its spin period.

Detection. The baseline is a local polynomial (cubic by default: it follows the bend of a
curve fading towards the terminator, and an odd degree adds no extra bias at the ends of
the night, Fan & Gijbels 1996, "Local Polynomial Modelling and Its Applications";
``degree=1`` is the running straight line) fitted over ``window_s`` with tricube weights,
with iterative clipping of brightenings above 3σ, so the flashes themselves do not pull it
up (where clipping takes most of one side of a window, the fit there is a straight line, so
the polynomial does not swing across the gap). Each residual ``r_i`` (baseline − magnitude)
has its own variance ``σ² e_i² v_i``, ``v_i = 1 − 2 l_ii + Σ_j l_ij² (e_j/e_i)²`` (``l_ij`` the
smoother's weights, ``e_i`` the ``mag_err``; Cleveland & Devlin 1988): below 1 where a point
pulls its own fit, most near the ends of a curve, above 1 where it was clipped from it. The
scatter σ is the MAD of the kept residuals each divided by ``e_i √v_i``, scaled by the MAD
of a unit normal cut above at the clipping level. A point is a flash candidate when it is
brighter than the baseline by ``z σ e_i √v_i``, with ``z`` chosen so that a light curve of N
points of pure Gaussian noise shows any such point with probability at most
``false_alarm``: the Student-t quantile at ``false_alarm/N`` (Bonferroni) with the degrees of
freedom of the MAD (:func:`detection_threshold`). Consecutive candidates form one glint,
whose epoch comes from a Gaussian fit to the flash profile (with its 1σ error).

Bias check. ``v_i`` is the variance of a residual, not its bias: where a curve bends faster
than the local polynomial follows (the first or last hour of a night fading towards a
panel's terminator), the baseline lies above the magnitudes by a smooth bias that is fixed
in magnitude, so the lower the noise, the more of it shows as false brightenings; once it
passes the clipping level those points leave the fit, the straight-line fallback beside them
bends even less, and the clipped stretch grows into a false glint of tens of σ. The leading
bias term of a local polynomial of degree p is that of the degree ``p + 1`` and ``p + 2``
terms of the curve (Fan & Gijbels 1996, ch. 3); a local polynomial of degree ``p + 2`` over
the same window and weights has no bias of that order. Every residual is therefore measured
against both fits, each in units of its own ``σ e_i √v_i``, and a point's brightening (used
for clipping and detection) is the smaller of the two: it exceeds ``z`` with at most the
probability that the nearly unbiased higher-degree residual does, so the false-alarm bound
holds where the baseline is biased, and it can only be lower where neither is. A flash,
narrower than the window, stands out of both fits.
"""

from __future__ import annotations

import functools
import math
import warnings
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import OptimizeWarning, brentq, curve_fit
from scipy.stats import norm
from scipy.stats import t as student_t

from lightcurve.io.observations import Observations
from lightcurve.sky.geometry import lon_lat_deg, phase_angle_bisector

__all__ = [
    "Glint",
    "GlintDetection",
    "detect_glints",
    "detection_threshold",
]

SECONDS_PER_DAY = 86400.0
MAD_EFFICIENCY = 0.37  # asymptotic efficiency of the MAD for Gaussian noise
CLIP_SIGMA = 3.0  # brightenings above this many σ leave the baseline's fit
BIAS_CHECK_DEGREES = 2  # the bias check fits a polynomial this much higher in degree


@dataclass
class Glint:
    """One detected flash.

    Attributes
    ----------
    time_s, sigma_time_s : float
        Epoch (s after the first epoch of the light curve) and its 1σ error.
    mjd : float
        Epoch as MJD.
    amplitude_mag : float
        Peak brightening above the baseline (mag).
    significance : float
        Peak brightening in units of the residual scatter σ.
    duration_s : float
        Time above the threshold.
    pab : (3,) float
        Unit phase-angle bisector at the epoch (inertial frame of the file).
    pab_rate : (3,) float
        Its time derivative (1/s), for the direction error ``|ḣ| σ_t``.
    rows : (k,) int
        Rows of the flash points.
    excess : (k,) float
        Their brightening above the baseline (flux ratio − 1).
    """

    time_s: float
    sigma_time_s: float
    mjd: float
    amplitude_mag: float
    significance: float
    duration_s: float
    pab: np.ndarray
    pab_rate: np.ndarray
    rows: np.ndarray
    excess: np.ndarray

    def summary(self) -> dict:
        lon, lat = lon_lat_deg(self.pab)
        return {
            "mjd": self.mjd,
            "time_s": self.time_s,
            "sigma_time_s": self.sigma_time_s,
            "amplitude_mag": self.amplitude_mag,
            "significance": self.significance,
            "duration_s": self.duration_s,
            "pab": self.pab.tolist(),
            "pab_lon_deg": lon,
            "pab_lat_deg": lat,
        }


@dataclass
class GlintDetection:
    """Glints of a light curve and the detection settings."""

    glints: list[Glint]
    threshold_sigma: float
    noise_mag: float
    false_alarm: float
    window_s: float
    baseline: np.ndarray = field(repr=False)
    degree: int = 3
    excess_sigma: np.ndarray = field(default=None, repr=False)
    """Brightening of every point above the baseline in units of its σ (the detector fires
    where it exceeds ``threshold_sigma``)."""
    dof: float | None = None
    """Degrees of freedom of the scatter estimate (``detection_threshold(FA, N, dof=dof)``
    gives the threshold at any other level FA)."""


@dataclass
class _Fit:
    """Baseline of a light curve and the statistics of its residuals (see :func:`_baseline`)."""

    baseline: np.ndarray
    variance: np.ndarray
    scale: float
    dof: float
    excess: np.ndarray


def detect_glints(
    observations: Observations,
    window_s: float | None = None,
    false_alarm: float = 1e-3,
    max_flash_s: float | None = None,
    degree: int = 3,
    bias_check: bool = True,
) -> GlintDetection:
    """Find specular flashes above a smooth, curved baseline.

    Parameters
    ----------
    observations : Observations
        One light curve (or several: each ``lightcurve_id`` gets its own baseline).
    window_s : float, optional
        Full width of the baseline's local fit (s). Default: ``4 · max_flash_s``, at least
        25 sampling intervals.
    false_alarm : float
        Probability that a flash-free light curve of this length shows a detection.
    max_flash_s : float, optional
        Longest flash to be found (time above the noise, s). Default: a sixteenth of the
        longest light curve (so the default window is a quarter of it). Ignored when
        ``window_s`` is given.
    degree : int
        Degree of the local polynomial (0 to 3; 3 and 2 follow the bend of a fading curve,
        3 without extra bias at the ends of a light curve; 1 is the running straight line).
    bias_check : bool
        Measure every brightening also against a local polynomial two degrees higher and
        keep the smaller of the two (module docstring, "Bias check"); ``False`` tests against
        the degree-``degree`` baseline alone (the detector before the check).

    Returns
    -------
    GlintDetection
    """
    if not 0 < false_alarm < 1:
        raise ValueError(f"false_alarm must be in (0, 1), got {false_alarm}")
    if degree not in (0, 1, 2, 3):
        raise ValueError(f"degree must be 0, 1, 2 or 3, got {degree}")
    times = observations.times
    mag = observations.magnitudes
    ids = observations.lightcurve_ids
    cadence = float(np.median(np.diff(times))) if len(times) > 1 else 1.0
    if window_s is None:
        if max_flash_s is None:
            durations = [np.ptp(times[ids == label]) for label in np.unique(ids)]
            max_flash_s = float(np.max(durations)) / 16.0
        elif not max_flash_s > 0:
            raise ValueError(f"max_flash_s must be positive, got {max_flash_s}")
        window = max(25.0 * cadence, 4.0 * float(max_flash_s))
    else:
        window = float(window_s)
        if not window > 0:
            raise ValueError(f"window_s must be positive, got {window_s}")
    errors = observations.magnitude_errors
    if np.any(~(errors > 0)):
        row = int(np.flatnonzero(~(errors > 0))[0])
        raise ValueError(f"mag_err must be positive (row {row}: {errors[row]})")
    fit = _baseline(times, mag, errors, ids, window=window, degree=degree, bias_check=bias_check)
    residual = fit.baseline - mag  # > 0: brighter than the baseline
    z = detection_threshold(false_alarm, len(mag), dof=fit.dof)
    excess_sigma = fit.excess
    candidate = excess_sigma > z
    glints = []
    sun, observer = observations.sun_vectors, observations.observer_vectors
    typical = float(np.median(fit.scale * errors))
    for rows in _runs(candidate, ids, times, 2.5 * cadence):
        glints.append(
            _describe(
                rows,
                times,
                residual,
                noise=typical,
                sun=sun,
                observer=observer,
                mjd=observations.mjd,
                cadence=cadence,
            )
        )
    return GlintDetection(
        glints,
        z,
        typical,
        false_alarm,
        window,
        fit.baseline,
        degree,
        excess_sigma,
        fit.dof,
    )


def detection_threshold(false_alarm: float, n: int, dof: float | None = None) -> float:
    """Per-point threshold (in σ) giving a per-curve false-alarm probability ≤ ``false_alarm``.

    Bonferroni: each of the ``n`` points may exceed it with probability ``false_alarm/n``.
    The scatter is itself estimated (by the MAD, of asymptotic efficiency 0.37 for Gaussian
    noise: ``var(σ̂)/σ² ≈ 1/(2 · 0.37 n)``, Rousseeuw & Croux 1993, "Alternatives to the
    median absolute deviation", JASA 88, 1273), so the quantile is Student's t with ``dof``
    degrees of freedom rather than the normal one.

    Parameters
    ----------
    false_alarm : float
        Per-curve false-alarm probability.
    n : int
        Number of points tested.
    dof : float, optional
        Degrees of freedom of the scatter estimate; default ``0.37 n`` (the MAD of ``n``
        independent residuals). :func:`detect_glints` passes ``0.37 δ₁``, with ``δ₁`` the
        residual degrees of freedom of its baseline (:attr:`GlintDetection.dof`).
    """
    if dof is None:
        dof = MAD_EFFICIENCY * n
    return float(student_t.isf(false_alarm / n, max(float(dof), 3.0)))


def _baseline(
    times: np.ndarray,
    mag: np.ndarray,
    errors: np.ndarray,
    ids: np.ndarray,
    *,
    window: float,
    degree: int,
    bias_check: bool = True,
    iterations: int = 4,
) -> _Fit:
    """Local polynomial (LOESS) baseline with brightenings above 3σ clipped.

    Every point gets a weighted least-squares polynomial of ``degree`` in time over
    ``±window/2`` with tricube weights ``(1 − |u|³)³`` (Cleveland 1979, "Robust locally
    weighted regression and smoothing scatterplots", JASA 74, 829) divided by ``mag_err²``;
    points brighter than the baseline by more than 3σ (and their neighbours) get weight 0
    in the next pass, so the flashes do not lift it. Unlike a straight line, it follows the
    curvature of a curve fading towards the terminator; at the ends and beside gaps it
    extrapolates the local polynomial (a running median does not).

    The scatter is estimated on the residuals each divided by its own standard deviation
    ``e_i √v_i`` (:func:`_local_fit`): near the ends of a curve a local fit follows its own
    point more closely (``v_i`` down to ≈ 0.7 for the cubic), and a MAD of the raw residuals
    would mix those with the interior ones and underestimate σ there. The MAD of the kept
    points, a normal sample cut above at ``CLIP_SIGMA`` σ, is scaled by the MAD of that
    truncated normal (:func:`_clipped_mad`) instead of the untruncated ``0.6745``.

    Returns
    -------
    _Fit
        ``baseline`` (N,); ``variance`` (N,): variance of each residual ``baseline − mag``
        in units of ``(scale · e_i)²``; ``scale``: robust scatter of the residuals in units
        of ``mag_err``; ``dof``: degrees of freedom of ``scale``, ``0.37 δ₁`` with
        ``δ₁ = Σ_kept v_i`` the residual degrees of freedom of the kept points (Cleveland &
        Devlin 1988, "Locally weighted regression: an approach to regression analysis by
        local fitting", JASA 83, 596); ``excess`` (N,): each point's brightening in units of
        ``scale · e_i √v_i``, the smaller of those above the degree-``degree`` baseline and
        (with ``bias_check``) above the degree ``degree + 2`` one, each with its own ``v_i``.
        Points whose ``excess`` passes ``CLIP_SIGMA`` leave both fits in the next pass.
    """
    degrees = (degree, degree + BIAS_CHECK_DEGREES) if bias_check else (degree,)
    baseline = np.empty((len(degrees), len(mag)))
    variance = np.empty((len(degrees), len(mag)))
    keep = np.ones(len(mag), dtype=bool)
    scale, dof = 1.0, MAD_EFFICIENCY * len(mag)
    segments = [np.flatnonzero(ids == label) for label in np.unique(ids)]
    for iteration in range(iterations):
        for rows in segments:
            for k, fit_degree in enumerate(degrees):
                baseline[k, rows], variance[k, rows] = _local_fit(
                    times[rows],
                    mag[rows],
                    errors[rows],
                    keep[rows],
                    window=window,
                    degree=fit_degree,
                )
        standards = (baseline - mag) / (errors * np.sqrt(variance))
        standard = np.min(standards, axis=0)
        inliers = standards[0, keep]
        spread = float(np.median(np.abs(inliers - np.median(inliers))))
        # The first pass keeps every point; later ones keep a sample cut above at the
        # clipping level (in units of the previous scale).
        scale = spread / _clipped_mad(CLIP_SIGMA if iteration else math.inf)
        if not scale > 0:
            scale = 1.0
        dof = MAD_EFFICIENCY * float(np.sum(variance[0, keep]))
        keep = ~_widen(standard > CLIP_SIGMA * scale)
    return _Fit(baseline[0], variance[0], scale, dof, standard / scale)


@functools.lru_cache(maxsize=8)
def _clipped_mad(clip: float) -> float:
    """Median absolute deviation (about the median) of a unit normal cut above at ``clip``.

    ``0.6745`` (= 1/1.4826) for ``clip = ∞``; the standard normal truncated to
    ``(−∞, clip]`` has median ``m = Φ⁻¹(Φ(clip)/2)`` and MAD ``d`` solving
    ``Φ(min(m + d, clip)) − Φ(m − d) = Φ(clip)/2``.
    """
    if not math.isfinite(clip):
        return float(norm.ppf(0.75))
    mass = float(norm.cdf(clip))
    median = float(norm.ppf(0.5 * mass))

    def excess(d: float) -> float:
        return float(norm.cdf(min(median + d, clip)) - norm.cdf(median - d)) - 0.5 * mass

    return float(brentq(excess, 1e-9, clip - median + 10.0))


def _widen(flagged: np.ndarray) -> np.ndarray:
    """Each run of flagged points widened by an eighth of its length (≥ 1 point) per side.

    A flash's wings, below the clipping level point by point, grow with its width; left in
    the fit they lift the baseline beside a long flash. (Widening by more lets the clipped
    stretch feed on itself over the iterations: a broad hump next to a flash gets clipped.)
    """
    rows = np.flatnonzero(flagged)
    if len(rows) == 0:
        return flagged
    breaks = np.flatnonzero(np.diff(rows) > 1) + 1
    first, last = rows[np.r_[0, breaks]], rows[np.r_[breaks - 1, len(rows) - 1]]
    margin = np.maximum((last - first + 1) // 8, 1)
    change = np.zeros(len(flagged) + 1, dtype=int)
    np.add.at(change, np.maximum(first - margin, 0), 1)
    np.add.at(change, np.minimum(last + margin + 1, len(flagged)), -1)
    return np.cumsum(change[:-1]) > 0


def _local_fit(
    t: np.ndarray,
    y: np.ndarray,
    e: np.ndarray,
    keep: np.ndarray,
    *,
    window: float,
    degree: int,
    block_size: int = 2_000_000,
    fallback_degree: int = 1,
) -> tuple[np.ndarray, np.ndarray]:
    """Value of the local polynomial fit at every point of one curve, and its residual variance.

    The residual ``r_i = y_i − Σ_j l_ij y_j`` (``l_ij`` the smoother's weights, ``l_ii = 0``
    for a clipped point) has variance ``e_i² v_i`` with
    ``v_i = 1 − 2 l_ii + Σ_j l_ij² (e_j/e_i)²`` (Cleveland & Devlin 1988): below 1 where the
    point pulls its own fit (most at the ends of a curve), above 1 where the fit leaves it out.

    Vectorised over (points × window neighbours), in blocks of at most ``block_size`` pairs.
    The normal equations are solved by pseudo-inverse (a degenerate window gives the
    minimum-norm fit). Where the clipped points carry more than half of the tricube weight
    of one side of a window, that point's fit has degree ``fallback_degree`` instead. Clipped
    points whose window keeps points on one side only, and
    points whose window keeps fewer than ``2 (degree + 1)``, get the baseline interpolated
    between the nearest good fits.
    """
    half = 0.5 * window
    lo = np.searchsorted(t, t - half, side="left")
    hi = np.searchsorted(t, t + half, side="right")
    width = int(np.max(hi - lo))
    powers = np.arange(degree + 1)
    value = np.empty(len(t))
    variance = np.empty(len(t))
    own = np.empty(len(t))
    support = np.empty(len(t), dtype=int)
    two_sided = np.empty(len(t), dtype=bool)
    step = max(1, block_size // width)
    for start in range(0, len(t), step):
        i = np.arange(start, min(start + step, len(t)))
        j = lo[i, None] + np.arange(width)
        inside = j < hi[i, None]
        j = np.minimum(j, len(t) - 1)
        u = (t[j] - t[i, None]) / half
        tricube = np.where(inside, (1.0 - np.clip(np.abs(u), 0, 1) ** 3) ** 3, 0.0)
        w = np.where(keep[j], tricube, 0.0) / e[j] ** 2
        design = u[..., None] ** powers  # (n, K, p)
        normal = np.einsum("nk,nkp,nkq->npq", w, design, design)
        first_row = np.linalg.pinv(normal, rcond=1e-10, hermitian=True)[:, 0, :]
        if degree > fallback_degree:
            # Where clipping took most of one side's weight, a high-degree polynomial fitted
            # to the other side (and the far end of the gapped one) swings across the gap:
            # there the leading block of the normal equations gives the low-degree fit.
            low = fallback_degree + 1
            gapped = np.zeros(len(i), dtype=bool)
            for side in (u < 0, u > 0):
                reach = np.sum(tricube * side, axis=1)
                gapped |= np.sum(tricube * side * keep[j], axis=1) < 0.5 * reach
            low_row = np.linalg.pinv(normal[:, :low, :low], rcond=1e-10, hermitian=True)[:, 0]
            first_row[gapped] = 0.0
            first_row[gapped, :low] = low_row[gapped]
        smoother = w * np.einsum("nkp,np->nk", design, first_row)  # l_ij
        value[i] = np.einsum("nk,nk->n", smoother, y[j])
        variance[i] = np.einsum("nk,nk->n", smoother**2, (e[j] / e[i, None]) ** 2)
        own[i] = np.sum(np.where(inside & (j == i[:, None]), smoother, 0.0), axis=1)
        used = w > 0
        support[i] = np.count_nonzero(used, axis=1)
        two_sided[i] = np.any(used & (u < 0), axis=1) & np.any(used & (u > 0), axis=1)
    # Inside a clipped stretch (a flash) a fit from one side only would extrapolate the
    # polynomial; there, and where the window keeps too few points, the baseline is bridged
    # linearly between the nearest good fits.
    valid = (support >= 2 * (degree + 1)) & (keep | two_sided)
    if not np.any(valid):
        raise ValueError(
            f"the baseline window ({window:g} s) holds fewer than {2 * (degree + 1)} points "
            "anywhere in the light curve; give a longer window_s"
        )
    if not np.all(valid):
        # A bridged baseline comes from the neighbours' fits: its own point is (nearly) left out.
        value = np.where(valid, value, np.interp(t, t[valid], value[valid]))
        variance = np.where(valid, variance, np.interp(t, t[valid], variance[valid]))
        own = np.where(valid, own, 0.0)
    return value, 1.0 - 2.0 * own + variance


def _runs(mask: np.ndarray, ids: np.ndarray, times: np.ndarray, gap: float) -> list[np.ndarray]:
    """Groups of consecutive flagged rows (same light curve, separated by ≤ ``gap`` s)."""
    rows = np.flatnonzero(mask)
    if len(rows) == 0:
        return []
    breaks = np.flatnonzero((np.diff(times[rows]) > gap) | (np.diff(ids[rows]) != 0)) + 1
    return np.split(rows, breaks)


def _gaussian(t: np.ndarray, amplitude: float, center: float, width: float) -> np.ndarray:
    return amplitude * np.exp(-0.5 * ((t - center) / width) ** 2)


def _describe(
    rows: np.ndarray,
    times: np.ndarray,
    residual: np.ndarray,
    *,
    noise: float,
    sun: np.ndarray,
    observer: np.ndarray,
    mjd: np.ndarray,
    cadence: float,
) -> Glint:
    """Epoch, amplitude and PAB of one flash (Gaussian profile fit around its points)."""
    peak = rows[np.argmax(residual[rows])]
    lo, hi = max(rows[0] - len(rows) - 2, 0), min(rows[-1] + len(rows) + 3, len(times))
    window = np.arange(lo, hi)
    t0 = times[peak]
    amplitude = float(residual[peak])
    width0 = max(0.5 * (times[rows[-1]] - times[rows[0]]), cadence)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", OptimizeWarning)
            params, cov = curve_fit(
                _gaussian,
                times[window] - t0,
                residual[window],
                p0=(amplitude, 0.0, width0),
                sigma=np.full(len(window), noise),
                absolute_sigma=True,
                maxfev=2000,
            )
        center, sigma_t = float(params[1]), float(math.sqrt(max(cov[1, 1], 0.0)))
        if not (abs(center) < 2 * width0 + cadence and np.isfinite(sigma_t)):
            raise RuntimeError("profile fit left the flash")
    except (RuntimeError, ValueError):
        center, sigma_t = 0.0, cadence / math.sqrt(12.0)
    epoch = t0 + center
    # Geometry at the epoch: linear interpolation between the samples around it.
    s = np.array([np.interp(epoch, times, sun[:, k]) for k in range(3)])
    o = np.array([np.interp(epoch, times, observer[:, k]) for k in range(3)])
    pab = np.asarray(phase_angle_bisector(s, o))
    i = int(np.clip(np.searchsorted(times, epoch), 1, len(times) - 1))
    h = np.asarray(phase_angle_bisector(sun[[i - 1, i]], observer[[i - 1, i]]))
    rate = (h[1] - h[0]) / max(times[i] - times[i - 1], 1e-9)
    return Glint(
        time_s=float(epoch),
        sigma_time_s=max(sigma_t, 1e-3 * cadence),
        mjd=float(mjd[0] + epoch / SECONDS_PER_DAY),
        amplitude_mag=amplitude,
        significance=amplitude / noise,
        duration_s=float(times[rows[-1]] - times[rows[0]] + cadence),
        pab=pab,
        pab_rate=rate,
        rows=rows,
        excess=10.0 ** (0.4 * residual[rows]) - 1.0,
    )
