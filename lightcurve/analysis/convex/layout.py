"""The parameter vector of the convex model and the set-up its torch and compiled versions
share."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from lightcurve.analysis.convex.data import Photometry
    from lightcurve.analysis.convex.sphere import GaussianSphere

__all__ = [
    "CONVEXITY_WEIGHT",
    "PHASE_NAMES",
    "SECONDS_PER_DAY",
    "SPIN_NAMES",
    "ModelSetup",
    "ParameterLayout",
]

SECONDS_PER_DAY = 86400.0
SPIN_NAMES = ("lambda", "beta", "rate", "phi0")
PHASE_NAMES = ("a", "d", "k")
#: Default weight ``w`` of the convexity regularisation (DAMIT's ``convexinv``).
CONVEXITY_WEIGHT = 0.1


@dataclass(frozen=True)
class ParameterLayout:
    """Positions of the parameters in a parameter vector.

    ``[c_0 … c_{K−1}, λ, β, ω, φ0, a, d, k, c_lambert, log_scale]`` — harmonics
    coefficients, pole longitude/latitude (rad), rotation rate (rad/s), rotation angle at t0
    (rad), phase-function parameters (d in rad), Lambert weight, log of the scale of the
    calibrated curves.
    """

    n_coefficients: int

    @property
    def size(self) -> int:
        return self.n_coefficients + 9

    @property
    def spin(self) -> slice:
        return slice(self.n_coefficients, self.n_coefficients + 4)

    @property
    def phase(self) -> slice:
        return slice(self.n_coefficients + 4, self.n_coefficients + 7)

    @property
    def lambert(self) -> int:
        return self.n_coefficients + 7

    @property
    def log_scale(self) -> int:
        return self.n_coefficients + 8

    def index(self, name: str) -> int:
        """Position of a named scalar parameter (``lambda``, ``beta``, ``rate``, ``phi0``,
        ``a``, ``d``, ``k``, ``c``, ``log_scale``)."""
        names = (*SPIN_NAMES, *PHASE_NAMES, "c", "log_scale")
        if name not in names:
            raise KeyError(f"unknown parameter {name!r}; known: {', '.join(names)}")
        return self.n_coefficients + names.index(name)


class ModelSetup:
    """What the compiled and the torch convex models derive alike from their inputs.

    Attributes
    ----------
    data : Photometry
    sphere : GaussianSphere
    layout : ParameterLayout
    epoch_mjd : float
        Reference epoch t0 of the rotation angle (UTC MJD).
    has_calibrated : bool
        Whether any light curve is calibrated (it then has a fitted scale ``s``).
    regularisation_scale : float
        ``w √N / σ̃`` (``w`` the convexity weight, N points, σ̃ their median error): the
        convexity residuals are this times ``Σ A_i n_i / Σ A_i`` (Kaasalainen & Torppa 2001,
        sec. 3.3).
    """

    def _set_up(
        self, data: Photometry, sphere: GaussianSphere, epoch_mjd: float, convexity_weight: float
    ) -> None:
        """Set the attributes above (the models' constructors call it first)."""
        self.data, self.sphere = data, sphere
        self.layout = ParameterLayout(sphere.n_coefficients)
        self.epoch_mjd = float(epoch_mjd)
        self.has_calibrated = bool((~data.relative).any())
        self.regularisation_scale = (
            convexity_weight * math.sqrt(len(data)) / float(np.median(data.sigma))
        )
