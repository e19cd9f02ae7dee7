"""Convex inversion on real and synthetic data: accuracy and runtime.

Prints JSON with:

* ``ariadne_fit``: (43) Ariadne, DAMIT test set (37 relative light curves, 1541 points,
  1965–1989), from DAMIT's starting guess λ = 220°, β = 0°, P = 5.76198 h with DAMIT's
  settings (degree/order 6, 8 rows = 512 facets, convexity 0.1, a = 0.5, d = 0.1, k = −0.5,
  c = 0.1) and the default stopping rule (relative χ² decrease < 1e-7 twice, at most 100
  Levenberg–Marquardt iterations); pole distance to the published (253°, −15°), period
  error against 5.761985 h, rms, runtime (one torch thread: the C reference takes about
  3 s on one core).
* ``ariadne_50_iterations``: the same fit stopped at 50 iterations like DAMIT's test run.
* ``minkowski``: the polyhedron reconstruction of the Ariadne solution: runtime and the
  largest difference between its facet areas (over their sum) and the closed Gaussian
  image's.
* ``ariadne_scan``: the period scan over 5.70–5.82 h (step ``coefficient · P²/2T``, pole
  starts spread over the sphere, light scan model on ≤ 20 points per light curve), the
  deepest minima refined with the full model; runtime and where the global minimum is.
* ``ariadne_profile``: χ² against period around the minimum, the pole and shape refitted at
  each fixed period from the converged solution (DAMIT's settings; with ``--profile-free
  a,d,k`` the phase function fitted too): where the χ² minimum of this data and model lies,
  its 1σ from the curvature (Δχ² = χ²_ν) and Δχ² at the published 5.761985 h.
* ``itokawa``: light curves of the (non-convex) Itokawa model simulated night by night on its
  2001 and 2004 apparitions (two-body orbit ``ITOKAWA_ORBIT`` of ``lightcurve.sky.ephemeris``,
  Earth from astropy; a 5-h run at 10-min cadence every 3 days in 2001 Feb–Apr and 2004
  Jan–Aug when the solar elongation is ≥ 60°, V ≤ 18 and the phase angle ≤ 90°) with the
  published spin (P = 12.132 h, λ = 128.5°, β = −89.66°, inertia diag(1, 1, 2)), Gaussian
  noise 0.01 mag (seed 1); a period scan over ±3·10⁻⁵ relative from 6 pole starts,
  refinement of the 3 deepest minima (150 iterations) with convexity weight 0.1 and 0.5;
  pole and period errors, the volume-normalised equivalent-ellipsoid axes against the true
  convex hull's, and the misalignment of the long axes (φ0 is the truth's, so the model's
  body frame is Itokawa's).

* ``reference``: the single fit against DAMIT's C ``convexinv`` on the same file, same start
  and settings, run side by side (best of ``--repeat`` runs each): ``convexinv`` as a
  process, ``lightcurve convex`` as a process (imports, fit, shape, plots), the library fit
  in a fresh process (imports, reading, fit) and in this process; the solution against the
  torch engine's in the same run (same optimiser, the torch model); the command is timed
  as run by default (no figures) and with ``--plots``; with ``--baseline DIR`` (a source
  tree of an earlier commit, put first on ``PYTHONPATH``) that commit's command runs in the
  same rounds, for a before/after ratio. And DAMIT's
  ``period_scan`` on its example range 5.7615–5.7625 h against ours on the same range. The C
  sources are DAMIT's distribution (``convexinv`` folder with its ``Makefile``): give its
  folder with ``--damit DIR`` or ``DAMIT_CONVEX_DIR``; it is built in a temporary folder
  (skipped, with a message, without ``make``/``cc`` or without the sources).
* ``rejection``: the Ariadne scan with and without early rejection: the minima of both, and
  how far above the lowest χ² at the same iteration the fits ending near the minima ever were.
* ``simulated``: a decades-long set like Eros's (simulated: ``ELLIPSOID`` spun with
  ``SIMULATED_SPIN`` on the ``EROS_LIKE_ORBIT`` apparitions 1975–2020, a 5-h run every
  ``--every`` days when observable, ~150 light curves, 0.01 mag noise, seed 3) scanned over
  0.02 h with the CLI defaults (6 pole starts, step coefficient 0.5) and refined.

Baselines printed with the ratios are those of the torch implementation this replaced,
measured on this machine type (``BASELINE_SECONDS``): an in-run baseline of the same code is
not available any more; the C references are measured in the same run.

    python -m benchmarks.convex [--parts ariadne,profile,itokawa,scan,reference,rejection,simulated]
        (reference_fit: the reference part without the period scans)
        [--poles 4] [--threads 2] [--repeat 3] [--damit DIR] [--baseline DIR]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

from benchmarks._machine import machine_info
from filters.attitude import attitude_matrix
from lightcurve.analysis.convex import ConvexSettings, Photometry, fit, period_scan
from lightcurve.analysis.convex.minkowski import (
    close_gaussian_image,
    equivalent_ellipsoid,
    minkowski_polyhedron,
    polytope,
)
from lightcurve.analysis.convex.scan import SCAN_SETTINGS, EarlyRejection, period_profile, refine
from lightcurve.analysis.spin import SpinState, pole_distance, simulate_rotator
from lightcurve.photometry.simulate import GaussianNoise
from lightcurve.sky.ephemeris import (
    ITOKAWA_APPARITIONS,
    HeliocentricOrbit,
    asteroid_geometry,
    itokawa_geometry,
    nightly_epochs,
)
from shapes import get_library
from shapes.mass import solid_properties
from shapes.material import REGOLITH

ROOT = Path(__file__).resolve().parents[1]
ARIADNE = ROOT / "data" / "ariadne" / "test_lcs_rel"
PUBLISHED = {"lambda_deg": 253.0, "beta_deg": -15.0, "period_h": 5.761985, "rms": 0.016}
ITOKAWA_SPIN = (128.5, -89.66, 12.132)
#: Wall times of the torch implementation this one replaced (2-core machine of this project,
#: torch 2.13, two threads): the command's Ariadne fit from DAMIT's start, the Ariadne scan
#: 5.70–5.82 h (4 poles, coefficient 0.8; eager and torch.compile), and the held-out Eros
#: scan 5.26–5.28 h (147 light curves, CLI defaults).
BASELINE_SECONDS = {
    "ariadne_fit_command": 11.0,
    "ariadne_scan": 633.0,
    "ariadne_scan_compiled": 385.0,
    "eros_scan": 1024.0,
}
#: An orbit like (433) Eros's (a, e, i, Ω, ω rounded from JPL; the mean anomaly is not
#: Eros's): a near-Earth asteroid observed at many apparitions over decades.
EROS_LIKE_ORBIT = HeliocentricOrbit(1.458, 0.223, 10.83, 304.3, 178.9, 0.0, 51000.0)
EROS_LIKE_HG = (10.4, 0.46)
SIMULATED_SPIN = (17.0, 11.0, 5.270)  # λ, β (deg), P (h)
SIMULATED_WINDOW = (42413.0, 58849.0)  # 1975-01-01 … 2020-01-01


def _pole_error_deg(solution, lambda_deg: float, beta_deg: float) -> float:
    return math.degrees(
        float(
            pole_distance(
                solution.spin.lambda_rad,
                solution.spin.beta_rad,
                math.radians(lambda_deg),
                math.radians(beta_deg),
            )
        )
    )


def _timed(func, *args, **kwargs):
    start = time.perf_counter()
    out = func(*args, **kwargs)
    return out, time.perf_counter() - start


def _timed_cpu(func, *args, **kwargs):
    """Result, wall seconds and CPU seconds of this process (all threads)."""
    cpu = time.process_time()
    out, wall = _timed(func, *args, **kwargs)
    return out, wall, time.process_time() - cpu


def _children_cpu() -> float:
    """CPU seconds (user + system) of the finished child processes so far."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _run_timed(command: list[str], env=None, stdin=None, cwd=ROOT) -> tuple[float, float]:
    """Wall and CPU seconds of one run of a process (its output discarded)."""
    cpu = _children_cpu()
    began = time.perf_counter()
    with open(stdin) if stdin else open(os.devnull) as source:
        subprocess.run(
            command, env=env, cwd=cwd, stdin=source, stdout=subprocess.DEVNULL, check=True
        )
    return time.perf_counter() - began, _children_cpu() - cpu


def ariadne_fit(data: Photometry, iterations: int, rtol: float) -> tuple[dict, object]:
    start = SpinState.from_degrees(220.0, 0.0, 5.76198, 0.0, float(data.mjd.min()))
    settings = ConvexSettings(max_iter=iterations, rtol=rtol)
    solutions, seconds = _timed(fit, data, start, settings)
    best = solutions[0]
    summary = best.summary()
    return {
        **{k: summary[k] for k in ("lambda_deg", "beta_deg", "period_h", "rms", "chi2")},
        "sigma": summary["sigma"],
        "iterations": best.iterations,
        "converged": best.converged,
        "dark_facet_percent": summary["dark_facet_percent"],
        "pole_error_deg": _pole_error_deg(best, 253.0, -15.0),
        "period_error_h": best.spin.period_h - PUBLISHED["period_h"],
        "seconds": seconds,
        "seconds_per_iteration": seconds / max(best.iterations, 1),
        "accept_pole_3deg": _pole_error_deg(best, 253.0, -15.0) <= 3.0,
        "accept_period_2e-6h": abs(best.spin.period_h - PUBLISHED["period_h"]) <= 2e-6,
        "accept_rms_0.0165": best.rms <= 0.0165,
    }, best


def ariadne_scan(data: Photometry, poles: int, coefficient: float, refined: int) -> dict:
    light = SCAN_SETTINGS
    scan, _, cpu = _timed_cpu(
        period_scan, data, (5.70, 5.82), poles, light, step_coefficient=coefficient
    )
    minima = scan.local_minima(refined)
    final, seconds_refine = _timed(refine, minima, data, ConvexSettings())
    best = final[0]
    return {
        "range_h": [5.70, 5.82],
        "periods": len(scan.periods_h),
        "pole_starts": poles,
        "periods_rejected": int(scan.rejected.sum()),
        "baseline_seconds": BASELINE_SECONDS["ariadne_scan"],
        "ratio_to_baseline": scan.seconds / BASELINE_SECONDS["ariadne_scan"],
        "step_coefficient": coefficient,
        "fits": len(scan.periods_h) * poles,
        "seconds": scan.seconds,
        "cpu_seconds": cpu,
        "seconds_per_fit": scan.seconds / (len(scan.periods_h) * poles),
        "scan_minimum_period_h": scan.minimum().spin.period_h,
        "scan_minima_h": [m.spin.period_h for m in minima],
        "refined_seconds": seconds_refine,
        "refined": [
            {k: s.summary()[k] for k in ("lambda_deg", "beta_deg", "period_h", "rms", "chi2")}
            for s in final
        ],
        "global_minimum_period_h": best.spin.period_h,
        "global_minimum_pole_error_deg": _pole_error_deg(best, 253.0, -15.0),
        "accept_global_minimum_at_right_period": abs(best.spin.period_h - 5.761982) < 2e-5,
    }


def ariadne_profile(data: Photometry, free: tuple[str, ...]) -> dict:
    """χ²(P) with pole and shape refitted at each fixed period (see the module docstring)."""
    settings = ConvexSettings(max_iter=400, rtol=1e-10, free=("lambda", "beta", "rate", *free))
    start = SpinState.from_degrees(220.0, 0.0, 5.76198, 0.0, float(data.mjd.min()))
    (converged,), seconds = _timed(fit, data, start, settings)
    periods = 5.761984 + np.arange(-9, 8, 2) * 1e-6
    profile_settings = dataclasses.replace(settings, max_iter=200)
    profile, seconds_profile = _timed(period_profile, data, converged, periods, profile_settings)
    chi2 = np.array([s.chi2 for s in profile])
    curvature, slope, _ = np.polyfit(periods - 5.761984, chi2, 2)
    minimum = 5.761984 - slope / (2 * curvature)
    reduced = converged.chi2 / (len(data) - len(converged.coefficients) - len(settings.free))
    keys = ("lambda_deg", "beta_deg", "period_h", "rms", "chi2", "iterations")
    return {
        "free": list(settings.free),
        "converged": {
            **{k: converged.summary()[k] for k in keys},
            "pole_error_deg": _pole_error_deg(converged, 253.0, -15.0),
            "seconds": seconds,
        },
        "profile": [
            {
                **{k: s.summary()[k] for k in keys},
                "pole_error_deg": _pole_error_deg(s, 253.0, -15.0),
            }
            for s in profile
        ],
        "profile_seconds": seconds_profile,
        "parabola_minimum_h": float(minimum),
        "sigma_h_from_curvature": math.sqrt(reduced / curvature),
        "reduced_chi2": reduced,
        "delta_chi2_at_published": float(curvature * (PUBLISHED["period_h"] - minimum) ** 2),
    }


def itokawa_apparitions() -> object:
    """Itokawa's 2001 and 2004 apparitions from the geocentre (see the module docstring)."""
    epochs = nightly_epochs(ITOKAWA_APPARITIONS, every_days=3.0, hours=5.0, cadence_minutes=10.0)
    return itokawa_geometry(epochs)


def itokawa(poles: int) -> dict:
    geometry = itokawa_apparitions()
    shape = get_library().load("itokawa")
    lam, beta, period = ITOKAWA_SPIN
    truth = SpinState.from_degrees(lam, beta, period, 0.0, float(geometry.mjd.min()))
    simulated, seconds_sim = _timed(
        simulate_rotator, geometry, shape, truth, GaussianNoise(0.01), seed=1
    )
    data = Photometry.from_observations([simulated])
    window = (period * (1 - 3e-5), period * (1 + 3e-5))
    scan, _ = _timed(period_scan, data, window, poles)
    import trimesh

    hull = trimesh.Trimesh(shape.vertices, shape.faces).convex_hull
    hull_axes = equivalent_ellipsoid((hull.vertices, hull.faces))
    hull_axis = np.linalg.eigh(solid_properties(hull.triangles).inertia)[1][:, 0]
    hull_axis = attitude_matrix(truth.attitude([truth.epoch_mjd])[0]).T @ hull_axis
    out = {
        "points": len(data),
        "nights": int(data.n_curves),
        "noise_mag": 0.01,
        "seed": 1,
        "simulate_seconds": seconds_sim,
        "scan_window_h": list(window),
        "scan_periods": len(scan.periods_h),
        "scan_pole_starts": poles,
        "scan_seconds": scan.seconds,
        "axes_true_hull": hull_axes.tolist(),
    }
    for weight in (0.1, 0.5):
        settings = ConvexSettings(convexity_weight=weight, max_iter=150)
        final, seconds = _timed(refine, scan.local_minima(3), data, settings)
        best = final[0]
        vertices, faces = minkowski_polyhedron(best.normals, best.areas)
        axes = equivalent_ellipsoid((vertices, faces))
        # Long axes compared in the ecliptic frame at t0 (near the pole λ turns the frame).
        long_axis = np.linalg.eigh(solid_properties(vertices[faces]).inertia)[1][:, 0]
        long_axis = attitude_matrix(best.spin.attitude([truth.epoch_mjd])[0]).T @ long_axis
        out[f"convexity_{weight}"] = {
            "refine_seconds": seconds,
            "lambda_deg": best.summary()["lambda_deg"],
            "beta_deg": best.summary()["beta_deg"],
            "period_h": best.spin.period_h,
            "rms": best.rms,
            "dark_facet_percent": 100 * best.dark_facet,
            "pole_error_deg": _pole_error_deg(best, lam, beta),
            "period_relative_error": best.spin.period_h / period - 1,
            "axes_model": axes.tolist(),
            "axes_relative_error": (axes / hull_axes - 1).tolist(),
            "long_axis_misalignment_deg": math.degrees(
                math.acos(min(1.0, abs(float(long_axis @ hull_axis))))
            ),
            "accept_pole_5deg": _pole_error_deg(best, lam, beta) <= 5.0,
            "accept_period_1e-5": abs(best.spin.period_h / period - 1) <= 1e-5,
            "accept_axes_10pct": bool(np.all(np.abs(axes / hull_axes - 1) <= 0.10)),
        }
    return out


def _damit_build(source: Path | None) -> Path | None:
    """DAMIT's ``convexinv`` and ``period_scan`` built in a temporary folder, or None."""
    if source is None or not (source / "convexinv" / "Makefile").exists():
        print("reference: no DAMIT sources (--damit DIR or DAMIT_CONVEX_DIR); skipped")
        return None
    if shutil.which("make") is None or (shutil.which("cc") or shutil.which("gcc")) is None:
        print("reference: no C compiler; skipped")
        return None
    build = Path(tempfile.mkdtemp(prefix="damit-")) / "damit"
    shutil.copytree(source, build)
    subprocess.run(["make", "-C", str(build / "convexinv")], check=True, capture_output=True)
    return build


def reference(
    data: Photometry,
    damit: Path | None,
    repeat: int,
    threads: int,
    scan: bool = True,
    baseline: Path | None = None,
) -> dict:
    """Our fit and (with ``scan``) scan against DAMIT's C programs, side by side (see the
    module docstring); with ``baseline`` (a source tree of an earlier commit) its command
    too, in the same rounds."""
    build = _damit_build(damit)
    out: dict = {"load_average": os.getloadavg()}
    start = SpinState.from_degrees(220.0, 0.0, 5.76198, 0.0, float(data.mjd.min()))
    # In-process fit timed before torch runs (its idle OpenMP threads spin for a while).
    runs = [_timed_cpu(fit, data, start)[1:] for _ in range(repeat)]
    timings = {
        "fit_in_process_seconds": min(r[0] for r in runs),
        "fit_in_process_cpu_seconds": min(r[1] for r in runs),
    }
    # Same solution as the torch engine (the model this replaces) in the same run.
    numba_fit = fit(data, start, ConvexSettings())[0]
    torch_fit, seconds_torch = _timed(fit, data, start, ConvexSettings(engine="torch"))
    torch_fit = torch_fit[0]
    out["solution"] = {
        "lambda_deg": math.degrees(numba_fit.spin.lambda_rad),
        "beta_deg": math.degrees(numba_fit.spin.beta_rad),
        "period_h": numba_fit.spin.period_h,
        "rms": numba_fit.rms,
        "iterations": numba_fit.iterations,
        "pole_difference_to_torch_engine_deg": math.degrees(
            float(
                pole_distance(
                    numba_fit.spin.lambda_rad,
                    numba_fit.spin.beta_rad,
                    torch_fit.spin.lambda_rad,
                    torch_fit.spin.beta_rad,
                )
            )
        ),
        "period_difference_to_torch_engine_h": numba_fit.spin.period_h - torch_fit.spin.period_h,
        "torch_engine_seconds": seconds_torch,
    }
    env = {**os.environ, "NUMBA_NUM_THREADS": str(threads)}
    out_dir = Path(tempfile.mkdtemp(prefix="convex-"))
    command = [sys.executable, "-m", "lightcurve.cli", "convex", str(ARIADNE)]
    command += ["--pole", "220,0", "--period", "5.76198", "--out", str(out_dir)]
    library = (
        "from lightcurve.analysis.convex import Photometry, fit; "
        "from lightcurve.analysis.spin import SpinState; "
        f"d = Photometry.read([{str(ARIADNE)!r}]); "
        "fit(d, SpinState.from_degrees(220.0, 0.0, 5.76198, 0.0, float(d.mjd.min())))"
    )
    # Interleaved: each round runs every program once. CPU seconds (user + system) are
    # reported with the wall times: on a shared machine they depend far less on the load.
    programs = {
        "command": (command, None, env, ROOT),
        "command_with_plots": ([*command, "--plots"], None, env, ROOT),
        "library_process": ([sys.executable, "-c", library], None, env, ROOT),
    }
    if baseline is not None:
        path = os.pathsep.join(filter(None, [str(baseline.resolve()), env.get("PYTHONPATH")]))
        # Run from the baseline tree: ``python -m`` puts the working folder first on sys.path.
        programs["command_baseline"] = (command, None, {**env, "PYTHONPATH": path}, baseline)
    if build is not None:
        convexinv = [str(build / "convexinv" / "convexinv"), "-o", str(out_dir / "areas")]
        convexinv += ["-p", str(out_dir / "par"), str(build / "input_convexinv")]
        convexinv = ([*convexinv, str(out_dir / "lcs")], str(ARIADNE), env, ROOT)
        programs = {"convexinv": convexinv, **programs}
    rounds = []
    for _ in range(repeat):
        row = {}
        for name, (argv, stdin, environment, cwd) in programs.items():
            wall, cpu = _run_timed(argv, env=environment, stdin=stdin, cwd=cwd)
            row[f"{name}_seconds"], row[f"{name}_cpu_seconds"] = wall, cpu
        rounds.append(row)
    for key in rounds[0]:
        timings[key] = min(r[key] for r in rounds)
    timings["rounds"] = rounds
    if build is not None:
        for kind in ("seconds", "cpu_seconds"):
            c = timings[f"convexinv_{kind}"]
            names = ["library_process", "command", "command_with_plots", "fit_in_process"]
            for name in names + (["command_baseline"] if baseline is not None else []):
                timings[f"ratio_{name}_to_convexinv_{kind}"] = timings[f"{name}_{kind}"] / c
    if baseline is not None:
        for kind in ("seconds", "cpu_seconds"):
            timings[f"ratio_command_to_command_baseline_{kind}"] = (
                timings[f"command_{kind}"] / timings[f"command_baseline_{kind}"]
            )
    timings["baseline_command_seconds"] = BASELINE_SECONDS["ariadne_fit_command"]
    timings["ratio_command_to_baseline"] = (
        timings["command_seconds"] / BASELINE_SECONDS["ariadne_fit_command"]
    )
    out["fit"] = timings
    if not scan:
        return out
    # DAMIT's period_scan on its example range against ours on the same range.
    lines = (build / "input_period_scan").read_text().splitlines() if build else []
    low, high, coefficient = (
        (float(v) for v in lines[0].split()[:3]) if lines else (5.7615, 5.7625, 0.8)
    )
    scan, seconds_scan, cpu_scan = _timed_cpu(
        period_scan, data, (low, high), 6, step_coefficient=coefficient
    )
    final = refine(scan.local_minima(3), data, ConvexSettings())
    ours = {
        "range_h": [low, high],
        "periods": len(scan.periods_h),
        "pole_starts": 6,
        "scan_seconds": seconds_scan,
        "scan_cpu_seconds": cpu_scan,
        "refined_minimum_period_h": final[0].spin.period_h,
        "refined_minimum_pole_deg": [
            math.degrees(final[0].spin.lambda_rad),
            math.degrees(final[0].spin.beta_rad),
        ],
    }
    if build is not None:
        period_scan_c = [str(build / "convexinv" / "period_scan"), str(build / "input_period_scan")]
        wall, cpu = _run_timed([*period_scan_c, str(out_dir / "periods")], stdin=str(ARIADNE))
        ours["period_scan_c_seconds"], ours["period_scan_c_cpu_seconds"] = wall, cpu
        rows = [line.split() for line in (out_dir / "periods").read_text().splitlines() if line]
        best = min(rows, key=lambda r: float(r[1]))
        ours["period_scan_c_minimum_period_h"] = float(best[0])
        ours["ratio_ours_to_period_scan_c"] = seconds_scan / wall
        ours["ratio_ours_to_period_scan_c_cpu"] = cpu_scan / cpu
    out["period_scan"] = ours
    return out


class _Recorder(EarlyRejection):
    """Never stops a fit; records every fit's χ² after each iteration (per batch)."""

    def stop(self, iteration, chi2, lowest):
        if iteration == 1:
            _RECORDED.append({})
        _RECORDED[-1][iteration] = chi2.copy()
        return np.zeros(len(chi2), dtype=bool)


_RECORDED: list[dict] = []


def rejection_study(data: Photometry, window, poles: int, coefficient: float) -> dict:
    """The scan with and without early rejection, and how close to the lowest χ² at each
    iteration the fits ending near the deepest minima stay."""
    _RECORDED.clear()
    full, seconds_full = _timed(
        period_scan, data, window, poles, step_coefficient=coefficient, reject=_Recorder()
    )
    fast, seconds_fast = _timed(period_scan, data, window, poles, step_coefficient=coefficient)
    last = SCAN_SETTINGS.max_iter
    traces = np.concatenate(
        [np.array([b.get(k, b[max(b)]) for k in range(1, last + 1)]) for b in _RECORDED], axis=1
    )
    final, lowest = traces[-1], traces.min(axis=1)
    rule = EarlyRejection()
    ratios = traces[rule.after - 1 : -1] / lowest[rule.after - 1 : -1, None]
    out = {"window_h": list(window), "periods": len(full.periods_h), "fits": traces.shape[1]}
    for within in (1.1, 1.5, 2.0):
        near = final < within * final.min()
        out[f"largest_ratio_to_lowest_after_{rule.after}_of_fits_within_{within}"] = float(
            ratios[:, near].max()
        )

    def minima(scan):
        return [(m.spin.period_h, m.chi2) for m in scan.local_minima(10)]

    out.update(
        {
            "seconds_without": seconds_full,
            "seconds_with": seconds_fast,
            "periods_rejected": int(fast.rejected.sum()),
            "minima_without": minima(full),
            "minima_with": minima(fast),
            "same_global_minimum": fast.minimum().spin.period_h == full.minimum().spin.period_h,
        }
    )
    return out


def simulated_set(every_days: float) -> tuple[Photometry, SpinState]:
    """A decades-long light-curve set like Eros's (see the module docstring)."""
    epochs = nightly_epochs(
        [SIMULATED_WINDOW], every_days=every_days, hours=5.0, cadence_minutes=15.0
    )
    geometry = asteroid_geometry(
        EROS_LIKE_ORBIT,
        epochs,
        name="eros_like",
        min_elongation_deg=60.0,
        absolute_magnitude=EROS_LIKE_HG[0],
        slope=EROS_LIKE_HG[1],
        max_magnitude=16.0,
        max_phase_deg=60.0,
    )
    from shapes import primitives

    shape = primitives.ellipsoid((1.8, 1.0, 0.75), 3)
    # A cut-off cap makes the body asymmetric under a half turn (no P/2 alias).
    vertices = shape.vertices.copy()
    vertices[:, 0] = np.minimum(vertices[:, 0], 1.4)
    import trimesh

    from shapes import FacetModel

    hull = trimesh.Trimesh(vertices, shape.faces).convex_hull
    body = FacetModel(hull.vertices * 1000.0, hull.faces, materials=REGOLITH)
    lam, beta, period = SIMULATED_SPIN
    truth = SpinState.from_degrees(lam, beta, period, 0.0, float(geometry.mjd.min()))
    simulated = simulate_rotator(geometry, body, truth, noise=GaussianNoise(0.01), seed=3)
    return Photometry.from_observations([simulated]), truth


def simulated(every_days: float) -> dict:
    (data, truth), seconds_sim = _timed(simulated_set, every_days)
    window = (truth.period_h - 0.01, truth.period_h + 0.01)
    scan, seconds, cpu = _timed_cpu(period_scan, data, window, 6, step_coefficient=0.5)
    final, seconds_refine = _timed(refine, scan.local_minima(5), data, ConvexSettings())
    best = final[0]
    lam, beta, _ = SIMULATED_SPIN
    return {
        "light_curves": data.n_curves,
        "points": len(data),
        "span_years": data.span_days / 365.25,
        "simulate_seconds": seconds_sim,
        "scan_window_h": list(window),
        "periods": len(scan.periods_h),
        "pole_starts": 6,
        "periods_rejected": int(scan.rejected.sum()),
        "scan_seconds": seconds,
        "scan_cpu_seconds": cpu,
        "refine_seconds": seconds_refine,
        "baseline_eros_scan_seconds": BASELINE_SECONDS["eros_scan"],
        "ratio_scan_to_baseline": seconds / BASELINE_SECONDS["eros_scan"],
        "period_error_h": best.spin.period_h - truth.period_h,
        "pole_error_deg": min(
            _pole_error_deg(best, lam, beta), _pole_error_deg(best, lam + 180.0, -beta)
        ),
        "rms": best.rms,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument(
        "--parts",
        default="ariadne,profile,itokawa,scan,reference,rejection,simulated",
        help="comma-separated parts: ariadne, profile, itokawa, scan, reference (reference_fit: "
        "without the period scans), rejection, simulated (default all)",
    )
    parser.add_argument("--repeat", type=int, default=3, help="runs of each timed process")
    parser.add_argument(
        "--damit",
        type=Path,
        default=os.environ.get("DAMIT_CONVEX_DIR"),
        help="DAMIT's convexinv distribution (folder with convexinv/Makefile)",
    )
    parser.add_argument(
        "--baseline",
        type=Path,
        help="reference part: also time the command of this source tree (an earlier commit)",
    )
    parser.add_argument(
        "--every", type=float, default=50.0, help="days between simulated nights (simulated)"
    )
    parser.add_argument("--poles", type=int, default=4, help="pole starts of the Ariadne scan")
    parser.add_argument("--coefficient", type=float, default=0.8, help="period-step coefficient")
    parser.add_argument(
        "--profile-free", default="", help="phase parameters fitted in the profile, e.g. a,d,k"
    )
    parser.add_argument("--threads", type=int, default=2, help="threads (numba and torch)")
    args = parser.parse_args()
    parts = set(args.parts.split(","))
    torch.set_num_threads(args.threads)
    import numba

    numba.set_num_threads(min(args.threads, numba.config.NUMBA_NUM_THREADS))
    data = Photometry.read([ARIADNE])
    out: dict = {"machine": machine_info(), "load_average": os.getloadavg()}
    if "ariadne" in parts:
        out["ariadne_fit"], best = ariadne_fit(data, 100, 1e-7)
        out["ariadne_50_iterations"], _ = ariadne_fit(data, 50, 1e-7)
        (vertices, faces), seconds = _timed(minkowski_polyhedron, best.normals, best.areas)
        normals, target = close_gaussian_image(best.normals, best.areas)
        areas = polytope(normals, (normals @ vertices.T).max(axis=1))[2]
        out["minkowski"] = {
            "facets_in": len(best.areas),
            "triangles_out": len(faces),
            "seconds": seconds,
            "largest_area_mismatch": float(
                np.abs(areas / areas.sum() - target / target.sum()).max()
            ),
            "axes": equivalent_ellipsoid((vertices, faces)).tolist(),
        }
    if "profile" in parts:
        free = tuple(v for v in args.profile_free.split(",") if v)
        out["ariadne_profile"] = ariadne_profile(data, free)
    if "itokawa" in parts:
        out["itokawa"] = itokawa(6)
    if "scan" in parts:
        out["ariadne_scan"] = ariadne_scan(data, args.poles, args.coefficient, 10)
    if "reference" in parts or "reference_fit" in parts:
        out["reference"] = reference(
            data,
            args.damit,
            args.repeat,
            args.threads,
            scan="reference" in parts,
            baseline=args.baseline,
        )
    if "rejection" in parts:
        out["rejection"] = rejection_study(data, (5.755, 5.77), args.poles, args.coefficient)
    if "simulated" in parts:
        out["simulated"] = simulated(args.every)
    out["load_average_end"] = os.getloadavg()
    print(json.dumps(out, indent=2, default=float))


if __name__ == "__main__":
    main()
