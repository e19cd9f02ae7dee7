"""Monte Carlo study of multi-mode relative navigation (Shi et al.): ``lightcurve relnav``.

Shi, Zhang, Li, Lang & Zheng, *Relative navigation architecture for aerospace vehicles based
on multimodal measurement*: a closed-loop approach from ``(−10, 0, 0)`` m to ``(−1, 0, 0)`` m
and station keeping, 6000 s, navigated by :class:`filters.navigation.relnav.
RelativeNavigationFilter` with the position fixes of whichever sensors the *mode* selects.

Modes are configuration, not code: a mode is a list of sensor names (:data:`DEFAULT_MODES`:
cooperative → relative GNSS, non-cooperative → lidar, semi-cooperative → both); a sensor
may name a *backup* that delivers fixes while it is unavailable (the binocular cameras for
the lidar). Relative GNSS is either a position-fix sensor with its own noise
(:class:`PositionSensor`) or the full receiver chain of :mod:`filters.gnss`
(:class:`RgnssSensor`): raw code and carrier phase of both spacecraft, double differences,
float ambiguities over several epochs, LAMBDA, the ratio test, fixed solutions and cycle-slip
handling. Its fix is the fixed carrier-phase solution when the ambiguities are fixed, else
the code double-difference solution, each with its full covariance; with fewer than five
satellites in common view it delivers nothing and the filter carries on with the other
sensors (or the IMU alone).

:class:`ApproachScenario` is the study's definition (read from TOML by
:mod:`lightcurve.scenarios.relnav`); :func:`simulate_approach` runs it.
"""

from __future__ import annotations

import dataclasses
import math
import time
import zlib
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from filters.gaussian import mahalanobis_squared
from filters.gnss.constellation import Almanac, Constellation
from filters.gnss.measurements import ReceiverModel, simulate_observations
from filters.gnss.relative import (
    RelativeGnssConfig,
    RelativeGnssSolver,
    fixed_ambiguities_correct,
)
from filters.navigation.hill import (
    EARTH_MU,
    circular_orbit,
    cw_input_matrix,
    cw_transition,
    hill_rotation,
)
from filters.navigation.relnav import RelativeNavigationFilter
from filters.robust import HUBER_THRESHOLD

__all__ = [
    "DEFAULT_MODES",
    "ApproachResult",
    "ApproachScenario",
    "PositionSensor",
    "RgnssSensor",
    "reference_trajectory",
    "simulate_approach",
]

DEFAULT_MODES: dict[str, tuple[str, ...]] = {
    "cooperative": ("gnss",),
    "non-cooperative": ("lidar",),
    "semi-cooperative": ("lidar", "gnss"),
}
"""Sensors used by each target type (Shi et al., sec. 2.1)."""


def _check_outages(name: str, outages: tuple[tuple[float, float], ...]) -> None:
    for window in outages:
        if len(window) != 2 or not window[0] < window[1]:
            raise ValueError(f"sensor {name!r}: outages are (t_start < t_end), got {window}")


@dataclass(frozen=True)
class PositionSensor:
    """A relative-position sensor.

    Attributes
    ----------
    name : str
    sigma : float
        1σ noise per component (m).
    period : float
        Fix interval (s).
    optical : bool
        Whether gross optical errors can occur (outliers are injected only here).
    outages : tuple of (t_start, t_end)
        Windows of scenario time (s) without fixes.
    backup : str or None
        Sensor that delivers fixes while this one is unavailable.
    """

    name: str
    sigma: float
    period: float
    optical: bool
    outages: tuple[tuple[float, float], ...] = ()
    backup: str | None = None

    def __post_init__(self) -> None:
        for attr in ("sigma", "period"):
            value = getattr(self, attr)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"sensor {self.name!r}: {attr} must be positive, got {value}")
        _check_outages(self.name, self.outages)

    def available(self, t: float) -> bool:
        """Whether the sensor delivers a fix at scenario time ``t`` (outside its outages)."""
        return not any(start <= t < end for start, end in self.outages)


@dataclass(frozen=True)
class RgnssSensor:
    """Relative GNSS from raw code and carrier phase of both spacecraft (:mod:`filters.gnss`).

    Attributes
    ----------
    name : str
    period : float
        Measurement interval (s).
    almanac : Almanac
        The GPS constellation (truth and broadcast orbits alike).
    target_receiver, chaser_receiver : ReceiverModel
        Error models and elevation masks of the two receivers; obstruction windows are in
        scenario time.
    solver : RelativeGnssConfig
    satellite_clock_sigma : float
        1σ of the satellite clock errors unknown to the receivers (s).
    backup : str or None
        Sensor that delivers fixes while this one has no relative fix.
    """

    name: str
    period: float
    almanac: Almanac
    target_receiver: ReceiverModel = field(default_factory=ReceiverModel)
    chaser_receiver: ReceiverModel = field(default_factory=ReceiverModel)
    solver: RelativeGnssConfig = field(default_factory=RelativeGnssConfig)
    satellite_clock_sigma: float = 1.0 / 299_792_458.0
    backup: str | None = None
    optical: bool = field(default=False, init=False)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.period) and self.period > 0):
            raise ValueError(f"sensor {self.name!r}: period must be positive, got {self.period}")


Sensor = PositionSensor | RgnssSensor


@dataclass(frozen=True)
class ApproachScenario:
    """The approach and station-keeping scenario of Shi et al. (SI units).

    Attributes
    ----------
    mean_motion : float
        Target orbit mean motion (rad/s).
    start, hold : (3,) numpy.ndarray
        Initial and station-keeping positions of the chaser (m, Hill frame).
    approach_duration : float
        Time of the smooth (cubic) transfer from ``start`` to ``hold`` (s).
    duration : float
        Simulated time (s).
    imu_period : float
        Accelerometer / control period (s).
    accelerometer_noise : float
        Accelerometer noise per sample (m/s²).
    thrust_noise : float
        Thrust execution error per control period (m/s²); measured by the accelerometer,
        it only perturbs the true trajectory.
    control_frequency, control_damping : float
        Natural frequency (rad/s) and damping of the true trajectory's tracking controller.
    sensors : dict[str, PositionSensor]
        Available sensors by name.
    modes : dict[str, tuple[str, ...]]
        Sensor names used by each mode.
    mode : str
        The mode to run.
    initial_sigma_position, initial_sigma_velocity : float
        Initial estimate errors (m, m/s): the estimate starts at truth + N(0, σ²).
    settle : float
        Start of the evaluation interval (s): RMS errors use epochs ``t ≥ settle``.
    huber_threshold : float
        Huber constant (standard deviations).
    inclination, raan, latitude_argument : float
        The target's circular orbit in the week-start inertial frame of the GNSS almanac
        (rad; argument of latitude at ``t = 0``); used by :class:`RgnssSensor` only.
    gnss_start : float
        GPS time of ``t = 0`` (s of the almanac week).
    """

    mean_motion: float
    start: np.ndarray
    hold: np.ndarray
    approach_duration: float
    duration: float
    imu_period: float
    accelerometer_noise: float
    thrust_noise: float
    control_frequency: float
    control_damping: float
    sensors: dict[str, Sensor]
    modes: dict[str, tuple[str, ...]] = field(default_factory=lambda: dict(DEFAULT_MODES))
    mode: str = "non-cooperative"
    initial_sigma_position: float = 0.5
    initial_sigma_velocity: float = 0.01
    settle: float = 60.0
    huber_threshold: float = HUBER_THRESHOLD
    inclination: float = math.radians(51.6)
    raan: float = 0.0
    latitude_argument: float = 0.0
    gnss_start: float = 0.0

    def __post_init__(self) -> None:
        if self.mode not in self.modes:
            raise ValueError(f"mode {self.mode!r} is not one of {sorted(self.modes)}")
        for mode, names in self.modes.items():
            unknown = [n for n in names if n not in self.sensors]
            if unknown or not names:
                raise ValueError(f"mode {mode!r} uses unknown or no sensors: {unknown}")
        for name, sensor in self.sensors.items():
            if sensor.backup is not None and sensor.backup not in self.sensors:
                raise ValueError(f"sensor {name!r}: unknown backup {sensor.backup!r}")
            if sensor.backup == name:
                raise ValueError(f"sensor {name!r} cannot be its own backup")
        for attr in ("approach_duration", "duration", "imu_period", "control_frequency"):
            value = getattr(self, attr)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{attr} must be positive, got {value}")
        if self.settle >= self.duration:
            raise ValueError(f"settle ({self.settle} s) must be shorter than duration")

    @property
    def active_sensors(self) -> list[Sensor]:
        """The sensors of the selected mode, then their backups."""
        names = list(self.modes[self.mode])
        names += [
            b for b in dict.fromkeys(self.sensors[n].backup for n in names) if b and b not in names
        ]
        return [self.sensors[name] for name in names]


def reference_trajectory(
    t: Any, start: np.ndarray, hold: np.ndarray, approach_duration: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Smooth transfer ``start → hold`` with the cubic ``3τ² − 2τ³``, then hold.

    Parameters
    ----------
    t : (...) array_like
        Times (s).
    start, hold : (3,) array_like
        Positions (m).
    approach_duration : float
        Transfer time ``T`` (s).

    Returns
    -------
    position, velocity, acceleration : (..., 3) numpy.ndarray
    """
    tau = np.clip(np.asarray(t, dtype=float) / approach_duration, 0.0, 1.0)[..., None]
    inside = (tau > 0) & (tau < 1)
    d = np.asarray(hold, dtype=float) - np.asarray(start, dtype=float)
    pos = start + d * (3 * tau**2 - 2 * tau**3)
    vel = np.where(inside, d * (6 * tau - 6 * tau**2) / approach_duration, 0.0)
    acc = np.where(inside, d * (6 - 12 * tau) / approach_duration**2, 0.0)
    return pos, vel, acc


def _gravity_terms(n: float, s: np.ndarray) -> np.ndarray:
    """The CW acceleration ``[3n²x + 2nẏ, −2nẋ, −n²z]`` of a state (m/s²)."""
    return np.array([3 * n * n * s[0] + 2 * n * s[4], -2 * n * s[3], -n * n * s[2]])


@dataclass
class ApproachResult:
    """Outcome of :func:`simulate_approach`.

    Attributes
    ----------
    position_rms, velocity_rms : float
        RMS of the 3-D estimation error norm over ``t ≥ settle`` (m, m/s).
    position_rms_axes, velocity_rms_axes : (3,) numpy.ndarray
        Per-axis RMS errors.
    nees_mean : float
        Mean 6-D NEES over the evaluation interval (6 for a consistent filter).
    fixes, fixes_downweighted : int
        Position fixes processed, and how many got a Huber weight below one.
    outliers_injected, outliers_downweighted : int
        Gross errors injected, and how many of them the robust update down-weighted.
    times, errors, sigmas : numpy.ndarray
        Per IMU epoch: time (s), estimation error (6), filter 1σ (6).
    truth : numpy.ndarray
        True states per IMU epoch (6).
    modes : numpy.ndarray of str
        Per IMU epoch, the navigation sources delivering fixes (``"lidar+rgnss-fixed"``,
        ``"stereo"``, ``"imu-only"``, …): a source delivers while its last fix is at most
        one of its periods old.
    gnss_epochs, gnss_fixed, gnss_wrong : int
        Relative GNSS epochs processed, epochs with a fixed solution, and fixed epochs whose
        integers differ from the simulated truth.
    time_to_first_fix : float or None
        Seconds from the first relative GNSS epoch with a relative solution to the first
        fixed one (``None`` without a fix or without relative GNSS).
    elapsed_s : float
    """

    position_rms: float
    velocity_rms: float
    position_rms_axes: np.ndarray
    velocity_rms_axes: np.ndarray
    nees_mean: float
    fixes: int
    fixes_downweighted: int
    outliers_injected: int
    outliers_downweighted: int
    times: np.ndarray
    errors: np.ndarray
    sigmas: np.ndarray
    truth: np.ndarray
    modes: np.ndarray
    gnss_epochs: int
    gnss_fixed: int
    gnss_wrong: int
    time_to_first_fix: float | None
    elapsed_s: float

    @property
    def ambiguity_fix_rate(self) -> float | None:
        """Fraction of relative GNSS epochs with fixed ambiguities (``None`` without GNSS)."""
        return self.gnss_fixed / self.gnss_epochs if self.gnss_epochs else None

    @property
    def wrong_fix_rate(self) -> float | None:
        """Fraction of fixed epochs with wrong integers (``None`` without fixed epochs)."""
        return self.gnss_wrong / self.gnss_fixed if self.gnss_fixed else None

    @property
    def mode_time_fractions(self) -> dict[str, float]:
        """Fraction of the IMU epochs spent in each navigation sub-mode."""
        counts = Counter(self.modes.tolist())
        return {key: counts[key] / len(self.modes) for key in sorted(counts)}

    def summary(self) -> dict[str, Any]:
        """JSON-ready summary (the ``lightcurve relnav`` contract)."""
        return {
            "position_rms_m": self.position_rms,
            "velocity_rms_m_s": self.velocity_rms,
            "position_rms_axes_m": self.position_rms_axes.tolist(),
            "velocity_rms_axes_m_s": self.velocity_rms_axes.tolist(),
            "nees_mean": self.nees_mean,
            "fixes": self.fixes,
            "fixes_downweighted": self.fixes_downweighted,
            "outliers_injected": self.outliers_injected,
            "outliers_downweighted": self.outliers_downweighted,
            "ambiguity_fix_rate": self.ambiguity_fix_rate,
            "wrong_fix_rate": self.wrong_fix_rate,
            "time_to_first_fix_s": self.time_to_first_fix,
            "gnss_epochs": self.gnss_epochs,
            "mode_time_fractions": self.mode_time_fractions,
            "elapsed_s": self.elapsed_s,
        }


def _fix_schedule(sensors: list[Sensor], duration: float) -> list[tuple[float, int]]:
    """All ``(time, sensor index)`` fix events in ``(0, duration]``, time-ordered."""
    events = []
    for i, sensor in enumerate(sensors):
        count = math.floor(duration / sensor.period + 1e-9)
        events.extend((j * sensor.period, i) for j in range(1, count + 1))
    return sorted(events)


def _sensor_rng(seed: int, name: str, purpose: int) -> np.random.Generator:
    """An independent stream per sensor (and purpose: 0 noise, 1 outliers), keyed by name,
    so a sensor sees the same noise in every mode that uses it."""
    return np.random.default_rng([seed, zlib.crc32(name.encode()), purpose])


class _RgnssChain:
    """The simulated receivers and the relative GNSS solver of one :class:`RgnssSensor`."""

    def __init__(self, sensor: RgnssSensor, sc: ApproachScenario, times, hill_positions, rng):
        radius = (EARTH_MU / sc.mean_motion**2) ** (1.0 / 3.0)
        target, velocity = circular_orbit(
            radius, sc.inclination, sc.raan, sc.latitude_argument, times
        )
        self.rotation = hill_rotation(target, velocity)
        chaser = target + np.einsum("kji,kj->ki", self.rotation, hill_positions)
        shift = sc.gnss_start

        def in_gps_time(model: ReceiverModel) -> ReceiverModel:
            windows = tuple((a + shift, b + shift, m) for a, b, m in model.obstructions)
            return dataclasses.replace(model, obstructions=windows)

        constellation = Constellation(sensor.almanac)
        self.obs = simulate_observations(
            constellation,
            shift + np.asarray(times),
            np.stack([target, chaser]),
            (in_gps_time(sensor.target_receiver), in_gps_time(sensor.chaser_receiver)),
            rng,
            satellite_clock_sigma=sensor.satellite_clock_sigma,
        )
        self.solver = RelativeGnssSolver(constellation, sensor.solver)
        self.epoch = 0
        self.first_solution: float | None = None
        self.first_fix: float | None = None
        self.fixed = self.wrong = 0

    def fix(self, t: float) -> tuple[str, np.ndarray | None, np.ndarray | None]:
        """Process the next epoch: ``(status, position, covariance)`` in the Hill frame."""
        k, obs = self.epoch, self.obs
        self.epoch += 1
        sol = self.solver.process(
            obs.times[k], obs.prn, obs.code[0, k], obs.phase[0, k], obs.code[1, k], obs.phase[1, k]
        )
        if sol.status == "none":
            return "none", None, None
        if self.first_solution is None:
            self.first_solution = t
        rot = self.rotation[k]
        if sol.status == "fixed":
            self.fixed += 1
            amb = obs.truth["ambiguity"][:, k]
            self.wrong += not fixed_ambiguities_correct(sol, obs.prn, amb[0], amb[1])
            if self.first_fix is None:
                self.first_fix = t
            return "fixed", rot @ sol.position, rot @ sol.covariance @ rot.T
        return "code", rot @ sol.code_position, rot @ sol.code_covariance @ rot.T


def simulate_approach(
    scenario: ApproachScenario,
    outlier_rate: float = 0.0,
    outlier_size: float = 2.0,
    robust: str = "huber",
    seed: int = 0,
) -> ApproachResult:
    """Simulate the closed-loop approach and run the navigation filter on it.

    The true chaser tracks :func:`reference_trajectory` with a PD controller that cancels
    the CW terms (guidance is not under test, so it uses the true state); the commanded
    acceleration plus a thrust error is held over each IMU period and integrated exactly.
    The filter receives the accelerometer output (true acceleration + noise) and the fixes
    of the mode's sensors. A fraction ``outlier_rate`` of the optical fixes is replaced by
    gross errors of ``outlier_size`` metres in a random direction.

    Relative GNSS sensors (:class:`RgnssSensor`) simulate both receivers along the true
    trajectory (the target on its circular orbit, the chaser at the true Hill offset) and run
    the relative GNSS solver epoch by epoch; its Hill-frame fixes use the target's true Hill
    frame (the target's own orbit determination is not under test). Backup sensors deliver
    fixes only while their primary is unavailable (in an outage, or without a relative GNSS
    fix).

    Random numbers come from independent streams spawned from ``seed`` (truth, accelerometer,
    initial estimate) and, per sensor name, for its noise and its outliers; so runs that
    differ only in the outliers, the robust option or the mode share the same truth and the
    same noise of each sensor (paired comparisons of modes).

    Parameters
    ----------
    scenario : ApproachScenario
    outlier_rate : float
        Probability that an optical fix is a gross error (0 … 1).
    outlier_size : float
        Magnitude of the gross errors (m).
    robust : {"huber", "none"}
    seed : int

    Returns
    -------
    ApproachResult
    """
    if not 0.0 <= outlier_rate <= 1.0:
        raise ValueError(f"outlier rate must be in [0, 1], got {outlier_rate}")
    if not (math.isfinite(outlier_size) and outlier_size >= 0):
        raise ValueError(f"outlier size must be a non-negative length, got {outlier_size}")
    start_clock = time.perf_counter()
    sc = scenario
    n = sc.mean_motion
    rng_truth, rng_imu, rng_init = (
        np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(3)
    )
    dt = sc.imu_period
    steps = round(sc.duration / dt)
    sensors = sc.active_sensors
    events = _fix_schedule(sensors, steps * dt)
    phi, gam = cw_transition(n, dt), cw_input_matrix(n, dt)

    # True trajectory at the IMU epochs and the acceleration held over each period.
    truth = np.zeros((steps + 1, 6))
    accel = np.zeros((steps, 3))
    ref_pos, ref_vel, ref_acc = reference_trajectory(
        dt * np.arange(steps), sc.start, sc.hold, sc.approach_duration
    )
    wn, zeta = sc.control_frequency, sc.control_damping
    truth[0, :3] = sc.start
    thrust_error = sc.thrust_noise * rng_truth.standard_normal((steps, 3))
    for k in range(steps):
        s = truth[k]
        command = (
            ref_acc[k]
            - _gravity_terms(n, s)
            + wn * wn * (ref_pos[k] - s[:3])
            + 2 * zeta * wn * (ref_vel[k] - s[3:])
        )
        accel[k] = command + thrust_error[k]
        truth[k + 1] = phi @ s + gam @ accel[k]
    imu = accel + sc.accelerometer_noise * rng_imu.standard_normal((steps, 3))

    # True positions at the fix events (the loop below assigns event e to IMU step k).
    event_t = np.array([t for t, _ in events])
    event_k = np.maximum(np.ceil((event_t - 1e-9) / dt).astype(int) - 1, 0)
    tau = event_t - event_k * dt
    true_fix = (
        np.einsum("eij,ej->ei", cw_transition(n, tau), truth[event_k])
        + np.einsum("eij,ej->ei", cw_input_matrix(n, tau), accel[event_k])
    )[:, :3]
    noise_rng = {s.name: _sensor_rng(seed, s.name, 0) for s in sensors}
    outlier_rng = {s.name: _sensor_rng(seed, s.name, 1) for s in sensors}
    chains = {}
    for i, sensor in enumerate(sensors):
        if isinstance(sensor, RgnssSensor):
            mine = np.array([j for j, (_, idx) in enumerate(events) if idx == i], dtype=int)
            chains[sensor.name] = _RgnssChain(
                sensor, sc, event_t[mine], true_fix[mine], noise_rng[sensor.name]
            )
    primary_of = {s.backup: s.name for s in sensors if s.backup is not None}
    # Availability of each sensor (as of its latest epoch) and its latest delivered fix.
    available = {s.name: True for s in sensors}
    delivered: dict[str, tuple[str, float]] = {}
    period = {s.name: s.period for s in sensors}

    p0 = np.diag([sc.initial_sigma_position**2] * 3 + [sc.initial_sigma_velocity**2] * 3)
    x0 = truth[0] + rng_init.multivariate_normal(np.zeros(6), p0)
    kf = RelativeNavigationFilter(
        x0, p0, n, sc.accelerometer_noise, robust=robust, huber_threshold=sc.huber_threshold
    )

    estimates = np.zeros((steps + 1, 6))
    covariances = np.zeros((steps + 1, 6, 6))
    modes = np.empty(steps + 1, dtype=object)
    modes[0] = "imu-only"
    estimates[0], covariances[0] = kf.x, kf.P
    fixes = downweighted = injected = caught = 0
    e = 0
    for k in range(steps):
        t_k, t_next = k * dt, (k + 1) * dt
        t_filter = t_k
        while e < len(events) and events[e][0] <= t_next + 1e-9:
            t_fix, i = events[e]
            true_pos = true_fix[e]
            e += 1
            sensor = sensors[i]
            if isinstance(sensor, RgnssSensor):
                status, z, noise = chains[sensor.name].fix(t_fix)
                available[sensor.name] = status != "none"
                label = f"{sensor.name}-{status}"
            else:
                available[sensor.name] = sensor.available(t_fix)
                z, noise, label = None, sensor.sigma, sensor.name
                if available[sensor.name]:
                    z = true_pos + sensor.sigma * noise_rng[sensor.name].standard_normal(3)
            primary = primary_of.get(sensor.name)
            if z is None or (primary is not None and available[primary]):
                continue
            is_outlier = sensor.optical and outlier_rng[sensor.name].random() < outlier_rate
            if is_outlier:
                direction = outlier_rng[sensor.name].standard_normal(3)
                z = true_pos + outlier_size * direction / np.linalg.norm(direction)
            kf.predict(imu[k], t_fix - t_filter)
            t_filter = t_fix
            weights = kf.update(z, noise)
            delivered[sensor.name] = (label, t_fix)
            fixes += 1
            low = bool(np.any(weights < 1.0))
            downweighted += low
            injected += is_outlier
            caught += is_outlier and low
        kf.predict(imu[k], t_next - t_filter)
        estimates[k + 1], covariances[k + 1] = kf.x, kf.P
        live = sorted(
            label
            for name, (label, t_last) in delivered.items()
            if t_next - t_last <= period[name] + 1e-9
        )
        modes[k + 1] = "+".join(live) if live else "imu-only"

    errors = estimates - truth
    sigmas = np.sqrt(np.diagonal(covariances, axis1=-2, axis2=-1))
    nees = mahalanobis_squared(errors, covariances)
    times = dt * np.arange(steps + 1)
    window = times >= sc.settle
    err = errors[window]
    return ApproachResult(
        position_rms=float(np.sqrt(np.mean(np.sum(err[:, :3] ** 2, axis=1)))),
        velocity_rms=float(np.sqrt(np.mean(np.sum(err[:, 3:] ** 2, axis=1)))),
        position_rms_axes=np.sqrt(np.mean(err[:, :3] ** 2, axis=0)),
        velocity_rms_axes=np.sqrt(np.mean(err[:, 3:] ** 2, axis=0)),
        nees_mean=float(np.mean(nees[window])),
        fixes=fixes,
        fixes_downweighted=downweighted,
        outliers_injected=injected,
        outliers_downweighted=caught,
        times=times,
        errors=errors,
        sigmas=sigmas,
        truth=truth,
        modes=modes.astype(str),
        gnss_epochs=sum(c.epoch for c in chains.values()),
        gnss_fixed=sum(c.fixed for c in chains.values()),
        gnss_wrong=sum(c.wrong for c in chains.values()),
        time_to_first_fix=_time_to_first_fix(chains.values()),
        elapsed_s=time.perf_counter() - start_clock,
    )


def _time_to_first_fix(chains) -> float | None:
    """Earliest first fix minus the first relative solution, over the GNSS sensors."""
    times = [c.first_fix - c.first_solution for c in chains if c.first_fix is not None]
    return min(times) if times else None
