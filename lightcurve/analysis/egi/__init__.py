"""Convex shapes of Earth-orbiting objects from light curves with known attitudes: the
extended Gaussian image (EGI).

With the attitude known at every epoch, the brightness of a convex body is linear in the
areas of its facets over a fixed grid of normals (Horn 1984, "Extended Gaussian images",
Proc. IEEE 72, 1671): a non-negative least-squares fit of those areas is the EGI, and
Minkowski's problem (Little 1983; :mod:`lightcurve.analysis.convex.minkowski`) turns it into
the convex polyhedron.

Modules
-------
- :mod:`~lightcurve.analysis.egi.grid` — the near-uniform grid of normals and its neighbour
  Laplacian (the smoothness regularisation).
- :mod:`~lightcurve.analysis.egi.epochs` — the epochs as fitted: body-frame Sun and observer
  directions, flux and its 1σ, from observation files and attitudes.
- :mod:`~lightcurve.analysis.egi.fit` — the design matrix, the non-negative fit, the material
  search and the areas' 1σ.
- :mod:`~lightcurve.analysis.egi.profile` — the profile χ² of trial attitude histories (the
  best non-negative EGI of each fitted out), shared by the searches over attitudes.
- :mod:`~lightcurve.analysis.egi.simplify` — the fewest faces the data need: merges and
  removals of facets judged by the Bayesian information criterion.
- :mod:`~lightcurve.analysis.egi.solid` — the convex mesh in metres and its axis ratios with 1σ.
- :mod:`~lightcurve.analysis.egi.joint` — shape and attitude together (the joint mode): rounds
  of an attitude step, the torque-free state refined against the best EGI, and the EGI.
- :mod:`~lightcurve.analysis.egi.plots` — the figure of a fit.

This ``__init__`` only hands the public names on.
"""

from lightcurve.analysis.egi.epochs import FitEpochs
from lightcurve.analysis.egi.fit import (
    EGIFit,
    bootstrap_areas,
    design_matrix,
    fit_egi,
    fit_material,
)
from lightcurve.analysis.egi.grid import normal_grid, smoothness_operator
from lightcurve.analysis.egi.solid import ConvexSolid, convex_solid

__all__ = [
    "ConvexSolid",
    "EGIFit",
    "FitEpochs",
    "bootstrap_areas",
    "convex_solid",
    "design_matrix",
    "fit_egi",
    "fit_material",
    "normal_grid",
    "smoothness_operator",
]
