"""Light-curve simulation: attitude truth, rendering, and measurement noise.

:func:`simulate` propagates the attitude from the first epoch of a geometry table with the
attitude core's DOP853 integrator (``torque-free``, the default) or follows a stabilised
attitude profile of :mod:`lightcurve.profiles` (``inertial``, ``nadir``, ``sun-pointing``,
with a fixed offset; the rates are those of the attitude sequence), renders the magnitudes with
:class:`~lightcurve.render.Renderer`, adds noise, and returns an observation table with
``mag``, ``mag_err`` and the truth columns ``q1 q2 q3 q4 wx wy wz`` (rad/s).

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

Epochs when the object is dark (no lit facet visible) and, with the CCD model,
non-detections (measured counts ≤ 0) cannot be measured: they are dropped and counted in
the metadata (``dropped_dark``, ``dropped_nondetections``).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Protocol

import numpy as np
from scipy.integrate import solve_ivp

from filters.attitude import quaternion_normalize, validate_inertia
from lightcurve.observations import TRUTH_COLUMNS, Observations, validate_table
from lightcurve.profiles import PROFILES, offset_quaternion, profile_states
from lightcurve.render import Renderer
from shapes import FacetModel

__all__ = ["CCDNoise", "GaussianNoise", "NoiseModel", "simulate", "truth_states"]

_MAG_PER_LN = 2.5 / math.log(10.0)


class NoiseModel(Protocol):
    """Turns true magnitudes into measured magnitudes and their 1σ errors."""

    def apply(
        self, magnitude: np.ndarray, exposure_s: np.ndarray | None, rng: np.random.Generator
    ) -> tuple[np.ndarray, np.ndarray]: ...

    def describe(self) -> str: ...


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

    def describe(self) -> str:
        return "ccd " + " ".join(f"{k}={v}" for k, v in asdict(self).items())


def truth_states(
    times: np.ndarray, q0: np.ndarray, omega0: np.ndarray, inertia: np.ndarray
) -> np.ndarray:
    """Torque-free states at ``times`` from ``[q0, ω0]`` at ``times[0]``.

    scipy's DOP853 at rtol = atol = 1e-12, as the attitude core's
    :func:`~filters.attitude.propagate`, with the compiled right-hand side
    :func:`lightcurve.kernels.dynamics.torque_free_rate` (one state: ~30× cheaper per call
    than the batched array-API form, which dominated long simulations). The output
    quaternions are renormalised.

    Parameters
    ----------
    times : (n,) array
        Seconds, strictly increasing.
    q0 : (4,) array
        Attitude at ``times[0]`` (inertial → body), normalised here.
    omega0 : (3,) array
        Body rates at ``times[0]`` (rad/s).
    inertia : (3, 3) array
        Body-frame inertia.

    Returns
    -------
    (n, 7) numpy.ndarray
        ``[q1..q4, ωx, ωy, ωz]`` with the quaternion sign continuous in time.
    """
    from lightcurve.kernels.dynamics import torque_free_rate

    j = validate_inertia(inertia)
    j_inv = np.linalg.inv(j)
    t = np.asarray(times, dtype=float)
    if t.ndim != 1 or t.size == 0 or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise ValueError("times must be a non-empty, finite, strictly increasing 1-D sequence")
    x0 = np.concatenate([quaternion_normalize(np.asarray(q0, float)), np.asarray(omega0, float)])
    if not np.all(np.isfinite(x0)):
        raise ValueError(f"initial state must be finite, got {x0}")
    if t.size == 1:
        return x0[None]
    solution = solve_ivp(
        lambda _t, x: torque_free_rate(x, j, j_inv),
        (t[0], t[-1]),
        x0,
        method="DOP853",
        t_eval=t,
        rtol=1e-12,
        atol=1e-12,
    )
    if not solution.success:
        raise RuntimeError(f"attitude propagation failed: {solution.message}")
    states = solution.y.T
    states[:, :4] = quaternion_normalize(states[:, :4])
    return states


def _attitude(
    geometry: Observations,
    profile: str,
    q0: np.ndarray | None,
    omega0: np.ndarray | None,
    inertia: np.ndarray,
    offset_deg: np.ndarray | None,
    yaw_steering: bool,
) -> tuple[np.ndarray, dict[str, str]]:
    """True states of the attitude profile and the metadata recording it."""

    def joined(values: np.ndarray) -> str:
        return ",".join(f"{v:.12g}" for v in np.asarray(values, float))

    if profile not in PROFILES:
        raise ValueError(f"profile must be one of {', '.join(PROFILES)}, got {profile!r}")
    if profile == "torque-free":
        if offset_deg is not None or yaw_steering:
            raise ValueError("offsets and yaw steering apply to stabilised profiles only")
        if q0 is None or omega0 is None:
            raise ValueError("the torque-free profile needs q0 and omega0")
        states = truth_states(geometry.times, q0, omega0, inertia)
        return states, {"q0": joined(q0), "omega0_rad_s": joined(omega0)}
    if omega0 is not None:
        raise ValueError(f"omega0 does not apply to the {profile} profile (rates follow it)")
    if q0 is not None and profile != "inertial":
        raise ValueError(f"q0 does not apply to the {profile} profile (it fixes the attitude)")
    states = profile_states(
        geometry,
        profile,
        reference=q0,
        yaw_steering=yaw_steering,
        offset=None if offset_deg is None else offset_quaternion(offset_deg),
    )
    meta = {"profile": profile + (" yaw-steering" if yaw_steering else "")}
    meta["offset_deg"] = joined(np.zeros(3) if offset_deg is None else offset_deg)
    if q0 is not None:
        meta["q_reference"] = joined(q0)
    return states, meta


def simulate(
    geometry: Observations,
    shape: FacetModel,
    q0: np.ndarray | None,
    omega0: np.ndarray | None,
    inertia: np.ndarray | None = None,
    noise: NoiseModel | None = None,
    shadows: str = "auto",
    seed: int | np.random.Generator | None = None,
    profile: str = "torque-free",
    offset_deg: np.ndarray | None = None,
    yaw_steering: bool = False,
) -> Observations:
    """Simulate a light curve over the epochs of a geometry table.

    Parameters
    ----------
    geometry : Observations
        Epochs and Sun/observer vectors (``mag`` columns, if any, are replaced).
    shape : FacetModel
        Shape with materials.
    q0 : (4,) array or None
        Attitude at the first epoch (inertial → body) of the ``torque-free`` profile; the
        fixed reference attitude of the ``inertial`` profile (default the identity);
        unused by the other profiles (give None).
    omega0 : (3,) array or None
        Body rates at the first epoch (rad/s, body frame), ``torque-free`` only.
    inertia : (3, 3) array, optional
        Body-frame inertia; defaults to the shape's.
    noise : NoiseModel, optional
        Measurement noise; without it ``mag`` is exact and ``mag_err`` is 1e-6.
    shadows : str
        Renderer shadow mode (``"auto"``, ``"none"``, ``"table"``, ``"exact"``).
    seed : int or numpy.random.Generator, optional
        Noise seed.
    profile : {"torque-free", "inertial", "nadir", "sun-pointing"}
        Attitude profile (:mod:`lightcurve.profiles`); ``nadir`` needs the ``obj_*``
        columns of ``lightcurve geometry``.
    offset_deg : (3,) array, optional
        Fixed offset ``[roll, pitch, yaw]`` (deg) of a stabilised profile.
    yaw_steering : bool
        Yaw-steer the ``nadir`` profile.

    Returns
    -------
    Observations
        With ``mag``, ``mag_err`` and the truth columns; metadata records the shape, the
        initial state, the inertia, the noise model and the seed.
    """
    rng = np.random.default_rng(seed)
    inertia = shape.inertia if inertia is None else np.asarray(inertia, float)
    states, attitude_meta = _attitude(
        geometry, profile, q0, omega0, inertia, offset_deg, yaw_steering
    )
    renderer = Renderer(shape, shadows=shadows)
    magnitude = renderer.magnitude(states[:, :4], geometry.sun_vectors, geometry.observer_vectors)
    dark = ~np.isfinite(magnitude)
    exposure = geometry.table["exposure_s"].to_numpy() if "exposure_s" in geometry.table else None
    if noise is None:
        measured, error = magnitude, np.full_like(magnitude, 1e-6)
    else:
        measured, error = noise.apply(np.where(dark, 0.0, magnitude), exposure, rng)
    nondetected = ~dark & ~np.isfinite(measured)
    keep = ~dark & ~nondetected
    table = geometry.table.loc[keep].drop(columns=["mag", "mag_err"], errors="ignore").copy()
    table["mag"] = measured[keep]
    table["mag_err"] = error[keep]
    for k, column in enumerate(TRUTH_COLUMNS):
        table[column] = states[keep, k]
    meta = dict(geometry.meta)
    meta.update(
        {
            "simulated": "true",
            "shape": shape.name,
            **attitude_meta,
            "inertia": ",".join(f"{v:.12g}" for v in np.asarray(inertia).ravel()),
            "noise": noise.describe() if noise is not None else "none",
            "shadows": renderer.shadows,
            "seed": str(seed) if not isinstance(seed, np.random.Generator) else "generator",
        }
    )
    if dark.any():
        meta["dropped_dark"] = str(int(dark.sum()))
    if nondetected.any():
        meta["dropped_nondetections"] = str(int(nondetected.sum()))
    if not keep.any():
        raise ValueError("the object is dark or undetected at every epoch")
    return Observations(validate_table(table, geometry.source, meta), meta, geometry.source)
