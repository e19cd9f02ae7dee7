"""Two-period analysis of simulated torque-free tumblers, and spin-rate drift over nights.

Sections:

``tumblers``
    Run ``i`` draws from ``numpy.random.default_rng([seed, i])``: an :func:`egg` of
    semi-axes uniform in [0.5, 3] m and stretches uniform in [1.3, 1.8] (Lambertian, convex:
    no shadows), a random inertia
    (principal moments uniform in [1, 3] kg m² satisfying the triangle inequality, uniform
    random principal axes), a uniform random attitude, and body rates of magnitude
    log-uniform in ``RATE_DEG_S`` whose direction is redrawn until the motion is in the
    run's mode (SAM for even runs, LAM for odd ones). Two runs in three are geostationary
    arcs of duration log-uniform in 20 min - 8 h (at most 10⁴ points, cadence ≥ 2 s), one
    in three the longest low-orbit pass of a night (2 s cadence), both seen from Mount
    Lemmon (:mod:`benchmarks.mismatch_study`); Gaussian noise uniform in 0.02-0.05 mag.
    The truth is :func:`filters.attitude.torque_free_periods` of the inertia and rates. A run
    *succeeds* when the reported precession and rotation periods are both within 1 % of
    ``P_φ`` and ``P_ψ``; the pair is also scored regardless of which is which. The search
    alone is scored by the lattice of combination frequencies its pair generates
    (:func:`lattice_relation`): ``lattice_right`` when it is the truth's, whichever
    generators the fit chose. The fractions are over runs whose arc covers ≥ 3 cycles of
    each period. Baselines: the one-period search, counted right when its period is within
    1 % of ``P_φ`` or ``P_ψ``; and the amplitude rule's reading of the same fitted pair
    (:func:`~lightcurve.analysis.tumbling.euler_reading`), against the reported one (the
    convex model's, :mod:`lightcurve.analysis.tumbling_reading`).
``rotators``
    Principal-axis rotators (the same eggs, rates along the axis of largest or smallest
    moment, the same geometries and noise; run ``i`` draws from ``default_rng([seed + 1000,
    i])``): the fraction called not tumbling, and each run's ΔBIC and fitted pair.
``runtime``
    A 10⁴-point geostationary night (8 h) of a tumbler: the wall time of the two-period
    search (median of ``--repeats``) against the one-period search on the same data and
    trial periods (oversampling 3, as the two-period coarse scan).
    Run with ``OMP_NUM_THREADS=1`` for the one-core figure (recorded in the report).
``drift``
    A principal-axis ellipsoid rotator seen on 30 consecutive nights (2 h per night, 10 s cadence,
    0.03 mag) from a geostationary slot, its period growing linearly by 0.5 % over the 30
    nights from ``DRIFT_PERIOD_H``, and the same rotator at a constant period: the relative
    error and sign of the recovered ``Ṗ`` (sidereal nightly periods about the known spin
    axis, :func:`spin_pole`, with the PAB approximation's systematic of
    :func:`lightcurve.analysis.drift.night_periods`, common to the nights), and the fraction
    of constant runs with ``|Ṗ| < 2σ``. The attitude at each night's start is the same
    (the rotation phase is not carried across nights: the nightly fits do not use it).

    python -m benchmarks.tumbling_periods [--runs 50] [--seed 0] [--sections …]
"""

from __future__ import annotations

import argparse
import math
import os
import time
from typing import Any

import numpy as np

from benchmarks._machine import machine_info
from benchmarks._report import add_sections_argument, emit_report
from benchmarks.mismatch_study import SITE, geo_geometry, leo_geometry
from filters.attitude import attitude_matrix, random_quaternion
from filters.attitude.torque_free_periods import euler_periods
from lightcurve.analysis.drift import period_drift
from lightcurve.analysis.period import period_search
from lightcurve.analysis.tumbling import euler_reading, tumbling_search
from lightcurve.io.observations import Observations
from lightcurve.photometry.simulate import GaussianNoise, simulate
from lightcurve.sky.ephemeris import CircularOrbit, orbit_geometry
from lightcurve.sky.sites import get_site
from shapes import FacetModel, primitives
from shapes.material import Material

SECTIONS = ("tumblers", "rotators", "runtime", "drift")
RATE_DEG_S = (0.5, 6.0)
ARC_S = (1200.0, 8 * 3600.0)
MAX_POINTS = 10_000
CADENCE_S = 2.0
NOISE_MAG = (0.02, 0.05)
TOLERANCE = 0.01
#: Largest |coefficient| of the integer combinations :func:`lattice_relation` tries.
LATTICE_COEFFICIENT = 4
MIN_CYCLES = 3.0
DRIFT_PERIOD_H = 0.1
DRIFT_FRACTION = 0.005
DRIFT_NIGHTS = 30
DRIFT_NOISE_MAG = 0.03
FIRST_NIGHT_MJD = 60324.0
#: Lambertian surface: smooth light curves (no specular glints).
DIFFUSE = Material("lambert", {"rd": 0.5}, name="diffuse")


def egg(semi_axes: np.ndarray, stretch: np.ndarray) -> FacetModel:
    """A smooth convex body without central symmetry: an ellipsoid of ``semi_axes`` (m)
    whose halves ``x > 0`` and ``y > 0`` are stretched by ``stretch`` (2,) along their axis
    (two half-ellipsoids glued on a common section stay convex). Lambertian ``DIFFUSE``.

    A centrally symmetric body (an ellipsoid) shows only the even combinations of the two
    frequencies, so its light curve alone has the halved rotation frequency; a box's facets
    need Fourier orders far above the series' (see ``docs/analysis.md``).
    """
    model = primitives.ellipsoid(tuple(semi_axes), subdivisions=3)
    vertices = np.array(model.vertices, float)
    for axis in range(2):
        vertices[vertices[:, axis] > 0, axis] *= stretch[axis]
    return FacetModel(vertices, model.faces, materials=DIFFUSE, name="egg")


def random_inertia(rng: np.random.Generator) -> np.ndarray:
    """A body-frame inertia (kg m²): moments uniform in [1, 3] (triangle inequality) about
    uniform random principal axes."""
    while True:
        moments = rng.uniform(1.0, 3.0, 3)
        if 2 * moments.max() < moments.sum():
            break
    axes = np.linalg.qr(rng.standard_normal((3, 3)))[0]
    return axes @ np.diag(moments) @ axes.T


def rates_in_mode(rng: np.random.Generator, inertia: np.ndarray, mode: str) -> np.ndarray:
    """Body rates (rad/s) of log-uniform magnitude in ``RATE_DEG_S`` whose torque-free
    motion is in ``mode`` (``"SAM"``, ``"LAM"``; ``"PA-max"``/``"PA-min"``: along the
    axis of largest/smallest moment)."""
    magnitude = math.radians(math.exp(rng.uniform(*np.log(RATE_DEG_S))))
    _, axes = np.linalg.eigh(inertia)
    if mode.startswith("PA"):
        axis = axes[:, 2 if mode == "PA-max" else 0]
        return magnitude * axis * rng.choice([-1.0, 1.0])
    while True:
        direction = rng.standard_normal(3)
        omega = magnitude * direction / np.linalg.norm(direction)
        if euler_periods(inertia, omega).mode == mode:
            return omega


def draw_geometry(rng: np.random.Generator, scenario: str) -> Observations:
    """A geostationary arc (log-uniform duration in ``ARC_S``) or a low-orbit pass."""
    if scenario == "leo":
        return leo_geometry(rng)[0]
    duration = math.exp(rng.uniform(*np.log(ARC_S)))
    return geo_geometry(rng, duration, max(CADENCE_S, duration / MAX_POINTS))[0]


def simulate_run(
    seed: int, index: int, *, mode: str | None = None, scenario: str | None = None
) -> tuple[Observations, np.ndarray, np.ndarray, str, float]:
    """The light curve of one seeded run (module docstring).

    Parameters
    ----------
    seed, index : int
        The run's generator is ``default_rng([seed, index])``.
    mode : str, optional
        ``"SAM"``, ``"LAM"``, ``"PA-max"`` or ``"PA-min"`` (default: SAM for even, LAM for
        odd runs).
    scenario : str, optional
        ``"geo"`` or ``"leo"`` (default: leo for every third run).

    Returns
    -------
    observations : Observations
    inertia : (3, 3) float
        Body-frame inertia (kg m²).
    omega : (3,) float
        Body rates at the first epoch (rad/s).
    scenario : str
    noise : float
        Gaussian noise (mag).
    """
    rng = np.random.default_rng([seed, index])
    mode = mode or ("SAM" if index % 2 == 0 else "LAM")
    scenario = scenario or ("leo" if index % 3 == 2 else "geo")
    body = egg(rng.uniform(0.5, 3.0, 3), rng.uniform(1.3, 1.8, 2))
    inertia = random_inertia(rng)
    omega = rates_in_mode(rng, inertia, mode)
    q0 = random_quaternion((), rng)
    geometry = draw_geometry(rng, scenario)
    noise = float(rng.uniform(*NOISE_MAG))
    observations = simulate(
        geometry,
        body,
        q0=q0,
        omega0=omega,
        inertia=inertia,
        noise=GaussianNoise(noise),
        shadows="none",
        seed=rng,
    )
    return observations, inertia, omega, scenario, noise


def _lattice_index(generators: np.ndarray, targets: np.ndarray) -> int | None:
    """|det M| of the integer matrix M (entries within ±``LATTICE_COEFFICIENT``) with
    ``targets = M generators`` to ``TOLERANCE`` of each target, each row the combination
    with the smallest ``|a| + |b|``; None when a target is no such combination."""
    span = range(-LATTICE_COEFFICIENT, LATTICE_COEFFICIENT + 1)
    rows = []
    for target in targets:
        matches = [
            (abs(a) + abs(b), a, b)
            for a in span
            for b in span
            if abs(a * generators[0] + b * generators[1] - target) < TOLERANCE * target
        ]
        if not matches:
            return None
        rows.append(min(matches)[1:])
    return round(abs(np.linalg.det(np.array(rows, float))))


def lattice_relation(fitted: np.ndarray, truth: np.ndarray) -> str:
    """How the lattice of combinations of a fitted frequency pair relates to the truth's.

    Parameters
    ----------
    fitted, truth : (2,) float
        Frequency pairs (Hz); the truth is ``(f_φ, f_ψ)``.

    Returns
    -------
    str
        ``"same"`` (each truth frequency an integer combination of the fitted pair, the
        matrix unimodular: other generators of the same lattice); ``"finer"`` (the truth's
        lattice a proper sublattice of the fitted one, e.g. a fitted ``f_φ/2``);
        ``"coarser"`` (the fitted lattice a proper sublattice of the truth's, e.g.
        ``(2 f_φ + f_ψ, f_ψ)``); ``"other"`` (neither: an alias or a wrong pair).
    """
    fitted, truth = np.asarray(fitted, float), np.asarray(truth, float)
    index = _lattice_index(fitted, truth)
    if index == 1:
        return "same"
    if index:
        return "finer"
    return "coarser" if _lattice_index(truth, fitted) else "other"


def run_case(
    seed: int, index: int, *, mode: str | None = None, scenario: str | None = None
) -> dict[str, Any]:
    """One seeded run (:func:`simulate_run`): simulate, search, score.

    Returns
    -------
    dict
        JSON-ready record with the truth, the estimate and the scores.
    """
    observations, inertia, omega, scenario, noise = simulate_run(
        seed, index, mode=mode, scenario=scenario
    )
    truth = euler_periods(inertia, omega)
    span = float(np.ptp(observations.times))
    true_pair = np.array([truth.precession_period_s, truth.rotation_period_s])
    record: dict[str, Any] = {
        "run": index,
        "scenario": scenario,
        "mode": truth.mode,
        "points": len(observations),
        "arc_s": span,
        "noise_mag": noise,
        "true_precession_s": truth.precession_period_s,
        "true_rotation_s": truth.rotation_period_s,
        "covered": bool(span >= MIN_CYCLES * max(true_pair)),
        "tumbling": False,
        "both_right": False,
        "pair_right": False,
        "lattice_right": False,
        "single_period_right": False,
    }
    started = time.perf_counter()
    try:
        result = tumbling_search(observations)
    except ValueError as error:  # an arc too short for two periods in the default range
        return {**record, "error": str(error)}
    summary = result.summary()
    precession = summary["precession_period_h"]["period_h"] * 3600.0
    rotation = summary["rotation_period_h"]["period_h"] * 3600.0
    found = np.sort(result.periods_h * 3600.0)
    lattice = lattice_relation(1.0 / found, 1.0 / true_pair)
    rule = euler_reading(result.periods_h, result.sigmas_h, result.combinations)

    def close(a: float, b: float) -> bool:
        return abs(a / b - 1.0) < TOLERANCE

    def right(reading: dict) -> bool:
        return close(
            reading["precession_period_h"]["period_h"] * 3600.0, truth.precession_period_s
        ) and close(reading["rotation_period_h"]["period_h"] * 3600.0, truth.rotation_period_s)

    return {
        **record,
        "periods_s": [float(v) for v in found],
        "combinations": [(c["j"], c["k"], c["amplitude_mag"]) for c in summary["combinations"][:4]],
        "precession_s": precession,
        "rotation_s": rotation,
        "reported_mode": summary["mode"],
        "reading_method": summary["reading_method"],
        "reading_delta_chi2": summary["reading_delta_chi2"],
        "tumbling": summary["tumbling"],
        "delta_bic": summary["delta_bic"],
        "both_right": right(summary),
        "rule_both_right": right(rule),
        "pair_right": bool(
            all(close(a, b) for a, b in zip(found, np.sort(true_pair), strict=True))
        ),
        "lattice": lattice,
        "lattice_right": lattice == "same",
        "single_period_right": bool(
            any(close(result.single.period_h * 3600.0, p) for p in true_pair)
        ),
        "runtime_s": time.perf_counter() - started,
    }


def tumblers(seed: int, runs: int) -> dict[str, Any]:
    records = [run_case(seed, i) for i in range(runs)]
    covered = [r for r in records if r["mode"] in ("SAM", "LAM") and r["covered"]]

    def fraction(key: str, rows: list[dict]) -> float | None:
        return float(np.mean([r[key] for r in rows])) if rows else None

    return {
        "runs": runs,
        "covered_runs": len(covered),
        "both_periods_within_1pct": fraction("both_right", covered),
        "baseline_rule_reading_both_within_1pct": fraction("rule_both_right", covered),
        "pair_within_1pct_either_assignment": fraction("pair_right", covered),
        "pair_generates_the_true_lattice": fraction("lattice_right", covered),
        "called_tumbling": fraction("tumbling", covered),
        "mode_right": float(np.mean([r.get("reported_mode") == r["mode"] for r in covered]))
        if covered
        else None,
        "baseline_single_period_within_1pct_of_either": fraction("single_period_right", covered),
        "by_mode": {
            mode: fraction("both_right", [r for r in covered if r["mode"] == mode])
            for mode in ("SAM", "LAM")
        },
        "records": records,
    }


def rotators(seed: int, runs: int) -> dict[str, Any]:
    records = [
        run_case(seed + 1000, i, mode="PA-max" if i % 2 == 0 else "PA-min") for i in range(runs)
    ]
    return {
        "runs": runs,
        "called_not_tumbling": float(np.mean([not r["tumbling"] for r in records])),
        "search_errors": sum("error" in r for r in records),
        "records": [
            {
                k: r.get(k)
                for k in (
                    "run",
                    "scenario",
                    "points",
                    "arc_s",
                    "tumbling",
                    "delta_bic",
                    "periods_s",
                )
            }
            for r in records
        ],
    }


def runtime(seed: int, repeats: int) -> dict[str, Any]:
    rng = np.random.default_rng([seed, 99])
    inertia = random_inertia(rng)
    omega = rates_in_mode(rng, inertia, "SAM")
    geometry = geo_geometry(rng, 8 * 3600.0, 8 * 3600.0 / MAX_POINTS)[0]
    observations = simulate(
        geometry,
        egg(np.array([1.0, 2.0, 3.0]), np.array([1.5, 1.5])),
        q0=random_quaternion((), rng),
        omega0=omega,
        inertia=inertia,
        noise=GaussianNoise(0.03),
        shadows="none",
        seed=rng,
    )
    two, read, one = [], [], []
    for _ in range(repeats):
        started = time.perf_counter()
        tumbling_search(observations, model_reading=False)
        two.append(time.perf_counter() - started)
        started = time.perf_counter()
        tumbling_search(observations)
        read.append(time.perf_counter() - started)
        started = time.perf_counter()
        period_search(observations, (4 * 2.88 / 3600.0, 4.0), oversample=3.0)
        one.append(time.perf_counter() - started)
    return {
        "points": len(observations),
        "omp_num_threads": os.environ.get("OMP_NUM_THREADS"),
        "two_period_search_s": float(np.median(two)),
        "with_convex_reading_s": float(np.median(read)),
        "baseline_one_period_search_s": float(np.median(one)),
        "ratio": float(np.median(two) / np.median(one)),
        "repeats": repeats,
    }


def drift_nights(seed: int, run: int, fraction: float) -> list[Observations]:
    """30 nightly 2-h arcs of a principal-axis ellipsoid rotator whose period grows linearly by
    ``fraction`` over the nights."""
    rng = np.random.default_rng([seed, 500 + run])
    site = get_site(SITE)
    longitude = float(rng.uniform(-130.0, -70.0))
    body = primitives.ellipsoid((1.0, 2.0, 3.5), subdivisions=3, materials=DIFFUSE)
    q0 = random_quaternion((), rng)
    nights = []
    for night in range(DRIFT_NIGHTS):
        start = FIRST_NIGHT_MJD + night + 0.25  # 06:00 UTC: dark at Mount Lemmon
        mjd = start + np.arange(0.0, 7200.0, 10.0) / 86400.0
        geometry = orbit_geometry(CircularOrbit.geostationary(longitude, start), site, mjd)
        period_s = DRIFT_PERIOD_H * 3600.0 * (1 + fraction * night / (DRIFT_NIGHTS - 1))
        nights.append(
            simulate(
                geometry,
                body,
                q0=q0,
                omega0=[0.0, 0.0, 2 * math.pi / period_s],
                noise=GaussianNoise(DRIFT_NOISE_MAG),
                shadows="none",
                seed=rng,
            )
        )
    return nights


def spin_pole(observations: Observations) -> tuple[float, float]:
    """(λ, β) (rad, the geometry's inertial frame) of the body z axis at the first epoch,
    the spin axis of the drift study's rotator."""
    axis = attitude_matrix(observations.truth[0, :4])[2]
    return float(np.arctan2(axis[1], axis[0])), float(np.arcsin(np.clip(axis[2], -1, 1)))


def drift(seed: int, runs: int) -> dict[str, Any]:
    window = (0.8 * DRIFT_PERIOD_H, 1.3 * DRIFT_PERIOD_H)
    truth = DRIFT_PERIOD_H * 3600.0 * DRIFT_FRACTION / (DRIFT_NIGHTS - 1)
    growing, constant = [], []
    for run in range(runs):
        nights = drift_nights(seed, run, DRIFT_FRACTION)
        _, (fit,) = period_drift(nights, window, pole=spin_pole(nights[0]))
        growing.append((fit.period_derivative_s_per_day, fit.derivative_sigma_s_per_day))
        nights = drift_nights(seed, run, 0.0)
        _, (fit,) = period_drift(nights, window, pole=spin_pole(nights[0]))
        constant.append((fit.period_derivative_s_per_day, fit.derivative_sigma_s_per_day))
    growing_arr, constant_arr = np.array(growing), np.array(constant)
    return {
        "runs": runs,
        "true_derivative_s_per_day": truth,
        "growing_relative_error": [float(v) for v in growing_arr[:, 0] / truth - 1],
        "growing_within_20pct_right_sign": float(
            np.mean((np.abs(growing_arr[:, 0] / truth - 1) < 0.2) & (growing_arr[:, 0] > 0))
        ),
        "constant_no_drift_fraction": float(
            np.mean(np.abs(constant_arr[:, 0]) < 2 * constant_arr[:, 1])
        ),
        "constant_pulls": [float(v) for v in constant_arr[:, 0] / constant_arr[:, 1]],
    }


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=50, help="tumbler runs")
    parser.add_argument("--rotator-runs", type=int, default=50, help="principal-axis runs")
    parser.add_argument("--drift-runs", type=int, default=50, help="drift runs (each way)")
    parser.add_argument("--repeats", type=int, default=3, help="runtime repeats")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", help="also write the JSON report here")
    add_sections_argument(parser, SECTIONS)
    args = parser.parse_args(argv)
    report: dict[str, Any] = {"seed": args.seed, "machine": machine_info()}
    if "tumblers" in args.sections:
        report["tumblers"] = tumblers(args.seed, args.runs)
    if "rotators" in args.sections:
        report["rotators"] = rotators(args.seed, args.rotator_runs)
    if "runtime" in args.sections:
        report["runtime"] = runtime(args.seed, args.repeats)
    if "drift" in args.sections:
        report["drift"] = drift(args.seed, args.drift_runs)
    emit_report(report, args.out)


if __name__ == "__main__":
    main()
