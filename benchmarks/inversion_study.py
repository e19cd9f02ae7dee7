"""Seeded simulated scenarios and Monte Carlo studies of the inversion methods.

The accuracy studies of ``benchmarks/inversion.py`` and their reduced versions in the
tests both call these functions, so the test runs exactly the benchmark's code with fewer
runs and shorter arcs.

Scenario (:class:`Scenario`): a geostationary object above 100° W seen from Mount Lemmon
(32.44° N, 110.79° W, 2790 m) at night on 2024-06-21 from 04:00 UTC (phase angle 41° → 37°
over 20 min), one magnitude per second with Gaussian noise of 0.05 mag. Every run ``i`` of a
study with seed ``s`` draws its truth from ``numpy.random.default_rng([s, i])``: a uniform
random attitude, a rate direction uniform on the sphere and a rate magnitude uniform in the
scenario's range, and (for the UKF/MMAE studies) the prior: the truth turned by the stated
angle about a random axis, and rates off by the stated amount in a random direction.
Attitude errors are measured modulo the truth shape's symmetry group.
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from filters.attitude import (
    axis_angle_to_quaternion,
    quaternion_conjugate,
    quaternion_multiply,
    quaternion_to_rotation_vector,
    random_quaternion,
)
from filters.gaussian import chi2_band, mahalanobis_squared
from filters.symmetry import SymmetryGroup
from lightcurve.inversion import InversionResult, invert, shape_symmetry
from lightcurve.io.observations import Observations
from lightcurve.photometry.simulate import GaussianNoise, simulate
from lightcurve.sky.ephemeris import CircularOrbit, Site, orbit_geometry
from shapes import FacetModel, get_library

__all__ = [
    "Scenario",
    "Truth",
    "final_errors",
    "geometry",
    "mmae_study",
    "pf_study",
    "simulate_run",
    "ukf_study",
]

MOUNT_LEMMON = Site(32.4434, -110.7881, 2790.0, "Mount Lemmon")


@dataclass(frozen=True)
class Scenario:
    """Observation geometry and noise of a simulated light curve.

    Attributes
    ----------
    start_mjd : float
        First epoch (UTC MJD); 60482.1667 is 2024-06-21T04:00Z.
    duration_s : float
        Arc length (s).
    cadence_s : float
        Time between measurements (s).
    longitude_deg : float
        Longitude of the geostationary slot (east).
    noise_mag : float
        Gaussian magnitude noise (1σ).
    rate_deg_s : (float, float)
        Range of the true rate magnitude (deg/s).
    """

    start_mjd: float = 60482.0 + 4.0 / 24.0
    duration_s: float = 1200.0
    cadence_s: float = 1.0
    longitude_deg: float = -100.0
    noise_mag: float = 0.05
    rate_deg_s: tuple[float, float] = (0.5, 3.0)


@functools.lru_cache(maxsize=8)
def geometry(scenario: Scenario) -> Observations:
    """Geometry-only observation table of the scenario (cached: astropy takes seconds)."""
    n = round(scenario.duration_s / scenario.cadence_s)
    mjd = scenario.start_mjd + np.arange(n) * scenario.cadence_s / 86400.0
    orbit = CircularOrbit.geostationary(scenario.longitude_deg, scenario.start_mjd)
    return orbit_geometry(orbit, MOUNT_LEMMON, mjd, name="geo")


@dataclass(frozen=True)
class Truth:
    """True initial state and the perturbed prior of one run."""

    q0: np.ndarray
    omega0: np.ndarray
    q_prior: np.ndarray
    omega_prior: np.ndarray


def draw_truth(
    scenario: Scenario,
    rng: np.random.Generator,
    attitude_error_deg: float = 20.0,
    rate_error_deg_s: float = 0.2,
) -> Truth:
    """Random truth and a prior off by exactly the given attitude and rate errors."""
    q0 = random_quaternion((), rng)
    direction = _unit(rng.standard_normal(3))
    omega0 = direction * math.radians(rng.uniform(*scenario.rate_deg_s))
    turn = axis_angle_to_quaternion(_unit(rng.standard_normal(3)), math.radians(attitude_error_deg))
    q_prior = quaternion_multiply(turn, q0)
    omega_prior = omega0 + _unit(rng.standard_normal(3)) * math.radians(rate_error_deg_s)
    return Truth(q0, omega0, q_prior, omega_prior)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def simulate_run(scenario: Scenario, shape: FacetModel, truth: Truth, seed: Any) -> Observations:
    """Simulated light curve of ``shape`` with the truth's initial state (noise seeded)."""
    return simulate(
        geometry(scenario),
        shape,
        q0=truth.q0,
        omega0=truth.omega0,
        noise=GaussianNoise(scenario.noise_mag),
        seed=np.random.default_rng(seed),
    )


def final_errors(
    result: InversionResult, observations: Observations, group: SymmetryGroup
) -> dict[str, float]:
    """Final attitude error (deg) and rate error (deg/s) modulo ``group``, and the NEES of
    ``[δθ, ω]`` against the result's covariance (truth taken at its closest equivalent)."""
    truth = observations.truth[-1]
    q, omega = result.quaternion, result.omega_rad_s
    q_true, index = group.closest(q, truth[:4])
    omega_true = group.equivalent_rates(truth[4:])[int(index)]
    dtheta = quaternion_to_rotation_vector(quaternion_multiply(q_true, quaternion_conjugate(q)))
    error = np.concatenate([dtheta, omega_true - omega])
    return {
        "attitude_error_deg": math.degrees(float(group.attitude_error(q, truth[:4]))),
        "rate_error_deg_s": math.degrees(float(np.linalg.norm(omega_true - omega))),
        "nees": _nees(error, result.covariance),
    }


def _nees(error: np.ndarray, covariance: np.ndarray) -> float:
    """``eᵀ P⁻¹ e``; infinite when ``P`` is singular (a collapsed particle cloud claims
    certainty it does not have)."""
    try:
        return float(mahalanobis_squared(error, covariance))
    except np.linalg.LinAlgError:
        return math.inf


def _runs(
    runs: int,
    seed: int,
    one_run: Callable[[int, np.random.Generator], dict[str, Any]],
    progress: Callable[[str], None] | None,
    first: int = 0,
) -> list[dict[str, Any]]:
    """Runs ``first … first + runs − 1``; run ``i`` draws from ``default_rng([seed, i])``,
    so a study split into parts gives the same records as one long study."""
    out = []
    for i in range(first, first + runs):
        start = time.perf_counter()
        record = one_run(i, np.random.default_rng([seed, i]))
        record["run"] = i
        record["runtime_s"] = time.perf_counter() - start
        out.append(record)
        if progress:
            progress(f"run {i + 1}/{first + runs}: {record}")
    return out


def ukf_study(
    runs: int = 50,
    seed: int = 0,
    shape_name: str = "box_wing",
    scenario: Scenario | None = None,
    attitude_error_deg: float = 20.0,
    rate_error_deg_s: float = 0.2,
    attitude_limit_deg: float = 3.0,
    rate_limit_deg_s: float = 0.02,
    progress: Callable[[str], None] | None = None,
    first: int = 0,
    **options: Any,
) -> dict[str, Any]:
    """UKF study: the UKF on a known shape from a perturbed prior.

    Returns
    -------
    dict
        Settings, per-run records (errors, NEES, runtime), the success rate
        (``attitude < attitude_limit_deg`` and ``rate < rate_limit_deg_s``), the mean NEES
        and its 95 % chi-square band for ``runs`` samples of 6 degrees of freedom.
    """
    scenario = scenario or Scenario()
    shape = get_library().load(shape_name)
    group = shape_symmetry(shape)

    def one(i: int, rng: np.random.Generator) -> dict[str, Any]:
        truth = draw_truth(scenario, rng, attitude_error_deg, rate_error_deg_s)
        observations = simulate_run(scenario, shape, truth, rng)
        result = invert(
            observations,
            {shape_name: shape},
            "ukf",
            q0=truth.q_prior,
            omega0=truth.omega_prior,
            attitude_sigma_deg=attitude_error_deg,
            omega_sigma=math.radians(max(rate_error_deg_s, 1e-3)),
            seed=int(rng.integers(2**31)),
            **options,
        )
        record = final_errors(result, observations, group)
        record["gated"] = int(result.estimates["gated"].sum())
        record["residual_rms_mag"] = result.residual_rms_mag
        return record

    records = _runs(runs, seed, one, progress, first)
    attitude = np.array([r["attitude_error_deg"] for r in records])
    rate = np.array([r["rate_error_deg_s"] for r in records])
    ok = (attitude < attitude_limit_deg) & (rate < rate_limit_deg_s)
    nees = np.array([r["nees"] for r in records])
    band = chi2_band(6, runs, 0.95)
    return {
        "study": "ukf",
        "shape": shape_name,
        "scenario": scenario.__dict__,
        "runs": runs,
        "first_run": first,
        "seed": seed,
        "attitude_error_deg": attitude_error_deg,
        "rate_error_deg_s": rate_error_deg_s,
        "options": options,
        "success_rate": float(ok.mean()),
        "mean_nees": float(nees.mean()),
        "mean_nees_converged": float(nees[ok].mean()) if ok.any() else math.nan,
        "nees_band_95": list(band),
        "nees_band_95_converged": list(chi2_band(6, max(int(ok.sum()), 1), 0.95)),
        "median_attitude_error_deg": float(np.median(attitude)),
        "median_rate_error_deg_s": float(np.median(rate)),
        "records": records,
    }


def mmae_study(
    runs: int = 30,
    seed: int = 0,
    bank: Sequence[str] = ("cube", "box", "plate", "cylinder", "rocket_body", "box_wing"),
    truths: Sequence[str] | None = None,
    scenario: Scenario | None = None,
    attitude_error_deg: float = 20.0,
    rate_error_deg_s: float = 0.2,
    probability_limit: float = 0.9,
    progress: Callable[[str], None] | None = None,
    first: int = 0,
    **options: Any,
) -> dict[str, Any]:
    """MMAE study: the MMAE over a bank of library shapes.

    Run ``i`` takes its truth from ``truths[i % len(truths)]`` (default: the bank itself,
    each shape in turn). With truths inside the bank the study reports how often the true
    shape ends with ``p ≥ probability_limit``; with truths outside it, how often
    ``none_fits`` is raised.
    """
    scenario = scenario or Scenario()
    library = get_library()
    shapes = {name: library.load(name) for name in bank}
    truths = list(truths or bank)
    truth_models = {name: shapes.get(name) or library.load(name) for name in truths}

    def one(i: int, rng: np.random.Generator) -> dict[str, Any]:
        name = truths[i % len(truths)]
        truth = draw_truth(scenario, rng, attitude_error_deg, rate_error_deg_s)
        observations = simulate_run(scenario, truth_models[name], truth, rng)
        result = invert(
            observations,
            shapes,
            "mmae",
            q0=truth.q_prior,
            omega0=truth.omega_prior,
            attitude_sigma_deg=attitude_error_deg,
            omega_sigma=math.radians(max(rate_error_deg_s, 1e-3)),
            seed=int(rng.integers(2**31)),
            **options,
        )
        record = {
            "truth": name,
            "shape": result.shape,
            "p_truth": float(result.shape_probabilities.get(name, 0.0)),
            "none_fits": result.none_fits,
            "probabilities": result.shape_probabilities,
        }
        if name in shapes and result.shape == name:
            record.update(final_errors(result, observations, shape_symmetry(shapes[name])))
        return record

    records = _runs(runs, seed, one, progress, first)
    inside = [r for r in records if r["truth"] in shapes]
    outside = [r for r in records if r["truth"] not in shapes]
    return {
        "study": "mmae",
        "bank": list(bank),
        "truths": truths,
        "scenario": scenario.__dict__,
        "runs": runs,
        "first_run": first,
        "seed": seed,
        "options": options,
        "true_shape_rate": (
            float(np.mean([r["p_truth"] >= probability_limit for r in inside]))
            if inside
            else math.nan
        ),
        "false_none_fits_rate": (
            float(np.mean([r["none_fits"] for r in inside])) if inside else math.nan
        ),
        "none_fits_rate": (
            float(np.mean([r["none_fits"] for r in outside])) if outside else math.nan
        ),
        "records": records,
    }


def pf_study(
    runs: int = 20,
    seed: int = 0,
    shape_name: str = "box_wing",
    scenario: Scenario | None = None,
    particles: int = 2000,
    omega_max_deg_s: float = 5.0,
    attitude_limit_deg: float = 5.0,
    progress: Callable[[str], None] | None = None,
    first: int = 0,
    bank: Sequence[str] | None = None,
    truths: Sequence[str] | None = None,
    probability_limit: float = 0.9,
    **options: Any,
) -> dict[str, Any]:
    """Particle-filter study: the PF from a uniform attitude prior and ``|ω| ≤ omega_max``.

    Reports how often the heaviest mode is within ``attitude_limit_deg`` of the truth
    (modulo the shape's symmetry), how often some reported mode is (its attitude or a
    listed symmetry-equivalent) and how often the particle filter's own final mean is
    (before its modes are polished, ``filter_success_rate``).

    With a ``bank`` of candidate shapes (joint attitude–shape inversion) run ``i`` takes
    its truth from ``truths[i % len(truths)]`` (default: the bank, each shape in turn;
    without a bank: ``shape_name``). A run then succeeds when the true shape wins with
    ``p ≥ probability_limit`` and its attitude is within the limit; the errors of a run
    whose result names another shape are infinite.
    """
    scenario = scenario or Scenario(rate_deg_s=(0.5, omega_max_deg_s))
    library = get_library()
    candidates = list(bank or [shape_name])
    truths = list(truths or (candidates if bank else [shape_name]))
    models = {name: library.load(name) for name in {*candidates, *truths}}
    groups = {name: shape_symmetry(models[name]) for name in truths}

    def one(i: int, rng: np.random.Generator) -> dict[str, Any]:
        name = truths[i % len(truths)]
        group = groups[name]
        truth = draw_truth(scenario, rng)
        observations = simulate_run(scenario, models[name], truth, rng)
        start = time.process_time()
        result = invert(
            observations,
            {c: models[c] for c in candidates},
            "pf",
            omega_max=math.radians(omega_max_deg_s),
            particles=particles,
            seed=int(rng.integers(2**31)),
            **options,
        )
        right = result.shape == name
        if right:
            record = final_errors(result, observations, group)
        else:
            record = {"attitude_error_deg": math.inf, "rate_error_deg_s": math.inf}
            record["nees"] = math.inf
        record["inversion_cpu_s"] = time.process_time() - start
        record["truth"], record["shape"] = name, result.shape
        record["p_truth"] = float(result.shape_probabilities.get(name, 0.0))
        record["residual_rms_mag"] = result.residual_rms_mag
        final = observations.truth[-1, :4]
        mode_errors = [
            math.degrees(float(group.attitude_error(np.asarray(m["quaternion"]), final)))
            if m.get("shape", name) == name
            else math.inf
            for m in result.modes
        ]
        record["modes"] = len(result.modes)
        record["mode_weights"] = [m["weight"] for m in result.modes]
        record["mode_errors_deg"] = mode_errors
        record["truth_in_modes"] = bool(mode_errors) and min(mode_errors) < attitude_limit_deg
        # The particle filter's own final mean (before the modes are polished).
        filtered = result.estimates[["q1", "q2", "q3", "q4"]].to_numpy(float)[-1]
        record["filter_attitude_error_deg"] = (
            math.degrees(float(group.attitude_error(filtered, final))) if right else math.inf
        )
        record["success"] = (
            record["p_truth"] >= probability_limit
            and record["attitude_error_deg"] < attitude_limit_deg
        )
        return record

    records = _runs(runs, seed, one, progress, first)
    return {
        "study": "pf",
        "shape": shape_name if not bank else None,
        "bank": candidates,
        "truths": truths,
        "symmetry_order": groups[truths[0]].order,
        "scenario": scenario.__dict__,
        "runs": runs,
        "first_run": first,
        "seed": seed,
        "particles": particles,
        "omega_max_deg_s": omega_max_deg_s,
        "options": options,
        "success_rate": float(
            np.mean([r["attitude_error_deg"] < attitude_limit_deg for r in records])
        ),
        "shape_and_attitude_rate": float(np.mean([r["success"] for r in records])),
        "true_shape_rate": float(np.mean([r["p_truth"] >= probability_limit for r in records])),
        "truth_in_modes_rate": float(np.mean([r["truth_in_modes"] for r in records])),
        "filter_success_rate": float(
            np.mean([r["filter_attitude_error_deg"] < attitude_limit_deg for r in records])
        ),
        "records": records,
    }
