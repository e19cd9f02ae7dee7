"""Simulated GPS L1 code and carrier-phase measurements of spacecraft receivers.

For receiver ``r`` (position ``x_r`` at GPS time ``t``, week-start inertial frame of
:mod:`filters.gnss.constellation`) and satellite ``s``:

``P = ρ + c (δt_r − δt^s) + m_P + ε_P``                  (code pseudorange, m)
``φ = [ρ + c (δt_r − δt^s) + m_φ + ε_φ] / λ + N + φ_r0 − φ^s0``   (carrier phase, cycles)

with the geometric range ``ρ = |x^s(t − τ) − x_r(t)|`` solved for the signal travel time
``τ = ρ / c`` (light-time iteration), receiver and satellite clock offsets ``δt`` (s),
multipath ``m`` (first-order Gauss–Markov processes, optional), white noise ``ε``, the L1
wavelength ``λ = c / 1575.42 MHz``, an integer ambiguity ``N`` drawn at each acquisition and
changed by cycle slips, and fractional initial phases of the receiver and the satellite
(which, like the clocks, cancel in double differences). Ionosphere, troposphere and
antenna phase-centre effects are not modelled: over short baselines they cancel in
double differences (Misra & Enge, *Global Positioning System*, 2nd ed., ch. 7).

**Visibility.** A receiver tracks a satellite when the line of sight clears the Earth (a
sphere of radius ``EARTH_RADIUS + blockage_altitude``: rays grazing the atmosphere are lost)
and the satellite is above the receiver's elevation mask, measured from the local horizontal
plane (the antenna points to the local zenith). The mask can be raised over time windows
(``obstructions``) to model a partly blocked antenna. A satellite lost and re-acquired gets a
new ambiguity.

**Clocks.** Receivers sample at common GPS epochs (clock-steered receivers); their clock
offsets enter the measurements as ``c δt_r`` with ``δt_r`` a random offset, drift and random
walk. Satellite clocks are the almanac's ``af0 + af1 tk`` plus an error unknown to the user.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from filters.gnss.constellation import GPS_MU, SPEED_OF_LIGHT, Constellation

__all__ = [
    "EARTH_RADIUS",
    "L1_FREQUENCY",
    "L1_WAVELENGTH",
    "GnssObservations",
    "ReceiverModel",
    "elevations",
    "light_time_positions",
    "simulate_observations",
    "transmit_positions",
    "visible_satellites",
]

L1_FREQUENCY = 1575.42e6
"""GPS L1 carrier frequency (Hz)."""

L1_WAVELENGTH = SPEED_OF_LIGHT / L1_FREQUENCY
"""GPS L1 carrier wavelength λ = c / f ≈ 0.1903 m."""

EARTH_RADIUS = 6378.137e3
"""WGS-84 equatorial radius (m): the Earth is a sphere of this radius for blockage."""


@dataclass(frozen=True)
class ReceiverModel:
    """Measurement errors and tracking of one spacecraft's GNSS receiver (SI units).

    Attributes
    ----------
    code_sigma, phase_sigma : float
        White noise of code pseudoranges and carrier phases (m), 1σ.
    elevation_mask : float
        Elevation mask above the local horizontal (rad; may be negative in orbit).
    obstructions : tuple of (t_start, t_end, mask)
        Windows of GPS time ``[t_start, t_end)`` (s) during which the mask is raised to
        ``mask`` (rad).
    clock_offset_sigma, clock_drift_sigma : float
        Initial receiver clock offset (s) and drift (s/s), 1σ.
    clock_random_walk : float
        Random walk of the clock offset (s/√s).
    cycle_slip_probability : float
        Probability per satellite and epoch of a cycle slip.
    cycle_slip_max : int
        Slips are uniform in ``±1 … ±cycle_slip_max`` cycles.
    multipath_code_sigma, multipath_phase_sigma : float
        Steady-state 1σ of the code and phase multipath errors (m); 0 disables them.
    multipath_time_constant : float
        Correlation time of the multipath processes (s).
    """

    code_sigma: float = 0.5
    phase_sigma: float = 0.003
    elevation_mask: float = math.radians(10.0)
    obstructions: tuple[tuple[float, float, float], ...] = ()
    clock_offset_sigma: float = 1e-4
    clock_drift_sigma: float = 1e-8
    clock_random_walk: float = 1e-10
    cycle_slip_probability: float = 0.0
    cycle_slip_max: int = 10
    multipath_code_sigma: float = 0.0
    multipath_phase_sigma: float = 0.0
    multipath_time_constant: float = 60.0

    def __post_init__(self) -> None:
        for name in ("code_sigma", "phase_sigma", "multipath_time_constant"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be positive, got {value}")
        for name in (
            "clock_offset_sigma",
            "clock_drift_sigma",
            "clock_random_walk",
            "multipath_code_sigma",
            "multipath_phase_sigma",
        ):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be >= 0, got {value}")
        if not 0.0 <= self.cycle_slip_probability <= 1.0:
            raise ValueError(
                f"cycle_slip_probability must be in [0, 1], got {self.cycle_slip_probability}"
            )
        if self.cycle_slip_max < 1:
            raise ValueError(f"cycle_slip_max must be >= 1, got {self.cycle_slip_max}")
        if not -math.pi / 2 <= self.elevation_mask < math.pi / 2:
            raise ValueError(
                f"elevation_mask must be in [-90°, 90°), got {self.elevation_mask} rad"
            )
        for window in self.obstructions:
            if len(window) != 3 or not window[0] < window[1]:
                raise ValueError(f"obstruction windows are (t_start < t_end, mask), got {window}")

    def mask_at(self, t: Any) -> np.ndarray:
        """Elevation mask (rad) at GPS times ``t``: the highest of the base mask and every
        obstruction window containing ``t``."""
        t = np.asarray(t, dtype=float)
        mask = np.full(t.shape, self.elevation_mask)
        for start, end, value in self.obstructions:
            inside = (t >= start) & (t < end)
            mask = np.where(inside, np.maximum(mask, value), mask)
        return mask


@dataclass
class GnssObservations:
    """Code and phase observations of several receivers over a series of epochs.

    Attributes
    ----------
    times : (T,) numpy.ndarray
        GPS epochs (s of the almanac week).
    prn : (n,) numpy.ndarray
        Satellite identifiers, the last axis of the measurement arrays.
    code : (R, T, n) numpy.ndarray
        Pseudoranges (m); NaN where the satellite is not tracked.
    phase : (R, T, n) numpy.ndarray
        Carrier phases (cycles); NaN where not tracked.
    wavelength : float
        Carrier wavelength (m).
    truth : dict[str, numpy.ndarray]
        Simulation truth: ``ambiguity`` (R, T, n) integers ``N``, ``slips`` (R, T, n) cycles
        injected at each epoch, ``elevation`` (R, T, n) rad, ``range`` (R, T, n) m,
        ``visible`` (R, T, n) bool.
    """

    times: np.ndarray
    prn: np.ndarray
    code: np.ndarray
    phase: np.ndarray
    wavelength: float
    truth: dict[str, np.ndarray] = field(default_factory=dict)

    def tracked(self) -> np.ndarray:
        """(R, T, n) bool: finite code and phase."""
        return np.isfinite(self.code) & np.isfinite(self.phase)


def light_time_positions(
    constellation: Constellation, t: Any, receiver: Any, index: Any = None, iterations: int = 3
) -> tuple[np.ndarray, np.ndarray]:
    """Satellite positions at signal transmission for a receiver at ``receiver`` at time ``t``.

    Parameters
    ----------
    constellation : Constellation
    t : (...) array_like
        Reception times (s), broadcast against the satellites (use ``t[..., None]``).
    receiver : (..., 3) array_like
        Receiver positions (m, inertial), broadcast like ``t`` (use ``x[..., None, :]``).
    index : (n,) array_like of int, optional
        Satellites (indices into the almanac); all by default.
    iterations : int
        Light-time iterations (2 reach 1e-9 m for GPS ranges).

    Returns
    -------
    positions : (..., 3) numpy.ndarray
        Satellite positions at ``t − τ`` (m).
    ranges : (...) numpy.ndarray
        Geometric ranges ``|x^s(t − τ) − x_r(t)|`` (m).
    """
    t = np.asarray(t, dtype=float)
    receiver = np.asarray(receiver, dtype=float)
    tau = np.zeros(np.broadcast_shapes(t.shape, receiver.shape[:-1]))
    for _ in range(iterations + 1):
        sat = constellation.positions(t - tau, index)
        rho = np.linalg.norm(sat - receiver, axis=-1)
        tau = rho / SPEED_OF_LIGHT
    return sat, rho


def transmit_positions(
    positions: Any, velocities: Any, receiver: Any, iterations: int = 3
) -> tuple[np.ndarray, np.ndarray]:
    """Satellite positions at signal transmission from their state at reception time.

    ``x^s(t − τ) ≈ x − v τ − ½ (μ / |x|³) x τ²`` (two-body acceleration; the neglected
    third-order term is below 1e-8 m for GPS signal travel times of ~0.07 s), with
    ``τ = |x^s(t − τ) − x_r| / c`` iterated.

    Parameters
    ----------
    positions, velocities : (..., 3) array_like
        Satellite states at the reception time (m, m/s, inertial).
    receiver : (..., 3) array_like
        Receiver positions at the reception time (m), broadcast against the satellites.
    iterations : int
        Light-time iterations.

    Returns
    -------
    positions : (..., 3) numpy.ndarray
        Satellite positions at transmission (m).
    ranges : (...) numpy.ndarray
        Geometric ranges (m).
    """
    x = np.asarray(positions, dtype=float)
    v = np.asarray(velocities, dtype=float)
    acc = -GPS_MU * x / np.linalg.norm(x, axis=-1, keepdims=True) ** 3
    receiver = np.asarray(receiver, dtype=float)
    rho = np.linalg.norm(x - receiver, axis=-1)
    for _ in range(iterations):
        tau = (rho / SPEED_OF_LIGHT)[..., None]
        sat = x - v * tau + 0.5 * acc * tau * tau
        rho = np.linalg.norm(sat - receiver, axis=-1)
    return sat, rho


def elevations(receiver: Any, satellites: Any) -> np.ndarray:
    """Elevations (rad) of satellites above the receiver's local horizontal plane.

    Parameters
    ----------
    receiver : (..., 3) array_like
        Receiver positions (m, geocentric).
    satellites : (..., 3) array_like
        Satellite positions (m), broadcast against ``receiver``.

    Returns
    -------
    (...) numpy.ndarray
    """
    receiver = np.asarray(receiver, dtype=float)
    los = np.asarray(satellites, dtype=float) - receiver
    up = receiver / np.linalg.norm(receiver, axis=-1, keepdims=True)
    sin_el = np.sum(los * up, axis=-1) / np.linalg.norm(los, axis=-1)
    return np.arcsin(np.clip(sin_el, -1.0, 1.0))


def earth_blocked(receiver: Any, satellites: Any, radius: float) -> np.ndarray:
    """Whether the segment receiver → satellite passes within ``radius`` of the geocentre.

    Parameters
    ----------
    receiver, satellites : (..., 3) array_like
        Positions (m, geocentric), broadcast together.
    radius : float
        Blocking sphere radius (m).

    Returns
    -------
    (...) bool numpy.ndarray
    """
    receiver = np.asarray(receiver, dtype=float)
    d = np.asarray(satellites, dtype=float) - receiver
    # Closest approach of x(s) = receiver + s d, s in [0, 1], to the origin.
    s = np.clip(-np.sum(receiver * d, axis=-1) / np.sum(d * d, axis=-1), 0.0, 1.0)
    closest = receiver + s[..., None] * d
    return np.linalg.norm(closest, axis=-1) < radius


def visible_satellites(
    receiver: Any,
    satellites: Any,
    mask: Any,
    blockage_altitude: float = 100e3,
) -> np.ndarray:
    """Satellites above the elevation mask whose line of sight clears the Earth.

    Parameters
    ----------
    receiver, satellites : (..., 3) array_like
        Positions (m, geocentric), broadcast together.
    mask : float or (...) array_like
        Elevation masks (rad).
    blockage_altitude : float
        Rays passing below this altitude over the Earth's sphere are blocked (m).

    Returns
    -------
    (...) bool numpy.ndarray
    """
    el = elevations(receiver, satellites)
    blocked = earth_blocked(receiver, satellites, EARTH_RADIUS + blockage_altitude)
    return (el >= mask) & ~blocked


def _gauss_markov(rng: np.random.Generator, shape: tuple, sigma: float, dt: np.ndarray, tau: float):
    """First-order Gauss–Markov sequences along axis 1 (epochs) with steady-state σ."""
    out = np.zeros(shape)
    if sigma == 0:
        return out
    out[:, 0] = sigma * rng.standard_normal((shape[0], *shape[2:]))
    for k in range(1, shape[1]):
        phi = math.exp(-dt[k - 1] / tau)
        out[:, k] = phi * out[:, k - 1] + sigma * math.sqrt(1 - phi * phi) * rng.standard_normal(
            (shape[0], *shape[2:])
        )
    return out


def simulate_observations(
    constellation: Constellation,
    times: Any,
    receiver_positions: Any,
    models: ReceiverModel | tuple[ReceiverModel, ...],
    rng: np.random.Generator,
    *,
    satellite_clock_sigma: float = 1.0 / SPEED_OF_LIGHT,
    blockage_altitude: float = 100e3,
    slips: tuple[tuple[float, int, int, int], ...] = (),
) -> GnssObservations:
    """Simulate code and carrier-phase observations of receivers along their trajectories.

    Parameters
    ----------
    constellation : Constellation
    times : (T,) array_like
        GPS epochs (s of the almanac week), increasing.
    receiver_positions : (R, T, 3) array_like
        Receiver positions at the epochs (m, week-start inertial frame).
    models : ReceiverModel or tuple of R ReceiverModel
        Error models (one shared, or one per receiver).
    rng : numpy.random.Generator
    satellite_clock_sigma : float
        1σ of each satellite's clock error unknown to the user (s; default 1 m / c).
    blockage_altitude : float
        See :func:`visible_satellites` (m).
    slips : tuple of (time, receiver, prn, cycles)
        Cycle slips to inject in addition to the random ones: at the first epoch ``≥ time``
        the ambiguity of ``prn`` at ``receiver`` changes by ``cycles``.

    Returns
    -------
    GnssObservations
    """
    times = np.asarray(times, dtype=float)
    x = np.asarray(receiver_positions, dtype=float)
    n_rx, n_t = x.shape[:2]
    if x.shape != (n_rx, len(times), 3):
        raise ValueError(f"receiver positions must be (R, {len(times)}, 3), got {x.shape}")
    if np.any(np.diff(times) <= 0):
        raise ValueError("epochs must be strictly increasing")
    if isinstance(models, ReceiverModel):
        models = (models,) * n_rx
    if len(models) != n_rx:
        raise ValueError(f"{n_rx} receivers but {len(models)} receiver models")
    n_sat = constellation.size
    lam = L1_WAVELENGTH

    sat, rho = light_time_positions(constellation, times[None, :, None], x[:, :, None, :])
    el = elevations(x[:, :, None, :], sat)
    visible = np.stack(
        [
            visible_satellites(
                x[r][:, None, :], sat[r], m.mask_at(times)[:, None], blockage_altitude
            )
            for r, m in enumerate(models)
        ]
    )
    tau = rho / SPEED_OF_LIGHT
    sat_clock = constellation.clock_offsets(times[None, :, None] - tau) + (
        satellite_clock_sigma * rng.standard_normal(n_sat)
    )

    dt = np.diff(times)
    code = np.empty((n_rx, n_t, n_sat))
    phase = np.empty((n_rx, n_t, n_sat))
    ambiguity = np.zeros((n_rx, n_t, n_sat), dtype=np.int64)
    slip_record = np.zeros((n_rx, n_t, n_sat), dtype=np.int64)
    sat_phase0 = rng.random(n_sat)
    for r, model in enumerate(models):
        # Receiver clock: offset + drift·t + random walk (s).
        walk = np.concatenate(
            [[0.0], np.cumsum(model.clock_random_walk * np.sqrt(dt) * rng.standard_normal(n_t - 1))]
        )
        clock = (
            model.clock_offset_sigma * rng.standard_normal()
            + model.clock_drift_sigma * rng.standard_normal() * (times - times[0])
            + walk
        )
        common = rho[r] + SPEED_OF_LIGHT * (clock[:, None] - sat_clock[r])
        mp = _gauss_markov(
            rng, (2, n_t, n_sat), 1.0, np.append(dt, 1.0), model.multipath_time_constant
        )
        code[r] = (
            common
            + model.multipath_code_sigma * mp[0]
            + model.code_sigma * rng.standard_normal((n_t, n_sat))
        )
        phase_m = (
            common
            + model.multipath_phase_sigma * mp[1]
            + model.phase_sigma * rng.standard_normal((n_t, n_sat))
        )

        # Ambiguities: new at each acquisition, changed by cycle slips while tracking.
        acquired = visible[r] & ~np.vstack([np.zeros((1, n_sat), bool), visible[r][:-1]])
        new_n = rng.integers(-(2**20), 2**20, size=(n_t, n_sat))
        slip_draw = rng.random((n_t, n_sat)) < model.cycle_slip_probability
        sizes = rng.integers(1, model.cycle_slip_max + 1, size=(n_t, n_sat)) * rng.choice(
            [-1, 1], size=(n_t, n_sat)
        )
        slip = np.where(slip_draw & visible[r] & ~acquired, sizes, 0)
        for t_slip, receiver, prn, cycles in slips:
            if receiver == r:
                k = int(np.searchsorted(times, t_slip))
                j = np.flatnonzero(constellation.prn == prn)
                if k < n_t and j.size:
                    slip[k, j[0]] += int(cycles)
        n_amb = np.zeros(n_sat, dtype=np.int64)
        for k in range(n_t):
            n_amb = np.where(acquired[k], new_n[k], n_amb + slip[k])
            ambiguity[r, k] = n_amb
        slip_record[r] = slip
        phase[r] = phase_m / lam + ambiguity[r] + rng.random() - sat_phase0
        code[r][~visible[r]] = np.nan
        phase[r][~visible[r]] = np.nan

    return GnssObservations(
        times=times,
        prn=constellation.prn.copy(),
        code=code,
        phase=phase,
        wavelength=lam,
        truth={
            "ambiguity": ambiguity,
            "slips": slip_record,
            "elevation": el,
            "range": rho,
            "visible": visible,
        },
    )
