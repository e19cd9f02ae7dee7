"""Period scans of convex inversion: χ²(P) over trial periods, its minima refined, and χ²
profiles in period.

:func:`period_scan` fits a grid of trial periods, each from several pole starts spread over
the sphere, all batched, and returns χ²(P) with its minima (Kaasalainen, Torppa & Muinonen
2001, *Optimization methods for asteroid lightcurve inversion II*, sec. 4; Ďurech, Sidorin &
Kaasalainen 2010, *DAMIT: a database of asteroid models*, for DAMIT's settings);
:func:`refine` refits the minima with a finer model and :func:`period_profile` redoes a fit at
fixed periods. The fits themselves are those of :mod:`lightcurve.analysis.convex.fit`.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from lightcurve.analysis.convex.data import Photometry
from lightcurve.analysis.convex.fit import (
    ConvexSettings,
    ConvexSolution,
    _free_mask,
    _solutions,
    _solve,
    _start_vectors,
    fibonacci_poles,
    fit,
)
from lightcurve.analysis.spin import SpinState

__all__ = [
    "SCAN_SETTINGS",
    "EarlyRejection",
    "PeriodScan",
    "period_profile",
    "period_scan",
    "period_step",
    "refine",
]

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class EarlyRejection:
    """Rule that ends the hopeless trial fits of a period scan early.

    Every fit of a scan starts from a sphere and runs the same number of Levenberg–Marquardt
    iterations, so fits are compared at equal iterations: after ``after`` iterations, a fit
    whose χ² exceeds ``factor`` times the lowest χ² that any fit of the scan so far had
    after the same number of iterations is stopped. The fits that end at the deepest minima
    of χ²(P) stay close to that lowest χ² all along: on Ariadne and on a simulated
    decades-long set (``benchmarks/convex.py``, ``rejection``), the fits ending within 1.5
    times the scan's minimum never exceed it by more than a factor 1.6 after the third
    iteration, so the default factor 3 leaves them a margin of two. Most fits are 5–10 times
    above it by then and stop after three iterations instead of ten.

    Periods whose best fit was stopped keep the χ² at which it stopped (an upper bound of
    what the fit would have reached); :attr:`PeriodScan.rejected` flags them and
    :meth:`PeriodScan.local_minima` does not report them.

    Parameters
    ----------
    after : int
        Iterations every fit runs before it may be stopped.
    factor : float
        Stop when χ² > factor × the lowest χ² at the same iteration (> 1).
    """

    after: int = 3
    factor: float = 3.0

    def __post_init__(self) -> None:
        if self.after < 1 or not self.factor > 1:
            raise ValueError(f"need after ≥ 1 and factor > 1, got {self.after}, {self.factor}")

    def stop(self, iteration: int, chi2: np.ndarray, lowest: np.ndarray) -> np.ndarray:
        """Fits to stop after ``iteration`` iterations, given their χ².

        ``lowest[iteration]`` is the lowest χ² of the scan so far after that many
        iterations; it is updated with these fits' values first.
        """
        lowest[iteration] = min(lowest[iteration], float(np.min(chi2)))
        if iteration < self.after:
            return np.zeros(len(chi2), dtype=bool)
        return chi2 > self.factor * lowest[iteration]


@dataclass
class PeriodScan:
    """χ² against trial period.

    Attributes
    ----------
    periods_h : (n,) float
        Trial periods (h).
    chi2 : (n,) float
        Best χ² over the pole starts at each trial period (scaled to the full data when
        the scan ran on thinned data).
    best : list of ConvexSolution
        The best fit of each trial period.
    seconds : float
        Wall-clock time of the scan.
    rejected : (n,) bool
        Periods whose best fit was stopped by the :class:`EarlyRejection` rule (their χ² is
        where it stopped, above the rule's factor times the minimum).
    """

    periods_h: np.ndarray
    chi2: np.ndarray
    best: list[ConvexSolution]
    seconds: float
    rejected: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.rejected is None:
            self.rejected = np.zeros(len(self.periods_h), dtype=bool)

    def minimum(self) -> ConvexSolution:
        """The global minimum."""
        return self.best[int(np.argmin(self.chi2))]

    def local_minima(self, count: int = 5) -> list[ConvexSolution]:
        """The ``count`` deepest local minima of χ²(P), best first (rejected periods are
        none)."""
        c = self.chi2
        is_min = np.r_[True, c[1:] <= c[:-1]] & np.r_[c[:-1] <= c[1:], True] & ~self.rejected
        rows = np.flatnonzero(is_min)
        rows = rows[np.argsort(c[rows])][:count]
        return [self.best[r] for r in rows]


def period_step(data: Photometry, period_h: float, coefficient: float = 0.5) -> float:
    """Trial-period step ``coefficient · P²/(2T)`` (h) for a data span T.

    Adjacent χ² minima of a double-peaked light curve are ``P²/(2T)`` apart (half a
    rotation accumulated over the span), so a step of half that misses none.
    """
    return coefficient * period_h**2 / (2.0 * data.span_days * 24.0)


def period_scan(
    data: Photometry,
    period_range_h: tuple[float, float],
    poles: int | Sequence[tuple[float, float]] = 6,
    settings: ConvexSettings | None = None,
    *,
    step_coefficient: float = 0.5,
    thin: int | None = 20,
    batch_size: int | None = None,
    epoch_mjd: float | None = None,
    progress: bool | Callable[[int, int], None] = False,
    reject: EarlyRejection | None = EarlyRejection(),
) -> PeriodScan:
    """χ² against trial period, each period fitted from several pole starts.

    Every trial period is fitted from every pole start (the shape from a sphere), batched;
    the scan's χ² at a period is the best over the pole starts, so that a wrong local
    minimum in pole does not show as a false minimum in period (DAMIT's ``period_scan``).
    The trial periods are ``period_step`` apart. The model (its data arrays, the Gaussian
    sphere and harmonics) is built once for the whole scan.

    Parameters
    ----------
    data : Photometry
    period_range_h : (float, float)
        Scan interval (h).
    poles : int or sequence of (λ, β)
        Number of pole starts (spread by :func:`fibonacci_poles`) or the starts (rad).
    settings : ConvexSettings, optional
        Model of the scan; default a light one (degree 3, 72 facets, 10 iterations,
        float32): the scan only has to rank the periods, the minima are refined afterwards.
    step_coefficient : float
        See :func:`period_step`.
    thin : int or None
        Fit at most this many evenly spaced points per light curve (None: all). χ² is
        scaled back to the full number of points.
    batch_size : int, optional
        Fits run together (rounded to whole periods; default about 40 000 facet sums ×
        epochs per batch).
    epoch_mjd : float, optional
        Epoch t0 at which the solutions report φ0 (default: the first epoch); the fits
        themselves refer the rotation to the data's mean epoch, as :func:`fit`.
    progress : bool or callable
        True: a tqdm progress bar on stderr; a callable is called as
        ``progress(periods_done, periods_total)`` after every batch.
    reject : EarlyRejection or None
        Early rejection of hopeless fits (None: every fit runs to the end).

    Returns
    -------
    PeriodScan
    """
    low, high = sorted(float(v) for v in period_range_h)
    if not (low > 0 and high > low):
        raise ValueError(f"period range must be 0 < A < B hours, got {period_range_h}")
    settings = settings or SCAN_SETTINGS
    pole_starts = fibonacci_poles(poles) if isinstance(poles, int) else list(poles)
    periods = [low]
    while periods[-1] < high:
        periods.append(periods[-1] + period_step(data, periods[-1], step_coefficient))
    periods = np.array(periods)
    fitted = data.thinned(thin) if thin else data
    epoch = float(data.mjd.min()) if epoch_mjd is None else float(epoch_mjd)
    began = time.perf_counter()
    model = settings.model(fitted, data.mean_epoch)
    free = _free_mask(model, settings)
    n_poles = len(pole_starts)
    if batch_size is None:
        batch_size = max(1, 40_000 // len(fitted))
    per_batch = max(1, batch_size // n_poles)
    report = _progress(progress, len(periods))
    lowest = np.full(settings.max_iter + 1, np.inf)  # lowest χ² after each iteration
    chi2 = np.empty(len(periods))
    rejected = np.zeros(len(periods), dtype=bool)
    best: list[ConvexSolution] = []
    for first in range(0, len(periods), per_batch):
        chunk = periods[first : first + per_batch]
        starts = [
            SpinState(lam, beta, p * 3600.0, 0.0, epoch) for p in chunk for lam, beta in pole_starts
        ]
        stop = None
        if reject is not None:

            def stop(iteration, values, active):
                return reject.stop(iteration, values, lowest)

        result = _solve(model, _start_vectors(model, settings, starts), free, settings, stop)
        values = result.chi2.reshape(len(chunk), n_poles)
        pick = np.argmin(values, axis=1)
        rows = np.arange(len(chunk)) * n_poles + pick
        best += _solutions(model, free, result, epoch, rows)
        chi2[first : first + len(chunk)] = [s.chi2 for s in best[first:]]
        rejected[first : first + len(chunk)] = result.stopped[rows]
        report(first + len(chunk))
        logger.info(
            "period scan: %d/%d periods, %d fits stopped early",
            first + len(chunk),
            len(periods),
            int(result.stopped.sum()),
        )
    report(None)
    scale = len(data) / len(fitted)
    return PeriodScan(periods, scale * chi2, best, time.perf_counter() - began, rejected)


def _progress(progress: bool | Callable[[int, int], None], total: int):
    """``report(done)`` for :func:`period_scan` (``report(None)`` at the end)."""
    if callable(progress):
        return lambda done: None if done is None else progress(done, total)
    if not progress:
        return lambda done: None
    from tqdm import tqdm

    bar = tqdm(total=total, desc="period scan", unit="period")

    def report(done):
        if done is None:
            bar.close()
        else:
            bar.update(done - bar.n)

    return report


#: The light model of :func:`period_scan`.
SCAN_SETTINGS = ConvexSettings(degree=3, order=3, nrows=3, max_iter=10, dtype="float32")


def refine(
    solutions: Sequence[ConvexSolution], data: Photometry, settings: ConvexSettings
) -> list[ConvexSolution]:
    """Refit solutions (e.g. scan minima) with other settings from their spin states, batched.

    Returns
    -------
    list of ConvexSolution
        Sorted by χ², best first.
    """
    return fit(data, [s.spin for s in solutions], settings)


def period_profile(
    data: Photometry,
    solution: ConvexSolution,
    periods_h: Sequence[float],
    settings: ConvexSettings | None = None,
) -> list[ConvexSolution]:
    """χ² profile in period: the fit redone at each fixed period from ``solution``.

    The pole, the shape and any other free parameter of ``settings`` are refitted with the
    rotation rate held at each trial period, starting from ``solution``'s parameters (its
    shape, not a sphere), all periods batched. The profile's curvature gives the period's
    uncertainty with the correlated parameters re-optimised; its minimum shows where the
    χ² of the data and model lies, independently of the optimiser's path in period.

    Parameters
    ----------
    data : Photometry
        The data ``solution`` was fitted to.
    solution : ConvexSolution
        A fit of :func:`fit` with the same settings.
    periods_h : sequence of float
        Fixed trial periods (h).
    settings : ConvexSettings, optional

    Returns
    -------
    list of ConvexSolution
        One per period, in the order of ``periods_h``.
    """
    settings = settings or ConvexSettings()
    model = settings.model(data, data.mean_epoch)
    lay = model.layout
    if len(solution.parameters) != lay.size:
        raise ValueError("solution and settings have different spherical-harmonics degrees")
    periods = np.asarray(periods_h, dtype=float)
    x0 = np.repeat(np.asarray(solution.parameters, float)[None], len(periods), axis=0)
    x0[:, lay.index("phi0")] = solution.spin.at_epoch(data.mean_epoch).phi0_rad
    x0[:, lay.index("rate")] = 2 * math.pi / (periods * 3600.0)
    free = _free_mask(model, settings)
    free[lay.index("rate")] = False
    result = _solve(model, x0, free, settings)
    return _solutions(model, free, result, solution.spin.epoch_mjd)
