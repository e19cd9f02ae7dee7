"""Convex shape and spin inversion of light curves (Kaasalainen & Torppa 2001).

Modules
-------
- :mod:`~lightcurve.analysis.convex.sphere` — the fixed Gaussian sphere and harmonics.
- :mod:`~lightcurve.analysis.convex.data` — light curves as fitted.
- :mod:`~lightcurve.analysis.convex.compiled` and :mod:`~lightcurve.analysis.convex.kernels` —
  the batched model and its Jacobian: numpy and compiled numba kernels.
- :mod:`~lightcurve.analysis.convex.model` — the same model in torch: autograd, GPU.
- :mod:`~lightcurve.analysis.convex.layout` — the parameter vector and the set-up both models
  share.
- :mod:`~lightcurve.analysis.convex.optimize` — batched Levenberg–Marquardt.
- :mod:`~lightcurve.analysis.convex.fit` — fits from pole starts, their results and
  uncertainties.
- :mod:`~lightcurve.analysis.convex.scan` — period scans, χ² profiles in period.
- :mod:`~lightcurve.analysis.convex.minkowski` — the polyhedron from the Gaussian image.
- :mod:`~lightcurve.analysis.convex.plots` — figures of a fit.

This ``__init__`` only hands the public names on.
"""

from lightcurve.analysis.convex.data import Photometry
from lightcurve.analysis.convex.fit import ConvexSettings, ConvexSolution, fibonacci_poles, fit
from lightcurve.analysis.convex.scan import (
    EarlyRejection,
    PeriodScan,
    period_profile,
    period_scan,
    period_step,
)
from lightcurve.analysis.convex.sphere import GaussianSphere

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
