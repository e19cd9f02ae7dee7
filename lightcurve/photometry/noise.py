"""Measurement noise: true magnitudes → measured magnitudes, their 1σ errors and flags.

Noise models
------------
:class:`GaussianNoise`
    ``mag_obs = mag + N(0, σ²)``, ``mag_err = σ``.
:class:`CCDNoise`
    Photon counting on a CCD: source electrons ``S = t A 10^(−0.4 (m − ZP))`` (``A`` the
    collecting area, ``ZP`` the magnitude giving 1 e⁻ s⁻¹ m⁻²), sky electrons per pixel
    ``B = t A Ω_pix 10^(−0.4 (μ_sky − ZP))``, ``n_pix`` pixels in the photometric aperture,
    read noise ``R`` e⁻ and gain ``g`` e⁻/ADU (quantisation ``g²/12`` per pixel):
    ``σ_S² = S + n_pix (B + R² + g²/12)`` (the CCD equation, Howell 2006, eq. 4.4).
    Counts are drawn from Poisson (source + sky) and normal (read noise) distributions and
    the sky is subtracted; ``mag_err = 2.5/ln 10 · σ_S / S``.
:class:`ObservingNoise`
    The full observing conditions of :mod:`lightcurve.photometry.conditions`: extinction ``k X``
    with the Kasten & Young (1989) airmass of every row's elevation, seeing losses in the
    photometric aperture, sky brightening with airmass, dark current, read noise, gain,
    the sky-estimate term of Howell's eq. 4.4, scintillation (Osborn et al. 2015) and
    full-well/ADC saturation. Adds the columns ``extinction_mag`` and ``saturated`` (and
    ``elevation_deg``/``airmass`` when the geometry has none).

Every model implements :meth:`NoiseModel.measure`, which sees the geometry table (exposure
times, elevations, the site in the header) and returns a :class:`Measurement`. Measured
counts ≤ 0 are non-detections: their magnitude is NaN.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from typing import Protocol

import numpy as np

from lightcurve.io.observations import Observations
from lightcurve.photometry.conditions import ObservingConditions
from lightcurve.sky.sites import Site, site_from_label
from lightcurve.sky.topocentric import horizontal_from_gcrs

__all__ = [
    "CCDNoise",
    "GaussianNoise",
    "Measurement",
    "NoiseModel",
    "ObservingNoise",
    "observation_elevation",
]

_MAG_PER_LN = 2.5 / math.log(10.0)


@dataclass(frozen=True)
class Measurement:
    """Measured magnitudes of every row of a geometry table.

    Attributes
    ----------
    magnitude, error : (n,) numpy.ndarray
        Measured magnitude and its 1σ error (mag); NaN for non-detections.
    columns : dict of str to (n,) array
        Extra per-row columns for the output table (e.g. ``saturated``).
    drop : dict of str to (n,) bool array
        Rows to drop, by reason (counted in the output header as ``dropped_<reason>``).
    """

    magnitude: np.ndarray
    error: np.ndarray
    columns: dict[str, np.ndarray] = field(default_factory=dict)
    drop: dict[str, np.ndarray] = field(default_factory=dict)


class NoiseModel(Protocol):
    """Turns true magnitudes into measured magnitudes and their 1σ errors."""

    def measure(
        self, magnitude: np.ndarray, geometry: Observations, rng: np.random.Generator
    ) -> Measurement: ...

    def describe(self) -> str: ...


def _exposure(geometry: Observations) -> np.ndarray | None:
    """The file's ``exposure_s`` column (s), if any."""
    table = geometry.table
    return table["exposure_s"].to_numpy(dtype=float) if "exposure_s" in table else None


@dataclass(frozen=True)
class GaussianNoise:
    """Gaussian magnitude noise of standard deviation ``sigma`` (mag)."""

    sigma: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.sigma) and self.sigma > 0):
            raise ValueError(f"noise sigma must be a positive magnitude, got {self.sigma}")

    def apply(
        self, magnitude: np.ndarray, exposure_s: np.ndarray | None, rng: np.random.Generator
    ) -> tuple[np.ndarray, np.ndarray]:
        noisy = magnitude + rng.normal(0.0, self.sigma, magnitude.shape)
        return noisy, np.full_like(magnitude, self.sigma)

    def measure(
        self, magnitude: np.ndarray, geometry: Observations, rng: np.random.Generator
    ) -> Measurement:
        return Measurement(*self.apply(magnitude, None, rng))

    def describe(self) -> str:
        return f"gaussian sigma={self.sigma} mag"


@dataclass(frozen=True)
class CCDNoise:
    """Photon-counting CCD photometry (see the module docstring).

    Parameters
    ----------
    aperture_m : float
        Telescope aperture diameter (m); the collecting area is ``π (D/2)²``.
    exposure_s : float
        Exposure time (s), unless the geometry has an ``exposure_s`` column.
    zero_point : float
        Magnitude giving 1 e⁻ s⁻¹ per m² of collecting area (24.0 ≈ V band with a
        typical 40 % system throughput).
    sky_mag_arcsec2 : float
        Sky surface brightness (mag arcsec⁻²).
    pixel_scale_arcsec : float
        Pixel size on the sky (arcsec).
    aperture_radius_px : float
        Photometric aperture radius (pixels).
    read_noise_e : float
        Read noise (e⁻ rms per pixel).
    gain_e_per_adu : float
        Gain (e⁻/ADU).
    """

    aperture_m: float = 0.5
    exposure_s: float = 1.0
    zero_point: float = 24.0
    sky_mag_arcsec2: float = 20.0
    pixel_scale_arcsec: float = 1.5
    aperture_radius_px: float = 3.0
    read_noise_e: float = 10.0
    gain_e_per_adu: float = 1.5

    def __post_init__(self) -> None:
        for name, value in asdict(self).items():
            if name not in ("zero_point", "sky_mag_arcsec2") and not (
                math.isfinite(value) and value > 0
            ):
                raise ValueError(f"CCD parameter {name} must be positive, got {value}")

    @property
    def collecting_area_m2(self) -> float:
        return math.pi * (0.5 * self.aperture_m) ** 2

    @property
    def n_pixels(self) -> float:
        return math.pi * self.aperture_radius_px**2

    def electrons(self, magnitude: np.ndarray, exposure_s: np.ndarray) -> np.ndarray:
        """Expected source electrons for magnitudes and exposure times."""
        return exposure_s * self.collecting_area_m2 * 10.0 ** (-0.4 * (magnitude - self.zero_point))

    def sky_electrons_per_pixel(self, exposure_s: np.ndarray) -> np.ndarray:
        """Expected sky electrons per pixel."""
        return (
            exposure_s
            * self.collecting_area_m2
            * self.pixel_scale_arcsec**2
            * 10.0 ** (-0.4 * (self.sky_mag_arcsec2 - self.zero_point))
        )

    def apply(
        self, magnitude: np.ndarray, exposure_s: np.ndarray | None, rng: np.random.Generator
    ) -> tuple[np.ndarray, np.ndarray]:
        t = np.full_like(magnitude, self.exposure_s) if exposure_s is None else exposure_s
        source = self.electrons(magnitude, t)
        sky = self.sky_electrons_per_pixel(t) * self.n_pixels
        per_pixel_var = self.read_noise_e**2 + self.gain_e_per_adu**2 / 12.0
        measured = (
            rng.poisson(source + sky).astype(float)
            - sky
            + rng.normal(0.0, math.sqrt(self.n_pixels * per_pixel_var), magnitude.shape)
        )
        with np.errstate(invalid="ignore", divide="ignore"):
            noisy = magnitude - 2.5 * np.log10(measured / source)
            sigma = np.sqrt(measured.clip(0) + sky + self.n_pixels * per_pixel_var)
            error = _MAG_PER_LN * sigma / measured
        return np.where(measured > 0, noisy, np.nan), np.where(measured > 0, error, np.nan)

    def measure(
        self, magnitude: np.ndarray, geometry: Observations, rng: np.random.Generator
    ) -> Measurement:
        return Measurement(*self.apply(magnitude, _exposure(geometry), rng))

    def describe(self) -> str:
        return "ccd " + " ".join(f"{k}={v}" for k, v in asdict(self).items())


def _recorded_site(geometry: Observations) -> Site | None:
    """The site named in the file's header, or None (absent or not understood)."""
    label = geometry.meta.get("site")
    if not label:
        return None
    try:
        return site_from_label(label)
    except ValueError:
        return None


def observation_elevation(geometry: Observations) -> np.ndarray:
    """Elevation of the object at the observing site for every row (deg).

    The file's ``elevation_deg`` column when present (every ``lightcurve geometry`` route,
    ``lightcurve import``); otherwise computed from the site recorded in the header
    (``# site: name (lat, lon, alt m)`` or an observatory name) and the object → observer
    vectors (GCRS).

    Raises
    ------
    ValueError
        Naming the file when neither is available, the frame is not GCRS, or a row has the
        object at or below the horizon.
    """
    source = geometry.source or "geometry"
    table = geometry.table
    if "elevation_deg" in table:
        elevation = table["elevation_deg"].to_numpy(dtype=float)
    else:
        site = _recorded_site(geometry)
        if site is None:
            what = (
                f"site {geometry.meta['site']!r} is not understood"
                if geometry.meta.get("site")
                else "no site in the header"
            )
            raise ValueError(
                f"{source}: extinction needs the elevation of every row: no elevation_deg "
                f"column and {what}; write the geometry with `lightcurve geometry ... --site "
                "NAME|LAT,LON,ALT_M` (or `lightcurve import`)"
            )
        frame = geometry.meta.get("frame", "GCRS")
        if frame != "GCRS" or geometry.meta.get("target") == "asteroid":
            raise ValueError(
                f"{source}: elevations are computed from GCRS vectors of an Earth-orbiting "
                f"object, the file's frame is {frame!r}"
            )
        elevation = horizontal_from_gcrs(site, geometry.mjd, -geometry.observer_vectors / 1e3)[0]
    low = ~(elevation > 0)
    if low.any():
        row = int(np.flatnonzero(low)[0])
        raise ValueError(
            f"{source}, row {row + 1}: the object is at or below the horizon "
            f"(elevation {elevation[row]:.2f} deg): no airmass"
        )
    return elevation


@dataclass(frozen=True)
class ObservingNoise:
    """Photometry through the atmosphere onto a CCD under :class:`ObservingConditions`.

    For every row (elevation ``h``, airmass ``X``, exposure ``t`` from the file's
    ``exposure_s`` column or ``[photometry] exposure_s``) the expected electrons come from
    :meth:`ObservingConditions.budget`; the draws are

    - scintillation: the source rate is multiplied by a log-normal factor of mean 1 and
      rms ``σ_sc`` (weak scintillation is log-normal);
    - photon noise: Poisson counts of source + sky + dark in the aperture;
    - read noise, gain quantisation and the error of the sky level estimated from ``n_B``
      pixels: one normal draw carrying the rest of Howell's eq. 4.4 variance;
    - saturation: a pixel at the peak of the seeing disc above ``min(full well, gain · ADC
      max)`` flags the row; the clipped light is lost from the aperture sum (the measured
      magnitude is too faint, as in real saturated photometry).

    The measured counts are calibrated as a reduction would (aperture correction and zero
    point known) and, with ``extinction_corrected``, corrected by ``k X``: the mean of the
    reported magnitudes is the magnitude above the atmosphere (plus the usual second-order
    bias ``(2.5/ln 10) σ²/2`` of a logarithm of a noisy flux). ``mag_err = 2.5/ln 10 · σ/N``
    with ``σ²`` from the measured counts ``N``, the scintillation and the background terms.

    Parameters
    ----------
    conditions : ObservingConditions
    """

    conditions: ObservingConditions = field(default_factory=ObservingConditions)

    def measure(
        self, magnitude: np.ndarray, geometry: Observations, rng: np.random.Generator
    ) -> Measurement:
        conditions = self.conditions
        elevation = observation_elevation(geometry)
        altitude = conditions.site.altitude_m
        if altitude is None:
            site = _recorded_site(geometry)
            if site is None:
                raise ValueError(
                    f"{geometry.source or 'geometry'}: scintillation needs the site's altitude:"
                    " give [site] altitude_m (or --condition site.altitude_m=...) or a geometry"
                    " file with a site (`lightcurve geometry ... --site`)"
                )
            altitude = site.altitude_m
        exposure = _exposure(geometry)
        if exposure is not None and not np.all(exposure > 0):
            row = int(np.flatnonzero(~(exposure > 0))[0])
            raise ValueError(
                f"{geometry.source or 'geometry'}, row {row + 1}, column 'exposure_s': "
                f"exposure must be > 0 s, got {exposure[row]}"
            )
        budget = conditions.budget(
            magnitude,
            elevation,
            conditions.photometry.exposure_s if exposure is None else exposure,
            altitude,
        )
        n = len(elevation)
        sigma_ln = np.sqrt(np.log1p(budget.scintillation**2))
        scintillation = np.exp(sigma_ln * rng.standard_normal(n) - 0.5 * sigma_ln**2)
        background = budget.n_pixels * (budget.sky_e + budget.dark_e)
        counts = rng.poisson(budget.source_e * scintillation + background).astype(float)
        pixel_area = conditions.detector.pixel_scale_arcsec**2
        room = budget.saturation_e - budget.sky_e - budget.dark_e
        saturated = budget.peak_e * scintillation >= room
        lost = conditions.site.profile.saturation_loss(
            budget.total_source_e * scintillation,
            budget.fwhm_arcsec,
            conditions.photometry.aperture_radius_arcsec,
            room / pixel_area,
        )
        other = np.sqrt(budget.background_variance - background)
        measured = counts - lost - background + other * rng.standard_normal(n)
        detected = measured > 0
        with np.errstate(invalid="ignore", divide="ignore"):
            observed = magnitude - 2.5 * np.log10(measured / budget.source_e)
            error = _MAG_PER_LN * np.sqrt(budget.variance(measured.clip(0))) / measured
        if not conditions.photometry.extinction_corrected:
            observed = observed + budget.extinction_mag
        columns = {"extinction_mag": budget.extinction_mag, "saturated": saturated}
        if "elevation_deg" not in geometry.table:
            columns["elevation_deg"] = elevation
        if "airmass" not in geometry.table:
            columns["airmass"] = budget.airmass
        drop = {"saturated": saturated} if conditions.photometry.saturated == "drop" else {}
        return Measurement(
            np.where(detected, observed, np.nan),
            np.where(detected, error, np.nan),
            columns,
            drop,
        )

    def describe(self) -> str:
        return "conditions " + " ".join(
            f"{table}.{key}={json.dumps(value)}"
            for table, values in self.conditions.to_mapping().items()
            for key, value in values.items()
        )
