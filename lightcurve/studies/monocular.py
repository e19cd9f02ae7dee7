"""Monocular attitude, rate and inertia study (Deng et al. 2024): ``lightcurve monocular``.

The simulated measurements (quaternions or pixel tracks through
:mod:`filters.navigation.epipolar`) and the Monte Carlo runs of
:class:`filters.navigation.monocular.MonocularEKF` (:func:`run_study`). The scenario
definition and run record are :mod:`lightcurve.studies.monocular_definition`; the
observability and Cramér–Rao analysis, the summary, the estimates table and the figures are
:mod:`lightcurve.studies.monocular_summary`; every name of both is importable from here. The
command is a thin layer over this module.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from filters.attitude import attitude_angle, propagate
from filters.navigation.epipolar import attitude_sequence
from filters.navigation.features import simulate_tracks
from filters.navigation.monocular import MonocularEKF, perturb_attitudes, reference_frame_truth
from lightcurve.io.scenario_files import ScenarioError
from lightcurve.studies.monocular_definition import (
    L_NAMES,
    Criteria,
    MonocularScenario,
    PixelSetup,
    Study,
    Truth,
    form_truth,
)
from lightcurve.studies.monocular_summary import (
    convergence,
    error_series,
    estimates_table,
    monte_carlo_table,
    normalized_parameters,
    print_summary,
    summarize,
    write_figures,
)

__all__ = [
    "L_NAMES",
    "Criteria",
    "MonocularScenario",
    "PixelSetup",
    "Study",
    "Truth",
    "convergence",
    "error_series",
    "estimates_table",
    "form_truth",
    "monte_carlo_table",
    "normalized_parameters",
    "pixel_measurements",
    "print_summary",
    "run_study",
    "summarize",
    "write_figures",
]


def _library_target(setup: PixelSetup) -> tuple[np.ndarray, np.ndarray, Any]:
    """Feature points (vertices), vertex normals and an occlusion test of the library shape."""
    import shapes
    from shapes.visibility.raycast import Occluder

    model = shapes.get_library().load(setup.shape)
    vertices = np.asarray(model.vertices, dtype=float) - np.asarray(model.center_of_mass)
    vertices *= setup.radius_m / np.max(np.linalg.norm(vertices, axis=1))
    normals = np.asarray(model.mesh.vertex_normals, dtype=float)
    return vertices, normals, Occluder(vertices, np.asarray(model.faces))


def pixel_measurements(
    setup: PixelSetup, attitudes: np.ndarray, times: np.ndarray, runs: int, seed: int
) -> tuple[np.ndarray, dict[str, Any]]:
    """Relative-attitude quaternions from simulated pixel tracks, one sequence per run.

    Parameters
    ----------
    setup : PixelSetup
    attitudes : (K, 4) numpy.ndarray
        True camera → body attitudes.
    times : (K,) numpy.ndarray
    runs : int
    seed : int
        Run ``i`` uses ``numpy.random.default_rng([seed, i])`` for pixels and RANSAC.

    Returns
    -------
    quaternions : (K, runs, 4) numpy.ndarray
    info : dict
        Pair statistics of run 0 against the truth and the pipeline's own noise estimate.
    """
    from tqdm import tqdm

    points, normals, occluder = _library_target(setup)
    out = np.full((times.size, runs, 4), np.nan)
    info: dict[str, Any] = {}
    for run in tqdm(range(runs), desc="pixels -> quaternions", disable=runs < 2):
        rng = np.random.default_rng([seed, run])
        tracks = simulate_tracks(
            points,
            normals,
            attitudes,
            times,
            setup.camera,
            position=np.array([0.0, 0.0, setup.range_m]),
            pixel_sigma=setup.pixel_sigma,
            rng=rng,
            occluded=occluder,
            outlier_fraction=setup.outlier_fraction,
        )
        seq = attitude_sequence(
            tracks,
            setup.camera,
            rng=rng,
            threshold_px=setup.threshold_px,
            refine_iterations=setup.refine_iterations,
            linking=setup.linking,
            min_matches=setup.min_matches,
        )
        out[:, run] = seq.quaternions
        if run == 0:
            info = _pair_statistics(seq, attitudes, tracks.visible.sum(axis=1))
    return out, info


def _pair_statistics(seq: Any, attitudes: np.ndarray, tracked: np.ndarray) -> dict[str, Any]:
    from filters.attitude import attitude_matrix, quaternion_from_matrix

    a = np.asarray(attitude_matrix(attitudes))
    true = np.stack([a[p.second].T @ a[p.first] for p in seq.poses])
    est = np.stack([p.rotation for p in seq.poses])
    err = np.degrees(
        np.asarray(attitude_angle(quaternion_from_matrix(est), quaternion_from_matrix(true)))
    )
    sigma = np.degrees(seq.pair_sigma)
    return {
        "tracked_points_min": int(tracked.min()),
        "tracked_points_mean": float(tracked.mean()),
        "pairs": len(seq.poses),
        "failed_frames": len(seq.failures),
        "failures": dict(list(seq.failures.items())[:10]),
        "pair_error_deg_rms": float(np.sqrt(np.mean(err**2))),
        "pair_error_deg_max": float(err.max()),
        "pair_sigma_deg_median": float(np.median(sigma)),
        "attitude_sigma_deg_max": float(np.degrees(np.nanmax(seq.sigma))),
        "link_depth_max": int(seq.depth.max()),
        "residual_px_median": float(np.median([p.residual_rms_px for p in seq.poses])),
    }


def run_study(
    scenario: MonocularScenario,
    runs: int = 1,
    seed: int = 0,
    measurements: tuple[np.ndarray, np.ndarray] | None = None,
) -> Study:
    """Simulate (or take) the measurements and run the EKF on ``runs`` noise realisations.

    Parameters
    ----------
    scenario : MonocularScenario
    runs : int
        Monte Carlo runs (batched through the filter); 1 with external measurements.
    seed : int
        Seed of every random stream.
    measurements : (times, quaternions), optional
        External measurements; the truth is then not used.

    Returns
    -------
    Study
    """
    clock = {}
    study_truth: dict[str, Any] = {}
    start = time.perf_counter()
    info: dict[str, Any] = {}
    if measurements is not None:
        times, z = measurements[0], measurements[1][:, None, :]
    else:
        truth = scenario.truth
        if truth is None:
            raise ScenarioError(
                f"{scenario.path}: [truth] is needed unless --measurements is given"
            )
        times = truth.times
        states = propagate(np.concatenate([truth.q0, truth.omega0]), times, truth.inertia)
        q_rel, omega_rel, _ = reference_frame_truth(truth.inertia, truth.q0, states)
        study_truth = {
            "truth_q": q_rel,
            "truth_omega": omega_rel,
            "truth_p": form_truth(scenario.form, truth.inertia, truth.q0),
        }
        clock["truth_s"] = time.perf_counter() - start
        start = time.perf_counter()
        if scenario.mode == "quaternion":
            rng = np.random.default_rng(seed)
            z = perturb_attitudes(
                np.broadcast_to(q_rel[:, None], (times.size, runs, 4)), scenario.sigma, rng
            )
        else:
            z, info = pixel_measurements(scenario.pixels, states[:, :4], times, runs, seed)
        clock["measurements_s"] = time.perf_counter() - start
    start = time.perf_counter()
    n_runs = z.shape[1]
    ekf = MonocularEKF(
        np.tile(scenario.x0, (n_runs, 1)), scenario.p0, scenario.q, scenario.r, scenario.form
    )
    history = ekf.batch_filter(times, z)
    clock["filter_s"] = time.perf_counter() - start
    return Study(
        scenario,
        times,
        z,
        history,
        measurement_info=info,
        seconds=clock,
        external=measurements is not None,
        **study_truth,
    )
