"""The profile χ² of trial attitude histories: the best non-negative EGI of each, fitted out.

A light curve is linear in the facet areas for given attitudes, so a search over attitudes
(a torque-free state, a reading of a tumbler's periods) scores each trial history by the χ²
of its best non-negative areas on a fixed grid of normals
(:func:`~lightcurve.analysis.egi.fit.egi_residuals`): variable projection (Golub & Pereyra
1973, "The differentiation of pseudo-inverses and nonlinear least squares problems whose
variables separate", SIAM J. Numer. Anal. 10, 413). The geometry is computed once, in the
inertial frame; each trial only turns it into the body frame.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace

import numpy as np

import brdf
from lightcurve.analysis.egi.epochs import FitEpochs
from lightcurve.analysis.egi.fit import egi_residuals
from lightcurve.analysis.egi.grid import normal_grid
from lightcurve.io.observations import Observations

__all__ = ["EGIProfile"]


class EGIProfile:
    """χ² of the best non-negative facet areas for trial attitudes, on thinned epochs.

    Parameters
    ----------
    observations : Observations or sequence of them
        The light curves of one object (one calibration: a common flux scale).
    material : brdf.BRDF
        The facets' reflectance.
    normals : int
        Grid normals (:func:`~lightcurve.analysis.egi.grid.normal_grid`).
    epochs : int
        Epochs at most (every ``ceil(E / epochs)``-th row of each file).

    Attributes
    ----------
    seconds : (E,) float
        The thinned epochs, seconds from the first file's first row.
    """

    def __init__(
        self,
        observations: Observations | Sequence[Observations],
        material: brdf.BRDF,
        *,
        normals: int,
        epochs: int,
    ) -> None:
        obs_list = [observations] if isinstance(observations, Observations) else observations
        step = max(1, math.ceil(sum(len(o) for o in obs_list) / epochs))
        parts = [Observations(o.table.iloc[::step], o.meta) for o in obs_list]
        identity = [np.tile([0.0, 0.0, 0.0, 1.0], (len(p), 1)) for p in parts]
        # With identity attitudes the "body" directions are the inertial ones.
        self.inertial = FitEpochs.from_observations(parts, identity)
        start = min(float(o.mjd[0]) for o in obs_list)
        self.seconds = (self.inertial.mjd - start) * 86400.0
        self.grid = normal_grid(normals)
        self.material = material

    def residuals(self, matrices: np.ndarray) -> np.ndarray:
        """Weighted flux residuals (E,) of the best non-negative areas for inertial → body
        attitude matrices (E, 3, 3) at :attr:`seconds`."""
        epochs = replace(
            self.inertial,
            light=np.einsum("eij,ej->ei", matrices, self.inertial.light),
            view=np.einsum("eij,ej->ei", matrices, self.inertial.view),
        )
        return egi_residuals(epochs, self.material, self.grid)

    def chi2(self, matrices: np.ndarray) -> float:
        """χ² of :meth:`residuals`."""
        return float(np.sum(self.residuals(matrices) ** 2))
