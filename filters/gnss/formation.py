"""Relative GNSS of a two-spacecraft LEO formation: one seeded simulation and its scores.

The target flies a circular orbit; the chaser flies a projected circular relative orbit of
radius ``ρ`` about it (Clohessy–Wiltshire, ``x = ρ/2 cos θ``, ``y = −ρ sin θ``,
``z = √3/2 ρ cos θ``, ``θ = n t + α``), so the baseline keeps the length ``ρ`` while its
direction sweeps radial, along-track and cross-track. Each seeded run draws the start time
within a day of the almanac's reference time, the orbit's node and phase, and the formation
phase ``α``; simulates both receivers (:mod:`filters.gnss.measurements`) and runs
:class:`filters.gnss.relative.RelativeGnssSolver`. Scores: time to first fix, whether any
fixed epoch has wrong integers, epoch-wise errors of the fixed, the raw code (snapshot) and
the carrier-smoothed code solutions in the target's Hill frame with their predicted standard
deviations, the velocity error, and the errors of the navigation filter of
:mod:`filters.navigation.relnav` fed with the navigator's fixes (fixed when available, otherwise
carrier-smoothed code) and, separately, with raw code and with carrier-smoothed code fixes.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field

import numpy as np

from filters.gnss.constellation import Almanac, Constellation
from filters.gnss.measurements import ReceiverModel, simulate_observations
from filters.gnss.relative import (
    RelativeGnssConfig,
    RelativeGnssSolver,
    fixed_ambiguities_correct,
)
from filters.navigation.hill import EARTH_RADIUS, circular_orbit, hill_rotation, mean_motion

__all__ = ["FormationResult", "FormationScenario", "simulate_formation"]


@dataclass(frozen=True)
class FormationScenario:
    """A LEO formation observed by two GNSS receivers (SI units).

    Attributes
    ----------
    almanac : Almanac
        Broadcast almanac (its unhealthy satellites are left out).
    altitude : float
        Target orbit altitude (m).
    inclination : float
        Target orbit inclination (rad).
    baseline : float
        Radius of the projected circular relative orbit, i.e. the baseline length (m).
    duration : float
        Simulated time (s).
    period : float
        Measurement interval (s).
    receiver : ReceiverModel
        Error model of both receivers.
    solver : RelativeGnssConfig
    filter_accelerometer_noise : float
        Process noise of the navigation filter per measurement interval (m/s²).
    slips : tuple of (time, receiver, prn, cycles)
        Cycle slips to inject (time in s from the start; receiver 0 target, 1 chaser).

    The receiver's obstruction windows are in seconds from the start as well.
    """

    almanac: Almanac
    altitude: float = 500e3
    inclination: float = math.radians(51.6)
    baseline: float = 1000.0
    duration: float = 120.0
    period: float = 1.0
    receiver: ReceiverModel = field(default_factory=ReceiverModel)
    solver: RelativeGnssConfig = field(default_factory=RelativeGnssConfig)
    filter_accelerometer_noise: float = 4e-4
    slips: tuple[tuple[float, int, int, int], ...] = ()


@dataclass
class FormationResult:
    """Outcome of :func:`simulate_formation` (errors in the target's Hill frame, m and m/s).

    Attributes
    ----------
    times : (T,) numpy.ndarray
        Seconds from the start.
    status : (T,) numpy.ndarray of str
    satellites : (T,) numpy.ndarray of int
    wrong : (T,) bool numpy.ndarray
        Fixed epochs whose integers differ from the truth.
    fixed_errors, code_errors, smoothed_errors : (T, 3) numpy.ndarray
        Errors of the fixed (NaN where not fixed), the raw code (snapshot) and the
        carrier-smoothed code solutions.
    code_std, smoothed_std : (T, 3) numpy.ndarray
        Predicted standard deviations of the raw and carrier-smoothed code solutions.
    velocity_errors : (T, 3) numpy.ndarray
        Error of the time-differenced carrier-phase velocity against the mean true velocity
        over the interval (NaN where unavailable).
    filtered_errors, filtered_code_errors, filtered_smoothed_errors : (T, 3) numpy.ndarray
        Navigation-filter position errors with the best fixes (fixed, else carrier-smoothed
        code), with raw code fixes and with carrier-smoothed code fixes.
    filtered_nees : dict[str, (T,) numpy.ndarray]
        Position NEES ``eᵀ P⁻¹ e`` of those filters (keys ``best``, ``code``, ``smoothed``;
        3 on average for a consistent filter).
    time_to_first_fix : float or None
        Seconds from the first epoch to the first fixed epoch.
    detected_slips : list of (time, prn)
        Cycle slips reported by the solver (seconds from the start).
    references : (T,) numpy.ndarray of int
        Reference satellite of each epoch (−1 without a relative solution).
    fixed_ambiguities : list of dict[int, int]
        Fixed double-difference ambiguities of each epoch by PRN.
    smoothing : list of dict[int, int]
        Epochs since each satellite's carrier smoothing (re)started, per epoch.
    elapsed_s : float
    """

    times: np.ndarray
    status: np.ndarray
    satellites: np.ndarray
    wrong: np.ndarray
    fixed_errors: np.ndarray
    code_errors: np.ndarray
    smoothed_errors: np.ndarray
    code_std: np.ndarray
    smoothed_std: np.ndarray
    velocity_errors: np.ndarray
    filtered_errors: np.ndarray
    filtered_code_errors: np.ndarray
    filtered_smoothed_errors: np.ndarray
    filtered_nees: dict[str, np.ndarray]
    time_to_first_fix: float | None
    detected_slips: list[tuple[float, int]]
    references: np.ndarray
    fixed_ambiguities: list[dict[int, int]]
    smoothing: list[dict[int, int]]
    elapsed_s: float

    @property
    def wrong_fix(self) -> bool:
        """Whether any fixed epoch carried wrong integers."""
        return bool(self.wrong.any())


def _formation_truth(sc: FormationScenario, rng: np.random.Generator):
    radius = EARTH_RADIUS + sc.altitude
    n = mean_motion(radius)
    t0 = float(sc.almanac.toa[0]) + rng.uniform(0.0, 86_400.0)
    raan, u0, alpha = rng.uniform(0.0, 2 * math.pi, 3)
    t = np.arange(0.0, sc.duration + 1e-9, sc.period)
    r, v = circular_orbit(radius, sc.inclination, raan, u0, t)
    rotation = hill_rotation(r, v)
    theta = n * t + alpha
    rho = sc.baseline
    hill = np.stack([0.5 * rho * np.cos(theta), -rho * np.sin(theta),
                     0.5 * math.sqrt(3) * rho * np.cos(theta)], axis=-1)  # fmt: skip
    inertial = np.einsum("kji,kj->ki", rotation, hill)
    return t0 + t, t, r, rotation, hill, inertial, n


def simulate_formation(scenario: FormationScenario, seed: int) -> FormationResult:
    """Simulate one seeded run of the formation and score the relative GNSS solutions.

    Parameters
    ----------
    scenario : FormationScenario
    seed : int

    Returns
    -------
    FormationResult
    """
    from filters.navigation.relnav import RelativeNavigationFilter

    clock = time.perf_counter()
    sc = scenario
    rng_geometry, rng_gnss = (
        np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(2)
    )
    gps_t, t, target, rotation, hill, baseline, n = _formation_truth(sc, rng_geometry)
    constellation = Constellation(sc.almanac.healthy())
    start = gps_t[0]
    receiver = dataclasses.replace(
        sc.receiver,
        obstructions=tuple((a + start, b + start, m) for a, b, m in sc.receiver.obstructions),
    )
    obs = simulate_observations(
        constellation,
        gps_t,
        np.stack([target, target + baseline]),
        receiver,
        rng_gnss,
        slips=tuple((t_slip + start, r, p, c) for t_slip, r, p, c in sc.slips),
    )
    solver = RelativeGnssSolver(constellation, sc.solver)
    amb = obs.truth["ambiguity"]
    steps = len(t)
    status = np.empty(steps, dtype=object)
    satellites = np.zeros(steps, dtype=int)
    wrong = np.zeros(steps, dtype=bool)
    fixed_err, code_err, smooth_err, code_std, smooth_std, vel_err = (
        np.full((steps, 3), np.nan) for _ in range(6)
    )
    filtered = {key: np.full((steps, 3), np.nan) for key in ("best", "code", "smoothed")}
    nees = {key: np.full(steps, np.nan) for key in filtered}
    filters: dict[str, RelativeNavigationFilter] = {}
    detected: list[tuple[float, int]] = []
    references = np.full(steps, -1)
    fixed_ambiguities: list[dict[int, int]] = []
    smoothing: list[dict[int, int]] = []
    for k in range(steps):
        sol = solver.process(
            gps_t[k], obs.prn, obs.code[0, k], obs.phase[0, k], obs.code[1, k], obs.phase[1, k]
        )
        status[k], satellites[k] = sol.status, sol.satellites
        detected.extend((float(t[k]), p) for p in sol.slips)
        references[k] = -1 if sol.reference is None else sol.reference
        fixed_ambiguities.append(sol.ambiguities)
        smoothing.append(sol.smoothing)
        rot = rotation[k]
        for kf in filters.values():
            kf.predict(np.zeros(3), sc.period)
        if not filters and sol.status != "none":
            # Start from the first code solution; the velocity prior spans the formation's
            # relative speeds (n ρ ≈ 1 m/s for 1 km).
            p0 = np.zeros((6, 6))
            p0[:3, :3] = rot @ sol.snapshot_covariance @ rot.T
            p0[3:, 3:] = (2.0 * n * sc.baseline + 0.1) ** 2 * np.eye(3)
            x0 = np.concatenate([rot @ sol.snapshot_position, np.zeros(3)])
            filters = {
                key: RelativeNavigationFilter(x0, p0, n, sc.filter_accelerometer_noise, "none")
                for key in filtered
            }
        if sol.status != "none":
            code_err[k] = rot @ sol.snapshot_position - hill[k]
            smooth_err[k] = rot @ sol.code_position - hill[k]
            code_std[k] = np.sqrt(np.diag(rot @ sol.snapshot_covariance @ rot.T))
            smooth_std[k] = np.sqrt(np.diag(rot @ sol.code_covariance @ rot.T))
            filters["code"].update(
                rot @ sol.snapshot_position, rot @ sol.snapshot_covariance @ rot.T
            )
            filters["smoothed"].update(rot @ sol.code_position, rot @ sol.code_covariance @ rot.T)
            best, best_cov = sol.code_position, sol.code_covariance
            if sol.status == "fixed":
                fixed_err[k] = rot @ sol.position - hill[k]
                wrong[k] = not fixed_ambiguities_correct(sol, obs.prn, amb[0, k], amb[1, k])
                best, best_cov = sol.position, sol.covariance
            filters["best"].update(rot @ best, rot @ best_cov @ rot.T)
        if np.all(np.isfinite(sol.velocity)):
            # Mean inertial velocity over the interval, compared in the Hill frame at its end.
            inertial_mean = (baseline[k] - baseline[k - 1]) / sc.period
            vel_err[k] = rot @ (sol.velocity - inertial_mean)
        for key, kf in filters.items():
            filtered[key][k] = e = kf.x[:3] - hill[k]
            nees[key][k] = e @ np.linalg.solve(kf.P[:3, :3], e)
    fixed = status == "fixed"
    ttff = float(t[np.argmax(fixed)] - t[0]) if fixed.any() else None
    return FormationResult(
        times=t,
        status=status.astype(str),
        satellites=satellites,
        wrong=wrong,
        fixed_errors=fixed_err,
        code_errors=code_err,
        smoothed_errors=smooth_err,
        code_std=code_std,
        smoothed_std=smooth_std,
        velocity_errors=vel_err,
        filtered_errors=filtered["best"],
        filtered_code_errors=filtered["code"],
        filtered_smoothed_errors=filtered["smoothed"],
        filtered_nees=nees,
        time_to_first_fix=ttff,
        detected_slips=detected,
        references=references,
        fixed_ambiguities=fixed_ambiguities,
        smoothing=smoothing,
        elapsed_s=time.perf_counter() - clock,
    )
