"""Seeing-limited point-spread functions: aperture losses, peak intensity, saturation.

Two circularly symmetric profiles of the long-exposure seeing disc, both normalised to unit
flux and parameterised by their full width at half maximum (arcsec):

Gaussian
    ``I(r)/F = exp(−r²/2σ²) / (2πσ²)``, ``σ = FWHM / (2 √(2 ln 2))``; the fraction of the
    flux inside radius ``r`` is ``1 − exp(−r²/2σ²)``.
Moffat (Moffat 1969, "A theoretical investigation of focal stellar images in the
photographic emulsion and application to photographic photometry", A&A 3, 455)
    ``I(r)/F = (β − 1)/(π α²) · (1 + r²/α²)^−β``, ``α = FWHM / (2 √(2^{1/β} − 1))``; the
    fraction inside ``r`` is ``1 − (1 + r²/α²)^{1−β}``. ``β = 4.765`` is the profile of
    Kolmogorov turbulence (Trujillo et al. 2001, "The effects of seeing on Sérsic profiles
    – II. The Moffat PSF", MNRAS 328, 977).

Saturation clips the surface brightness at a level ``I_s``: inside the radius ``r_s`` where
``I(r_s) = I_s`` the detector records ``I_s`` instead of ``I(r)``, so an aperture of radius
``r`` loses ``F·f(ρ) − I_s π ρ²`` with ``ρ = min(r, r_s)`` and ``f`` the enclosed fraction
(closed forms for both profiles; pixels are taken as small compared with the seeing disc).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["PROFILES", "SeeingProfile"]

PROFILES = ("gaussian", "moffat")
_FWHM_PER_SIGMA = 2.0 * math.sqrt(2.0 * math.log(2.0))


@dataclass(frozen=True)
class SeeingProfile:
    """A Gaussian or Moffat point-spread function (see the module docstring).

    Parameters
    ----------
    kind : str
        ``"gaussian"`` or ``"moffat"``.
    beta : float
        Moffat exponent (> 1); ignored for the Gaussian.
    """

    kind: str = "moffat"
    beta: float = 4.765

    def __post_init__(self) -> None:
        if self.kind not in PROFILES:
            raise ValueError(
                f"seeing profile must be one of {', '.join(PROFILES)}, got {self.kind!r}"
            )
        if not (math.isfinite(self.beta) and self.beta > 1.0):
            raise ValueError(f"Moffat beta must be > 1, got {self.beta}")

    def _width(self, fwhm_arcsec: np.ndarray) -> np.ndarray:
        """σ (Gaussian) or α (Moffat), arcsec."""
        fwhm = np.asarray(fwhm_arcsec, dtype=float)
        if self.kind == "gaussian":
            return fwhm / _FWHM_PER_SIGMA
        return fwhm / (2.0 * math.sqrt(2.0 ** (1.0 / self.beta) - 1.0))

    def enclosed_fraction(self, radius_arcsec: np.ndarray, fwhm_arcsec: np.ndarray) -> np.ndarray:
        """Fraction of the flux inside a circle of the given radius (arcsec) centred on the peak."""
        u = (np.asarray(radius_arcsec, dtype=float) / self._width(fwhm_arcsec)) ** 2
        if self.kind == "gaussian":
            return -np.expm1(-0.5 * u)
        return 1.0 - (1.0 + u) ** (1.0 - self.beta)

    def peak_intensity(self, fwhm_arcsec: np.ndarray) -> np.ndarray:
        """Central surface brightness per unit flux, ``I(0)/F`` (arcsec⁻²)."""
        width = self._width(fwhm_arcsec)
        if self.kind == "gaussian":
            return 1.0 / (2.0 * math.pi * width**2)
        return (self.beta - 1.0) / (math.pi * width**2)

    def saturation_loss(
        self,
        flux: np.ndarray,
        fwhm_arcsec: np.ndarray,
        radius_arcsec: float,
        level: np.ndarray,
    ) -> np.ndarray:
        """Flux lost inside an aperture when the surface brightness is clipped at ``level``.

        Parameters
        ----------
        flux : array
            Total flux of the source (any unit, e.g. e⁻).
        fwhm_arcsec : array
            Seeing FWHM (arcsec).
        radius_arcsec : float
            Aperture radius (arcsec).
        level : array
            Clipping level in the unit of ``flux`` per arcsec² (≤ 0 clips everything).

        Returns
        -------
        numpy.ndarray
            ``F·f(ρ) − I_s π ρ²`` with ``ρ = min(r, r_s)``; zero where the peak is below the
            level.
        """
        flux = np.asarray(flux, dtype=float)
        peak = flux * self.peak_intensity(fwhm_arcsec)
        level = np.clip(np.asarray(level, dtype=float), 0.0, None)
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(peak > level, peak / level, 1.0)  # I(0)/I_s ≥ 1 (inf if level 0)
            width = self._width(fwhm_arcsec)
            if self.kind == "gaussian":
                clipped_radius_sq = 2.0 * width**2 * np.log(ratio)
            else:
                clipped_radius_sq = width**2 * (ratio ** (1.0 / self.beta) - 1.0)
        rho = np.sqrt(np.minimum(clipped_radius_sq, radius_arcsec**2))
        loss = flux * self.enclosed_fraction(rho, fwhm_arcsec) - level * math.pi * rho**2
        return np.clip(np.where(peak > level, loss, 0.0), 0.0, None)
