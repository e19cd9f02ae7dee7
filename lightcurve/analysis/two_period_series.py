"""The two-period Fourier series of a tumbler's light curve and its least-squares fit.

The series (Kaasalainen 2001, "Interpretation of lightcurves of precessing asteroids",
A&A 376, 302, eq. 9; Pravec et al. 2005, "Tumbling asteroids", Icarus 173, 108, eq. 1) ::

    m(t) = m_c + Σ_{(j,k)} [C_jk cos(2π(j f1 + k f2) t) + S_jk sin(2π(j f1 + k f2) t)]

over the combinations of :func:`two_period_combinations`, with ``m_c`` a per-curve
polynomial trend; at fixed (f1, f2) it is linear and solved, batched over trial pairs, by
:class:`~lightcurve.analysis.fourier_design.FourierDesign` (:class:`TwoPeriodFit`).
:func:`local_minimum` and :func:`chi2_hessian` take a pair to its minimum and give the
curvature there. The search that uses them is :mod:`lightcurve.analysis.tumbling`.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import minimize

from lightcurve.analysis.fourier_design import FourierDesign
from lightcurve.analysis.period import StackedLightCurves

__all__ = [
    "MIN_SEPARATION_CYCLES",
    "TwoPeriodFit",
    "chi2_hessian",
    "local_minimum",
    "two_period_combinations",
]

#: The two frequencies must differ by at least this many cycles over the time span T
#: (closer ones beat into a slow modulation the arc cannot resolve as a period), and so
#: must one and the double or half of the other: a rotator's first and second harmonics,
#: drifting in phase as the geometry changes, otherwise pass for two periods.
MIN_SEPARATION_CYCLES = 1.5
#: Trial pairs per vectorised block.
_CHUNK = 32


def two_period_combinations(order: int) -> np.ndarray:
    """The combination vectors (j, k) of the two-period series of order m.

    Parameters
    ----------
    order : int
        m ≥ 1.

    Returns
    -------
    (P, 2) int
        ``0 ≤ j ≤ m``, ``|j| + |k| ≤ m``, not both zero, ``k > 0`` when ``j = 0``; ordered
        by ``|j| + |k|`` then j then k. ``P = m(m + 1)`` (m = 2: 6, 3: 12, 4: 20).
    """
    if order < 1:
        raise ValueError(f"the two-period order must be ≥ 1, got {order}")
    pairs = [
        (j, k)
        for j in range(order + 1)
        for k in range(-order, order + 1)
        if j + abs(k) <= order and (j > 0 or k > 0)
    ]
    return np.array(sorted(pairs, key=lambda p: (p[0] + abs(p[1]), p[0], p[1])), dtype=int)


class TwoPeriodFit:
    """χ² of the two-period series at trial pairs, on all points or the subset ``keep``."""

    def __init__(
        self,
        data: StackedLightCurves,
        trend_degree: int,
        keep: np.ndarray | slice = slice(None),
    ) -> None:
        self.design = FourierDesign(
            data.times[keep],
            data.magnitudes[keep],
            data.sigma[keep],
            data.curve[keep],
            trend_degree=trend_degree,
        )
        self.n = len(self.design.t)
        # Combination terms slower than the trend resolves are left out of the series.
        self.slowest = MIN_SEPARATION_CYCLES / float(np.ptp(data.times))

    def chi2(self, pairs: np.ndarray, order: int) -> np.ndarray:
        pairs = np.atleast_2d(pairs)
        combos = two_period_combinations(order)
        return np.concatenate(
            [
                self.design.solve_combinations(pairs[i : i + _CHUNK], combos, slowest=self.slowest)[
                    1
                ]
                for i in range(0, len(pairs), _CHUNK)
            ]
        )

    def coefficients(self, pair: np.ndarray, order: int) -> np.ndarray:
        return self.design.solve_combinations(
            np.asarray(pair, float)[None], two_period_combinations(order), slowest=self.slowest
        )[0][0]

    def bic(self, chi2: float, order: int) -> float:
        n_parameters = 2 * len(two_period_combinations(order)) + self.design.n_nuisance + 2
        return chi2 + n_parameters * math.log(self.n)


def chi2_hessian(values: np.ndarray, h: float) -> np.ndarray:
    """Hessian of χ² from its values on a 3 × 3 stencil of spacing ``h`` (central
    differences)."""
    cross = (values[2, 2] - values[2, 0] - values[0, 2] + values[0, 0]) / 4.0
    return np.array(
        [
            [values[2, 1] - 2 * values[1, 1] + values[0, 1], cross],
            [cross, values[1, 2] - 2 * values[1, 1] + values[1, 0]],
        ]
    ) / (h * h)


def local_minimum(
    fit: TwoPeriodFit, pair: np.ndarray, order: int, step: float, *, tolerance: float
) -> np.ndarray:
    """Local minimum of χ²(f1, f2) near ``pair`` (Nelder–Mead in units of ``step``, to
    ``tolerance`` of them)."""
    origin = np.asarray(pair, float)
    result = minimize(
        lambda x: float(fit.chi2(origin + step * x, order)[0]),
        np.zeros(2),
        method="Nelder-Mead",
        options={
            "initial_simplex": [[0, 0], [0.5, 0], [0, 0.5]],
            "xatol": tolerance,
            "fatol": 1e-3,
        },
    )
    return origin + step * result.x
