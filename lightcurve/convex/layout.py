"""The parameter vector of the convex model, shared by its torch and compiled versions."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["PHASE_NAMES", "SECONDS_PER_DAY", "SPIN_NAMES", "ParameterLayout"]

SECONDS_PER_DAY = 86400.0
SPIN_NAMES = ("lambda", "beta", "rate", "phi0")
PHASE_NAMES = ("a", "d", "k")


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
