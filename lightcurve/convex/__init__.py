"""Convex shape and spin inversion of light curves (Kaasalainen & Torppa 2001).

Modules: :mod:`~lightcurve.convex.sphere` (the fixed Gaussian sphere and harmonics),
:mod:`~lightcurve.convex.data` (light curves as fitted), :mod:`~lightcurve.convex.model`
(batched model and Jacobian in torch), :mod:`~lightcurve.convex.optimize` (batched
Levenberg–Marquardt), :mod:`~lightcurve.convex.fit` (fits, period scans, χ² profiles in period),
:mod:`~lightcurve.convex.minkowski` (the polyhedron from the Gaussian image).
"""

from lightcurve.convex.data import Photometry
from lightcurve.convex.fit import (
    ConvexSettings,
    ConvexSolution,
    PeriodScan,
    fibonacci_poles,
    fit,
    period_profile,
    period_scan,
    period_step,
)
from lightcurve.convex.sphere import GaussianSphere

__all__ = [
    "ConvexSettings",
    "ConvexSolution",
    "GaussianSphere",
    "PeriodScan",
    "Photometry",
    "fibonacci_poles",
    "fit",
    "period_profile",
    "period_scan",
    "period_step",
]
