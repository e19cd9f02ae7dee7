"""Observing conditions: telescope, detector, site and sky, and the signal budget they give.

An :class:`ObservingConditions` groups five tables — the layout of the conditions TOML files
(``lightcurve/data/telescopes/half_metre.toml`` holds the defaults, a 0.5 m telescope):

``[telescope]`` aperture, central obstruction, system throughput;
``[detector]`` pixel scale, read noise, gain, dark current, full well, ADC range;
``[site]`` altitude, extinction coefficient, seeing and its profile, scintillation;
``[sky]`` zenith sky brightness and whether it brightens with airmass;
``[photometry]`` band zero point, exposure, aperture and sky-annulus size, and the
reduction choices (extinction correction, what to do with saturated points).

:meth:`ObservingConditions.budget` turns magnitudes above the atmosphere and elevations into
the expected electrons of the CCD equation (Howell 2006, "Handbook of CCD Astronomy", 2nd
ed., eq. 4.4) with extinction, seeing losses, sky, dark current, read noise and
scintillation (the modified Young formula of Osborn et al. 2015, "Atmospheric scintillation
in astronomical photometry", MNRAS 452, 1707, eq. 7 with the empirical factor ``C_Y``).
The formulas are collected in ``docs/rendering.md``; the noise draws are in
:mod:`lightcurve.photometry.noise`.
"""

from __future__ import annotations

import difflib
import math
import re
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field, fields
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from lightcurve.photometry.psf import PROFILES, SeeingProfile
from lightcurve.sky.topocentric import airmass

__all__ = [
    "TELESCOPES_PATH",
    "ConditionsError",
    "Detector",
    "ObservingConditions",
    "Photometry",
    "SignalBudget",
    "SiteConditions",
    "Sky",
    "Telescope",
    "load_conditions",
    "scintillation_sigma",
    "seeing_fwhm",
    "sky_brightness",
]

TELESCOPES_PATH = Path(str(resources.files("lightcurve").joinpath("data", "telescopes")))
#: Scale height of the optical turbulence in Young's formula (m; Osborn et al. 2015).
TURBULENCE_SCALE_HEIGHT_M = 8000.0
SATURATED_POLICIES = ("flag", "drop")


class ConditionsError(ValueError):
    """A bad observing-conditions value; ``table`` and ``key`` name the field."""

    def __init__(self, message: str, table: str | None = None, key: str | None = None) -> None:
        self.table, self.key, self.detail = table, key, message
        where = f"[{table}] {key}: " if table and key else ""
        super().__init__(where + message)


# Rules: name → (test on a finite number, wording in messages).
_RULES = {
    "positive": (lambda v: v > 0, "> 0"),
    "non-negative": (lambda v: v >= 0, ">= 0"),
    "fraction": (lambda v: 0 < v <= 1, "in (0, 1]"),
    "above one": (lambda v: v > 1, "> 1"),
    "finite": (lambda v: True, "finite"),
    "ground": (lambda v: -500 <= v <= 9000, "in [-500, 9000] (metres above the ellipsoid)"),
}


def _number(default: float | None, rule: str, unit: str) -> Any:
    return field(default=default, metadata={"rule": rule, "unit": unit})


def _choice(default: str, choices: Sequence[str]) -> Any:
    return field(default=default, metadata={"choices": tuple(choices)})


def _flag(default: bool) -> Any:
    return field(default=default, metadata={"bool": True})


class _Table:
    """Validation shared by the five tables (field metadata → checks)."""

    TABLE = ""

    def __post_init__(self) -> None:
        for spec in fields(self):  # type: ignore[arg-type]
            value = getattr(self, spec.name)
            meta = spec.metadata
            if "choices" in meta:
                if value not in meta["choices"]:
                    raise ConditionsError(
                        f"must be one of {', '.join(meta['choices'])}, got {value!r}",
                        self.TABLE,
                        spec.name,
                    )
            elif "bool" in meta:
                if not isinstance(value, bool):
                    raise ConditionsError(
                        f"must be true or false, got {value!r}", self.TABLE, spec.name
                    )
            elif value is not None or spec.default is not None:
                object.__setattr__(self, spec.name, self._checked(spec.name, value, meta))

    def _checked(self, name: str, value: Any, meta: Mapping[str, str]) -> float:
        test, wording = _RULES[meta["rule"]]
        unit = f" ({meta['unit']})" if meta["unit"] else ""
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ConditionsError(f"must be a number{unit}, got {value!r}", self.TABLE, name)
        if not (math.isfinite(value) and test(value)):
            raise ConditionsError(f"must be {wording}{unit}, got {value!r}", self.TABLE, name)
        return float(value)


@dataclass(frozen=True)
class Telescope(_Table):
    """``[telescope]``: aperture diameter and central obstruction (m), system throughput.

    ``throughput`` is the fraction of the band's photons arriving above the atmosphere that
    become photo-electrons (mirrors, filter, window, quantum efficiency); the atmosphere is
    the site's extinction.
    """

    TABLE = "telescope"
    aperture_m: float = _number(0.5, "positive", "m")
    obstruction_m: float = _number(0.2, "non-negative", "m")
    throughput: float = _number(0.5, "fraction", "")

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.obstruction_m >= self.aperture_m:
            raise ConditionsError(
                f"must be smaller than aperture_m = {self.aperture_m:g} m, "
                f"got {self.obstruction_m:g}",
                self.TABLE,
                "obstruction_m",
            )

    @property
    def collecting_area_m2(self) -> float:
        """Unobstructed collecting area ``π/4 (D² − d²)`` (m²)."""
        return 0.25 * math.pi * (self.aperture_m**2 - self.obstruction_m**2)


@dataclass(frozen=True)
class Detector(_Table):
    """``[detector]``: pixel scale, read noise, gain, dark current and saturation.

    A pixel saturates at ``min(full_well_e, gain_e_per_adu · adc_max_adu)`` electrons.
    """

    TABLE = "detector"
    pixel_scale_arcsec: float = _number(1.0, "positive", "arcsec per pixel")
    read_noise_e: float = _number(10.0, "non-negative", "e- rms per pixel")
    gain_e_per_adu: float = _number(1.5, "positive", "e-/ADU")
    dark_current_e_per_s: float = _number(0.1, "non-negative", "e-/s per pixel")
    full_well_e: float = _number(100_000.0, "positive", "e-")
    adc_max_adu: float = _number(65_535.0, "positive", "ADU")

    @property
    def saturation_e(self) -> float:
        """Electrons at which a pixel saturates (full well or the ADC's range)."""
        return min(self.full_well_e, self.gain_e_per_adu * self.adc_max_adu)

    @property
    def read_variance_e2(self) -> float:
        """Read noise plus gain quantisation per pixel, ``R² + g²/12`` (e⁻²)."""
        return self.read_noise_e**2 + self.gain_e_per_adu**2 / 12.0


@dataclass(frozen=True)
class SiteConditions(_Table):
    """``[site]``: altitude, extinction, seeing and scintillation.

    ``altitude_m`` may be left out: the altitude of the site recorded in the geometry file
    is used. ``seeing_fwhm_arcsec`` is the FWHM at the zenith; ``scintillation_coefficient``
    is Osborn et al.'s (2015) empirical ``C_Y`` (1.0: Young's 1967 formula; 0: no
    scintillation).
    """

    TABLE = "site"
    altitude_m: float | None = _number(None, "ground", "m")
    extinction_mag_per_airmass: float = _number(0.2, "non-negative", "mag per airmass")
    seeing_fwhm_arcsec: float = _number(2.0, "positive", "arcsec at the zenith")
    seeing_profile: str = _choice("moffat", PROFILES)
    moffat_beta: float = _number(4.765, "above one", "")
    scintillation_coefficient: float = _number(1.5, "non-negative", "C_Y")

    @property
    def profile(self) -> SeeingProfile:
        return SeeingProfile(self.seeing_profile, self.moffat_beta)


@dataclass(frozen=True)
class Sky(_Table):
    """``[sky]``: zenith sky surface brightness (mag arcsec⁻²) in the band.

    With ``airmass_brightening`` the sky brightens away from the zenith as in Krisciunas &
    Schaefer (1991), "A model of the brightness of moonlight", PASP 103, 1033, eq. 2.
    """

    TABLE = "sky"
    brightness_mag_arcsec2: float = _number(21.0, "finite", "mag/arcsec^2 at the zenith")
    airmass_brightening: bool = _flag(True)


@dataclass(frozen=True)
class Photometry(_Table):
    """``[photometry]``: the band's zero point, exposure, apertures and reduction choices.

    ``zero_point_mag`` is the magnitude that gives 1 photon s⁻¹ m⁻² in the band above the
    atmosphere (V: 3640 Jy at V = 0 over Δλ/λ = 0.16, Bessell 1979, i.e. 8.8·10⁹ photons
    s⁻¹ m⁻², 24.86 mag). ``sky_annulus_px`` is the number of pixels the sky level is
    estimated from (Howell's ``n_B``). ``extinction_corrected``: report magnitudes corrected
    to above the atmosphere (as a reduction against standard stars does) or as observed
    through the atmosphere. ``saturated``: keep saturated points with a flag, or drop them.
    """

    TABLE = "photometry"
    zero_point_mag: float = _number(24.86, "finite", "mag for 1 photon/s/m^2")
    exposure_s: float = _number(1.0, "positive", "s")
    aperture_radius_arcsec: float = _number(3.0, "positive", "arcsec")
    sky_annulus_px: float = _number(300.0, "positive", "pixels")
    extinction_corrected: bool = _flag(True)
    saturated: str = _choice("flag", SATURATED_POLICIES)


def seeing_fwhm(zenith_fwhm_arcsec: float, airmass_: np.ndarray) -> np.ndarray:
    """Seeing FWHM at an airmass: ``FWHM_z · X^{3/5}`` (arcsec).

    Roddier (1981), "The effects of atmospheric turbulence in optical astronomy", Progress
    in Optics 19, 281: the FWHM scales as ``r₀^{−1} ∝ (sec z)^{3/5}``.
    """
    return zenith_fwhm_arcsec * np.asarray(airmass_, dtype=float) ** 0.6


def scintillation_sigma(
    aperture_m: float,
    exposure_s: np.ndarray,
    airmass_: np.ndarray,
    altitude_m: float,
    coefficient: float = 1.5,
) -> np.ndarray:
    """Relative rms flux fluctuation from scintillation (long exposures).

    Osborn et al. (2015), "Atmospheric scintillation in astronomical photometry", MNRAS 452,
    1707, eq. 7 (Young 1967 with Dravins et al.'s constants) times the empirical
    correction ``C_Y``:

    ``σ² = 10⁻⁵ C_Y² D^{−4/3} t^{−1} X³ exp(−2 h / H)``, ``H = 8000 m``,

    ``D`` the aperture (m), ``t`` the exposure (s), ``X`` the airmass (``sec z`` in the
    paper), ``h`` the site's altitude (m).

    Returns
    -------
    numpy.ndarray
        σ (fraction of the flux).
    """
    variance = (
        1e-5
        * aperture_m ** (-4.0 / 3.0)
        / np.asarray(exposure_s, dtype=float)
        * np.asarray(airmass_, dtype=float) ** 3
        * math.exp(-2.0 * altitude_m / TURBULENCE_SCALE_HEIGHT_M)
    )
    return coefficient * np.sqrt(variance)


def sky_brightness(
    zenith_mag_arcsec2: float,
    extinction_mag_per_airmass: float,
    elevation_deg: np.ndarray,
) -> np.ndarray:
    """Sky surface brightness away from the zenith (mag arcsec⁻²).

    Krisciunas & Schaefer (1991), eq. 2: ``B(z) = B_zen · 10^{−0.4 k (X_s − 1)} · X_s`` with
    ``X_s = (1 − 0.96 sin² z)^{−1/2}`` (the airglow layer's path length), i.e.
    ``μ(z) = μ_zen + k (X_s − 1) − 2.5 log₁₀ X_s``.
    """
    zenith_distance = np.deg2rad(90.0 - np.asarray(elevation_deg, dtype=float))
    path = 1.0 / np.sqrt(1.0 - 0.96 * np.sin(zenith_distance) ** 2)
    return zenith_mag_arcsec2 + extinction_mag_per_airmass * (path - 1.0) - 2.5 * np.log10(path)


@dataclass(frozen=True)
class SignalBudget:
    """Expected electrons of one exposure per row (the terms of the CCD equation).

    Attributes
    ----------
    source_e : (n,) array
        Source electrons inside the photometric aperture.
    total_source_e : (n,) array
        Source electrons over the whole seeing disc.
    sky_e, dark_e : (n,) array
        Sky and dark-current electrons per pixel.
    peak_e : (n,) array
        Source electrons in the central pixel (central intensity × pixel area).
    scintillation : (n,) array
        Relative rms flux fluctuation.
    airmass, extinction_mag, fwhm_arcsec, aperture_fraction : (n,) array
    n_pixels, sky_pixels, read_variance_e2, saturation_e : float
        ``n_pix``, ``n_B``, ``R² + g²/12`` and the saturation level of a pixel.
    """

    source_e: np.ndarray
    total_source_e: np.ndarray
    sky_e: np.ndarray
    dark_e: np.ndarray
    peak_e: np.ndarray
    scintillation: np.ndarray
    airmass: np.ndarray
    extinction_mag: np.ndarray
    fwhm_arcsec: np.ndarray
    aperture_fraction: np.ndarray
    n_pixels: float
    sky_pixels: float
    read_variance_e2: float
    saturation_e: float

    @property
    def background_variance(self) -> np.ndarray:
        """``n_pix (1 + n_pix/n_B)(N_S + N_D + R² + g²/12)`` (e⁻², Howell 2006 eq. 4.4)."""
        per_pixel = self.sky_e + self.dark_e + self.read_variance_e2
        return self.n_pixels * (1.0 + self.n_pixels / self.sky_pixels) * per_pixel

    def variance(self, source_e: np.ndarray) -> np.ndarray:
        """Variance of the sky-subtracted aperture sum for a source signal (e⁻²).

        Poisson ``N*``, scintillation ``(σ_sc N*)²`` and the background term.
        """
        source_e = np.asarray(source_e, dtype=float)
        return source_e + (self.scintillation * source_e) ** 2 + self.background_variance

    @property
    def snr(self) -> np.ndarray:
        """Expected signal-to-noise ratio ``N* / σ``."""
        return self.source_e / np.sqrt(self.variance(self.source_e))

    @property
    def magnitude_error(self) -> np.ndarray:
        """Expected 1σ magnitude error, ``2.5 log₁₀(e) / SNR`` (mag)."""
        return 2.5 / math.log(10.0) / self.snr


@dataclass(frozen=True)
class ObservingConditions:
    """Telescope, detector, site, sky and photometry (see the module docstring)."""

    telescope: Telescope = field(default_factory=Telescope)
    detector: Detector = field(default_factory=Detector)
    site: SiteConditions = field(default_factory=SiteConditions)
    sky: Sky = field(default_factory=Sky)
    photometry: Photometry = field(default_factory=Photometry)

    @classmethod
    def tables(cls) -> dict[str, type]:
        """Table name → its dataclass."""
        return {spec.name: spec.default_factory for spec in fields(cls)}  # type: ignore[misc]

    @classmethod
    def from_mapping(cls, mapping: Mapping[str, Any]) -> ObservingConditions:
        """Build from a nested mapping ``{table: {key: value}}`` (as read from TOML).

        Raises
        ------
        ConditionsError
            For an unknown table or key (with the closest known name) or a bad value.
        """
        tables = cls.tables()
        values = {}
        for name, content in mapping.items():
            if name not in tables:
                raise ConditionsError(
                    f"unknown table [{name}]{_close(name, tables)}; tables: "
                    + ", ".join(f"[{t}]" for t in tables),
                    name,
                )
            if not isinstance(content, Mapping):
                raise ConditionsError(f"[{name}] must be a table of key = value pairs", name)
            known = [spec.name for spec in fields(tables[name])]
            for key in content:
                if key not in known:
                    raise ConditionsError(
                        f"unknown key{_close(key, known)}; keys: {', '.join(known)}", name, key
                    )
            values[name] = tables[name](**content)
        return cls(**values)

    def to_mapping(self) -> dict[str, dict[str, Any]]:
        """The nested mapping of every table (unset ``altitude_m`` left out)."""
        return {
            name: {k: v for k, v in asdict(getattr(self, name)).items() if v is not None}
            for name in self.tables()
        }

    def budget(
        self,
        magnitude: np.ndarray,
        elevation_deg: np.ndarray,
        exposure_s: np.ndarray,
        altitude_m: float,
    ) -> SignalBudget:
        """Expected electrons for magnitudes above the atmosphere at the given elevations.

        Parameters
        ----------
        magnitude : (n,) array
            Magnitude above the atmosphere in the band.
        elevation_deg : (n,) array
            Geometric elevation of the object (deg, > 0).
        exposure_s : (n,) array or float
            Exposure time (s).
        altitude_m : float
            Site altitude (m), for the scintillation.

        Returns
        -------
        SignalBudget
            ``N* = t · A · τ · 10^{−0.4 (m + k X − ZP)} · f_ap``, sky per pixel
            ``t · A · τ · p² · 10^{−0.4 (μ − ZP)}``, dark ``D t``.
        """
        tel, det, site, sky, phot = (
            self.telescope,
            self.detector,
            self.site,
            self.sky,
            self.photometry,
        )
        elevation = np.asarray(elevation_deg, dtype=float)
        t = np.broadcast_to(np.asarray(exposure_s, dtype=float), elevation.shape)
        x = airmass(elevation)
        extinction = site.extinction_mag_per_airmass * x
        electrons_zero_mag = (
            t * tel.collecting_area_m2 * tel.throughput * 10.0 ** (0.4 * phot.zero_point_mag)
        )
        fwhm = seeing_fwhm(site.seeing_fwhm_arcsec, x)
        profile = site.profile
        fraction = profile.enclosed_fraction(phot.aperture_radius_arcsec, fwhm)
        total = electrons_zero_mag * 10.0 ** (-0.4 * (np.asarray(magnitude, float) + extinction))
        mu = (
            sky_brightness(sky.brightness_mag_arcsec2, site.extinction_mag_per_airmass, elevation)
            if sky.airmass_brightening
            else np.full_like(elevation, sky.brightness_mag_arcsec2)
        )
        pixel_area = det.pixel_scale_arcsec**2
        return SignalBudget(
            source_e=total * fraction,
            total_source_e=total,
            sky_e=electrons_zero_mag * pixel_area * 10.0 ** (-0.4 * mu),
            dark_e=det.dark_current_e_per_s * t,
            peak_e=total * profile.peak_intensity(fwhm) * pixel_area,
            scintillation=scintillation_sigma(
                tel.aperture_m, t, x, altitude_m, site.scintillation_coefficient
            ),
            airmass=x,
            extinction_mag=extinction,
            fwhm_arcsec=fwhm,
            aperture_fraction=fraction,
            n_pixels=math.pi * phot.aperture_radius_arcsec**2 / pixel_area,
            sky_pixels=phot.sky_annulus_px,
            read_variance_e2=det.read_variance_e2,
            saturation_e=det.saturation_e,
        )


def _close(name: str, known: Sequence[str]) -> str:
    match = difflib.get_close_matches(name, list(known), n=1, cutoff=0.6)
    return f" (did you mean '{match[0]}'?)" if match else ""


def _parse_override(text: str) -> tuple[str, str, Any]:
    """``TABLE.KEY=VALUE`` → (table, key, value); the value is read as TOML, else a string."""
    key, sep, raw = text.partition("=")
    parts = key.strip().split(".")
    if not sep or len(parts) != 2 or not all(re.fullmatch(r"[A-Za-z_][\w-]*", p) for p in parts):
        raise ValueError(
            f"--condition expects TABLE.KEY=VALUE (e.g. site.seeing_fwhm_arcsec=1.5), got {text!r}"
        )
    try:
        value = tomllib.loads(f"v = {raw.strip()}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw.strip()
    return parts[0], parts[1], value


def _resolve(spec: str | Path) -> Path:
    path = Path(spec)
    if path.is_file():
        return path
    named = TELESCOPES_PATH / f"{spec}.toml"
    if path.suffix == "" and path.name == str(spec) and named.is_file():
        return named
    known = sorted(p.stem for p in TELESCOPES_PATH.glob("*.toml"))
    raise FileNotFoundError(
        f"{spec}: no such conditions file and no built-in telescope of that name "
        f"(known: {', '.join(known)})"
    )


def load_conditions(
    spec: str | Path | None = None, overrides: Sequence[str] | Mapping[str, Any] = ()
) -> ObservingConditions:
    """Observing conditions from a TOML file (or the defaults) with overrides.

    Parameters
    ----------
    spec : str or Path, optional
        A TOML file, or the name of one in ``lightcurve/data/telescopes/`` (``"half_metre"``); None
        starts from the defaults (the same values as ``half_metre``).
    overrides : sequence of str or mapping
        ``"TABLE.KEY=VALUE"`` strings (values in TOML syntax; bare words are strings) or a
        nested mapping ``{table: {key: value}}``; they replace the file's values.

    Raises
    ------
    ValueError
        A one-line message naming the file (or ``--condition``), the table and the key.
    """
    mapping: dict[str, dict[str, Any]] = {}
    origin: dict[tuple[str, str], str] = {}
    if spec is not None:
        path = _resolve(spec)
        try:
            content = tomllib.loads(path.read_text(encoding="utf-8"))
        except tomllib.TOMLDecodeError as exc:
            raise ValueError(f"{path}: invalid TOML: {exc}") from None
        for table, values in content.items():
            mapping[table] = dict(values) if isinstance(values, Mapping) else values
            for key in values if isinstance(values, Mapping) else ():
                origin[(table, key)] = str(path)
        default_origin = str(path)
    else:
        default_origin = "observing conditions"
    items = (
        [(t, k, v) for t, table in overrides.items() for k, v in table.items()]
        if isinstance(overrides, Mapping)
        else [_parse_override(text) for text in overrides]
    )
    for table, key, value in items:
        target = mapping.setdefault(table, {})
        if not isinstance(target, dict):
            target = mapping[table] = {}
        target[key] = value
        origin[(table, key)] = "--condition"
    try:
        return ObservingConditions.from_mapping(mapping)
    except ConditionsError as exc:
        where = origin.get((exc.table or "", exc.key or "")) or next(
            (label for (table, _), label in origin.items() if table == exc.table), default_origin
        )
        if where == "--condition" and exc.key:
            raise ValueError(f"--condition {exc.table}.{exc.key}: {exc.detail}") from None
        raise ValueError(f"{where}: {exc}") from None
