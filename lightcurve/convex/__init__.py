"""Convex shape and spin inversion of light curves (Kaasalainen & Torppa 2001).

Modules: :mod:`~lightcurve.convex.sphere` (the fixed Gaussian sphere and harmonics),
:mod:`~lightcurve.convex.data` (light curves as fitted), :mod:`~lightcurve.convex.compiled`
and :mod:`~lightcurve.convex.kernels` (the batched model and its Jacobian: numpy and compiled
numba kernels), :mod:`~lightcurve.convex.model` (the same model in torch: autograd, GPU),
:mod:`~lightcurve.convex.layout` (the parameter vector and the set-up both models share),
:mod:`~lightcurve.convex.optimize` (batched Levenberg–Marquardt), :mod:`~lightcurve.convex.fit`
(fits from pole starts, their results and uncertainties), :mod:`~lightcurve.convex.scan`
(period scans, χ² profiles in period), :mod:`~lightcurve.convex.minkowski` (the polyhedron
from the Gaussian image).
"""

from lightcurve.convex.data import Photometry
from lightcurve.convex.fit import ConvexSettings, ConvexSolution, fibonacci_poles, fit
from lightcurve.convex.scan import (
    EarlyRejection,
    PeriodScan,
    period_profile,
    period_scan,
    period_step,
)
from lightcurve.convex.sphere import GaussianSphere

__all__ = [
    "ConvexSettings",
    "ConvexSolution",
    "EarlyRejection",
    "GaussianSphere",
    "PeriodScan",
    "Photometry",
    "fibonacci_poles",
    "fit",
    "period_profile",
    "period_scan",
    "period_step",
]
