"""Light-curve simulation: attitude truth, rendering, and measurement noise.

:func:`simulate` propagates the attitude from the first epoch of a geometry table with the
attitude core's DOP853 integrator (``torque-free``, the default) or follows a stabilised
attitude profile of :mod:`lightcurve.photometry.profiles` (``inertial``, ``nadir``,
``sun-pointing``, with a fixed offset; the rates are those of the attitude sequence), renders the
magnitudes with :class:`~lightcurve.photometry.render.Renderer`, adds noise, and returns an
observation table with ``mag``, ``mag_err`` and the truth columns ``q1 q2 q3 q4 wx wy wz`` (rad/s).
An articulated shape (:class:`~shapes.articulation.ArticulatedModel`) is rendered by
:class:`~lightcurve.photometry.articulated.ArticulatedRenderer` (scheduled joints read their columns
from the geometry table) and every part's joint angle is written as ``joint_<part>_deg``.

The noise models (:class:`GaussianNoise`, :class:`CCDNoise`, :class:`ObservingNoise`) live
in :mod:`lightcurve.photometry.noise` and are re-exported here.

Epochs when the object is dark (no lit facet visible) and, with the photon-counting models,
non-detections (measured counts ≤ 0) cannot be measured: they are dropped and counted in
the metadata (``dropped_dark``, ``dropped_nondetections``), as are rows a noise model asks
to drop (``dropped_<reason>``, e.g. ``dropped_saturated``).
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

from filters.attitude import quaternion_normalize, validate_inertia
from lightcurve.io.observations import (
    TRUTH_COLUMNS,
    Observations,
    validate_table,
)
from lightcurve.photometry.articulated import ArticulatedRenderer, scheduled_columns
from lightcurve.photometry.bands import band_header, band_offset
from lightcurve.photometry.earthshine import (
    EARTH_ALBEDO,
    earthshine_applies,
    known_positions,
    sun_and_earth_flux,
)
from lightcurve.photometry.noise import (
    CCDNoise,
    GaussianNoise,
    Measurement,
    NoiseModel,
    ObservingNoise,
)
from lightcurve.photometry.profiles import PROFILES, offset_quaternion, profile_states
from lightcurve.photometry.render import Renderer, flux_to_magnitude
from shapes import FacetModel
from shapes.articulation import ArticulatedModel

__all__ = [
    "CCDNoise",
    "GaussianNoise",
    "NoiseModel",
    "ObservingNoise",
    "simulate",
    "truth_states",
]


def truth_states(
    times: np.ndarray, q0: np.ndarray, omega0: np.ndarray, inertia: np.ndarray
) -> np.ndarray:
    """Torque-free states at ``times`` from ``[q0, ω0]`` at ``times[0]``.

    scipy's DOP853 at rtol = atol = 1e-12, as the attitude core's
    :func:`~filters.attitude.propagate`, with the compiled right-hand side
    :func:`lightcurve.photometry.kernels.dynamics.torque_free_rate` (one state: ~30× cheaper per
    call than the batched array-API form, which dominated long simulations). The output
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
    from lightcurve.photometry.kernels.dynamics import torque_free_rate

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
    *,
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
    shape: FacetModel | ArticulatedModel,
    *,
    q0: np.ndarray | None = None,
    omega0: np.ndarray | None = None,
    inertia: np.ndarray | None = None,
    noise: NoiseModel | None = None,
    shadows: str = "auto",
    seed: int | np.random.Generator | None = None,
    profile: str = "torque-free",
    offset_deg: np.ndarray | None = None,
    yaw_steering: bool = False,
    band: tuple[str, str] | None = None,
    magnitude_offset: float = 0.0,
    earthshine: str = "auto",
) -> Observations:
    """Simulate a light curve over the epochs of a geometry table.

    Parameters
    ----------
    geometry : Observations
        Epochs and Sun/observer vectors (``mag`` columns, if any, are replaced).
    shape : FacetModel or ArticulatedModel
        Shape with materials (and parts).
    q0 : (4,) array or None
        Attitude at the first epoch (inertial → body) of the ``torque-free`` profile; the
        fixed reference attitude of the ``inertial`` profile (default the identity);
        unused by the other profiles.
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
        Attitude profile (:mod:`lightcurve.photometry.profiles`); ``nadir`` needs the ``obj_*``
        columns of ``lightcurve geometry``.
    offset_deg : (3,) array, optional
        Fixed offset ``[roll, pitch, yaw]`` (deg) of a stabilised profile.
    yaw_steering : bool
        Yaw-steer the ``nadir`` profile.
    band : (str, str), optional
        ``(band, system)`` of the magnitudes (:mod:`lightcurve.photometry.bands`, e.g.
        ``("r", "ab")``): the Sun's magnitude in that band replaces the V magnitude of
        the measurement model (a grey object), and the header records it.
    magnitude_offset : float
        Added to every magnitude before the noise (mag): a calibrated albedo–area scale
        (:mod:`lightcurve.photometry.calibration`); recorded in the header when not 0.
    earthshine : {"auto", "on", "off"}
        Add the light of a Lambertian Earth (:mod:`lightcurve.photometry.earthshine`, the
        default quadrature) and an ``earthshine_fraction`` column (its share of the flux):
        ``"auto"`` when the table carries the object's position (``obj_*`` columns) and the
        object is below :data:`~lightcurve.photometry.earthshine.EARTHSHINE_ALTITUDE_KM` at
        some epoch; ``"on"`` needs the position. The header's ``earthshine`` records it.

    Returns
    -------
    Observations
        With ``mag``, ``mag_err`` and the truth columns; metadata records the shape, the
        initial state, the inertia, the noise model and the seed.
    """
    rng = np.random.default_rng(seed)
    inertia = shape.inertia if inertia is None else np.asarray(inertia, float)
    states, attitude_meta = _attitude(
        geometry,
        profile,
        q0=q0,
        omega0=omega0,
        inertia=inertia,
        offset_deg=offset_deg,
        yaw_steering=yaw_steering,
    )
    extra: dict[str, np.ndarray] = {}  # columns added to the table: joint angles, earthshine
    position = known_positions(geometry)
    with_earth = earthshine_applies(earthshine, position)
    columns = None
    if isinstance(shape, ArticulatedModel):
        renderer = ArticulatedRenderer(shape, shadows=shadows)
        columns = scheduled_columns(shape, geometry.table)
        angles = renderer.joint_angles(states[:, :4], geometry.sun_vectors, columns)
        for part, angle in zip(shape.articulation.names, angles, strict=True):
            extra[f"joint_{part}_deg"] = angle
    else:
        renderer = Renderer(shape, shadows=shadows)
    sun, observer = geometry.sun_vectors, geometry.observer_vectors
    sunlit, earthlit = sun_and_earth_flux(
        renderer, states[:, :4], sun, observer, position if with_earth else None, columns=columns
    )
    flux = sunlit + earthlit
    if with_earth:
        with np.errstate(invalid="ignore", divide="ignore"):
            extra["earthshine_fraction"] = np.where(flux > 0, earthlit / flux, 0.0)
    magnitude = flux_to_magnitude(flux)
    if band is not None:
        magnitude = magnitude + band_offset(*band)
    magnitude = magnitude + magnitude_offset
    dark = ~np.isfinite(magnitude)
    if noise is None:
        measurement = Measurement(magnitude, np.full_like(magnitude, 1e-6))
    else:
        measurement = noise.measure(np.where(dark, 0.0, magnitude), geometry, rng)
    measured = measurement.magnitude
    nondetected = ~dark & ~np.isfinite(measured)
    keep = ~dark & ~nondetected
    dropped = {reason: mask & keep for reason, mask in measurement.drop.items()}
    for mask in dropped.values():
        keep &= ~mask
    table = geometry.table.loc[keep].drop(columns=["mag", "mag_err"], errors="ignore").copy()
    table["mag"] = measured[keep]
    table["mag_err"] = measurement.error[keep]
    for name, values in measurement.columns.items():
        table[name] = np.asarray(values)[keep]
    for k, column in enumerate(TRUTH_COLUMNS):
        table[column] = states[keep, k]
    for column, values in extra.items():
        table[column] = np.asarray(values)[keep]
    meta = dict(geometry.meta)
    meta.update(
        {
            "simulated": "true",
            "shape": shape.name,
            **attitude_meta,
            "inertia": ",".join(f"{v:.12g}" for v in np.asarray(inertia).ravel()),
            "noise": noise.describe() if noise is not None else "none",
            "shadows": renderer.shadows,
            "earthshine": f"lambertian earth, albedo {EARTH_ALBEDO}" if with_earth else "off",
            "seed": str(seed) if not isinstance(seed, np.random.Generator) else "generator",
        }
    )
    if band is not None:
        meta.update(band_header(*band))
    if magnitude_offset:
        meta["magnitude_offset"] = f"{magnitude_offset:.6g}"
    if dark.any():
        meta["dropped_dark"] = str(int(dark.sum()))
    if nondetected.any():
        meta["dropped_nondetections"] = str(int(nondetected.sum()))
    for reason, mask in dropped.items():
        if mask.any():
            meta[f"dropped_{reason}"] = str(int(mask.sum()))
    if not keep.any():
        raise ValueError(
            "the object is dark or undetected at every epoch"
            + (f" (or dropped as {', '.join(dropped)})" if dropped else "")
        )
    return Observations(validate_table(table, geometry.source, meta), meta, geometry.source)
