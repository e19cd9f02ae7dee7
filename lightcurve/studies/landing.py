"""Monte Carlo study of observation planning for small-body landing (Li et al. 2024, sec. 4).

Li, Wang, Deng, Ge & Dong (2024), *Relative navigation observation sequence planning for
small body attachment and its experiment*:
the lander's navigation filter (:mod:`filters.navigation.lander`) runs on the same drawn
descents (common random numbers) with three imaging strategies — an image at every step,
Li et al.'s Fisher-trace criterion, and the posterior-rollout criterion of
:mod:`filters.planning` with the same image budget — and the per-run error statistics are
summarised. :class:`LandingScenario` is the study's definition (read from TOML by
:mod:`lightcurve.scenarios.landing`); ``lightcurve plan`` is a thin layer over this module.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from filters.attitude import (
    quaternion_conjugate,
    quaternion_multiply,
    rotation_vector_to_quaternion,
)
from filters.navigation.lander import DescentTrajectory, LanderModel
from filters.planning.sequential import FisherTrace, ObservationPlanner, PosteriorRollout

__all__ = [
    "PAPER",
    "STRATEGIES",
    "Draws",
    "LandingScenario",
    "NavigationRun",
    "Study",
    "compare_strategies",
    "draw",
    "error_statistics",
    "navigate",
    "navigation_errors",
    "run_study",
    "summarize",
]

PAPER = {
    "images_used": {"fisher_trace": 55, "every_step": 104},
    "position_error_std_m": {"fisher_trace": 0.0082, "every_step": 0.0068},
    "attitude_error_std_deg": {"fisher_trace": 0.23, "every_step": 0.1932},
}


@dataclass(frozen=True)
class LandingScenario:
    """The landing scenario of Li et al. 2024: navigation model, commanded descent, filter settings.

    Parameters
    ----------
    model : LanderModel
    trajectory : DescentTrajectory
        Commanded descent (the truth follows it up to the process noise).
    initial_sigma : (9,) array
        Initial error standard deviations: position (m), velocity (m/s), attitude (rad).
    steps : int
        Last step ``N`` (``N + 1`` samples at ``model.dt``).
    settle_step : int
        First step of the error statistics.
    s_max : int
        Largest planned interval (steps).
    iterations : int
        Measurement-update iterations (1 = Li et al.'s EKF).
    truth_substeps : int
        RK4 substeps per step of the truth.
    """

    model: LanderModel
    trajectory: DescentTrajectory
    initial_sigma: np.ndarray
    steps: int
    settle_step: int
    s_max: int
    iterations: int = 3
    truth_substeps: int = 4

    def initial_covariance(self) -> np.ndarray:
        """``P_0 = diag(σ²)`` on the error state, ``(n, n)``."""
        return np.diag(np.asarray(self.initial_sigma, dtype=float)[: self.model.dim] ** 2)


@dataclass(frozen=True)
class Draws:
    """Random inputs shared by every strategy (common random numbers).

    Attributes
    ----------
    truth : (N+1, B, 10) array
        True ``[r, ṙ, e]`` (``e``: true attitude correction of the commanded attitude).
    pixel_noise : (N+1, B, 2K) array
        Standard-normal pixel noise of the image that would be taken at each step.
    initial : (B, 9) array
        Standard-normal initial errors.
    """

    truth: np.ndarray
    pixel_noise: np.ndarray
    initial: np.ndarray


def draw(scenario: LandingScenario, runs: int, rng: np.random.Generator) -> Draws:
    """Simulate ``runs`` true descents with process noise and draw all measurement noise.

    The truth integrates eq. 5 with the feed-forward control plus white acceleration noise
    (exact discrete draws of ``Q``) and a random walk of the camera attitude.
    """
    model = scenario.model
    n_steps = scenario.steps
    truth = np.zeros((n_steps + 1, runs, 10))
    truth[0, :, :3] = model.landmarks.site.to_body(scenario.trajectory.position(0.0))
    truth[0, :, 3:6] = model.landmarks.site.vector_to_body(scenario.trajectory.velocity(0.0))
    truth[0, :, 9] = 1.0
    q = model.process_noise()
    chol = np.linalg.cholesky(q[:6, :6]) if model.acceleration_psd > 0 else np.zeros((6, 6))
    attitude_step = math.sqrt(model.attitude_psd * model.dt)
    for k in range(n_steps):
        state = model.dynamics.step(
            k * model.dt, truth[k, :, :6], model.dt, scenario.truth_substeps
        )
        truth[k + 1, :, :6] = state + rng.standard_normal((runs, 6)) @ chol.T
        kick = rotation_vector_to_quaternion(attitude_step * rng.standard_normal((runs, 3)))
        truth[k + 1, :, 6:] = quaternion_multiply(kick, truth[k, :, 6:])
    pixel_noise = rng.standard_normal((n_steps + 1, runs, 2 * len(model.anchors)))
    return Draws(truth, pixel_noise, rng.standard_normal((runs, 9)))


@dataclass(frozen=True)
class NavigationRun:
    """Filter output of one strategy over all runs.

    Attributes
    ----------
    estimates : (N+1, B, 10) array
    covariances : (N+1, B, n, n) array
    taken : (N+1, B) bool array
        Steps at which an image was processed.
    """

    estimates: np.ndarray
    covariances: np.ndarray
    taken: np.ndarray


def navigate(
    scenario: LandingScenario,
    draws: Draws,
    planner: Any = None,
    budget: np.ndarray | None = None,
) -> NavigationRun:
    """Run the navigation filter on every drawn descent (Li et al. 2024, fig. 2).

    The first image is taken at step 0. Without a planner an image is taken at every step;
    with an :class:`filters.planning.sequential.ObservationPlanner` the next image step is
    planned after each update and the filter only propagates in between.

    Parameters
    ----------
    scenario : LandingScenario
    draws : Draws
    planner : ObservationPlanner, optional
    budget : (B,) int array, optional
        Images allowed per run (including the first).

    Returns
    -------
    NavigationRun
    """
    model = scenario.model
    truth = draws.truth
    n_steps, runs = scenario.steps, truth.shape[1]
    n = model.dim
    sigma = np.asarray(scenario.initial_sigma, dtype=float)
    x = truth[0].copy()
    x[:, :6] += draws.initial[:, :6] * sigma[:6]
    if model.estimate_attitude:
        error = rotation_vector_to_quaternion(draws.initial[:, 6:9] * sigma[6:9])
        x[:, 6:] = quaternion_multiply(quaternion_conjugate(error), x[:, 6:])
    p = np.broadcast_to(scenario.initial_covariance(), (runs, n, n)).copy()
    estimates = np.empty((n_steps + 1, runs, 10))
    covariances = np.empty((n_steps + 1, runs, n, n))
    taken = np.zeros((n_steps + 1, runs), dtype=bool)
    next_image = np.zeros(runs, dtype=int)
    used = np.zeros(runs, dtype=int)
    for k in range(n_steps + 1):
        if k > 0:
            phi, q = model.linearize(x, k - 1)
            x = model.predict(x, k - 1)
            p = phi @ p @ np.swapaxes(phi, -1, -2) + q
        if not model.estimate_attitude:
            x[:, 6:] = truth[k, :, 6:]
        now = np.flatnonzero(next_image == k)
        if now.size:
            ids, valid = model.select(truth[k, now], k)
            seen = model.landmarks.camera_points(
                truth[k, now, :3], model.attitude(truth[k, now], k), ids
            )
            pixels = model.camera.project(seen).reshape(now.size, -1)
            pixels = pixels + model.pixel_sigma * draws.pixel_noise[k, now]
            x[now], p[now] = model.update(
                x[now], p[now], k, pixels, ids, valid, iterations=scenario.iterations
            )
            taken[k, now] = True
            used[now] += 1
            if planner is None:
                next_image[now] = k + 1
            else:
                left = None if budget is None else np.asarray(budget)[now] - used[now]
                offsets = planner.next_offset(model, x[now], p[now], k, left)
                next_image[now] = np.where(offsets > 0, k + offsets, -1)
        estimates[k] = x
        covariances[k] = p
    return NavigationRun(estimates, covariances, taken)


def navigation_errors(scenario: LandingScenario, run: NavigationRun, draws: Draws) -> dict:
    """Estimation errors along the descent, in the site frame.

    Returns
    -------
    dict
        ``position`` (N+1, B, 3) m, ``velocity`` (N+1, B, 3) m/s and ``attitude``
        (N+1, B, 3) rad (camera axes; zero when the attitude is not estimated); all signed
        estimate minus truth.
    """
    axes = scenario.model.landmarks.site.axes
    truth, est = draws.truth, run.estimates
    flat_est = est.reshape(-1, 10)
    flat_true = truth.reshape(-1, 10)
    attitude = scenario.model.attitude_error(flat_est, flat_true[:, 6:])
    attitude = attitude.reshape((*truth.shape[:2], 3))
    return {
        "position": (est[..., :3] - truth[..., :3]) @ axes.T,
        "velocity": (est[..., 3:6] - truth[..., 3:6]) @ axes.T,
        "attitude": attitude,
    }


#: Strategies compared by :func:`compare_strategies` (and ``lightcurve plan``).
STRATEGIES = ("every_step", "fisher_trace", "improved")


def compare_strategies(scenario: LandingScenario, draws: Draws) -> dict[str, NavigationRun]:
    """Run the three observation strategies on the same draws.

    ``every_step``
        An image at every step (Li et al.'s reference).
    ``fisher_trace``
        Li et al.'s criterion ``min tr(F⁻¹)`` (eq. 23) on the position block, the part of
        their state ``[r, ṙ]`` an image informs.
    ``improved``
        :class:`filters.planning.sequential.PosteriorRollout` on the position covariance over the
        window after ``settle_step``, with each run's budget equal to the images the
        Fisher-trace criterion used in that run.
    """
    position = (0, 1, 2)
    trace_planner = ObservationPlanner(FisherTrace(position), scenario.s_max, scenario.steps)
    improved_planner = ObservationPlanner(
        PosteriorRollout(position, settle_step=scenario.settle_step),
        scenario.s_max,
        scenario.steps,
    )
    runs = {"every_step": navigate(scenario, draws)}
    runs["fisher_trace"] = navigate(scenario, draws, trace_planner)
    budget = runs["fisher_trace"].taken.sum(axis=0)
    runs["improved"] = navigate(scenario, draws, improved_planner, budget)
    return runs


def error_statistics(
    scenario: LandingScenario, run: NavigationRun, draws: Draws
) -> dict[str, np.ndarray]:
    """Per-run error statistics after the settle step (Li et al. 2024, table 3).

    Returns
    -------
    dict
        For ``position`` (m), ``velocity`` (m/s) and ``attitude`` (deg): ``<name>_std_axes``
        ``(B, 3)`` the standard deviation over time of each axis error (Li et al.'s
        statistic), ``<name>_std`` ``(B,)`` their root sum of squares, and ``<name>_rms``
        ``(B,)`` the root mean square of the error norm; ``images`` ``(B,)``.
    """
    errors = navigation_errors(scenario, run, draws)
    errors["attitude"] = np.degrees(errors["attitude"])
    window = slice(scenario.settle_step, None)
    out: dict[str, np.ndarray] = {"images": run.taken.sum(axis=0)}
    for name, error in errors.items():
        tail = error[window]
        axes = np.std(tail, axis=0)
        out[f"{name}_std_axes"] = axes
        out[f"{name}_std"] = np.sqrt(np.sum(axes**2, axis=-1))
        out[f"{name}_rms"] = np.sqrt(np.mean(np.sum(tail**2, axis=-1), axis=0))
    return out


@dataclass(frozen=True)
class Study:
    """Result of :func:`run_study`: the draws, each strategy's run and its statistics."""

    scenario: LandingScenario
    draws: Draws
    runs: dict[str, NavigationRun]
    statistics: dict[str, dict[str, np.ndarray]]
    seed: int
    seconds: float


def run_study(scenario: LandingScenario, runs: int, seed: int) -> Study:
    """Draw ``runs`` descents with ``numpy.random.default_rng(seed)`` and compare strategies."""
    if runs < 1:
        raise ValueError(f"--runs must be >= 1, got {runs}")
    start = time.perf_counter()
    draws = draw(scenario, runs, np.random.default_rng(seed))
    navigation = compare_strategies(scenario, draws)
    stats = {name: error_statistics(scenario, run, draws) for name, run in navigation.items()}
    return Study(scenario, draws, navigation, stats, seed, time.perf_counter() - start)


def _spread(values: np.ndarray) -> dict[str, Any]:
    values = np.asarray(values, dtype=float)
    spread = float(np.std(values, axis=0, ddof=1)) if len(values) > 1 else 0.0
    return {"mean": float(np.mean(values, axis=0)), "spread": spread}


def summarize(study: Study) -> dict[str, Any]:
    """The ``summary.json`` content of a study (see the module docstring)."""
    scenario = study.scenario
    dt = scenario.model.dt
    total = scenario.steps + 1
    strategies: dict[str, Any] = {}
    for name in STRATEGIES:
        stats, run = study.statistics[name], study.runs[name]
        images = stats["images"]
        entry: dict[str, Any] = {
            "images_used": {
                **_spread(images),
                "min": int(images.min()),
                "max": int(images.max()),
            },
            "images_total": total,
        }
        for key, unit in (("position", "m"), ("velocity", "m_s"), ("attitude", "deg")):
            if key == "attitude" and not scenario.model.estimate_attitude:
                entry["attitude_error_std_deg"] = None
                continue
            block = _spread(stats[f"{key}_std"])
            block["per_axis_mean"] = np.mean(stats[f"{key}_std_axes"], axis=0).tolist()
            entry[f"{key}_error_std_{unit}"] = block
        entry["position_error_rms_m"] = _spread(stats["position_rms"])
        entry["observation_times_s"] = [
            (np.flatnonzero(run.taken[:, b]) * dt).tolist() for b in range(run.taken.shape[1])
        ]
        strategies[name] = entry
    every, trace, improved = (study.statistics[n] for n in STRATEGIES)
    comparison = {
        "fisher_trace_images_fraction": float(trace["images"].mean() / every["images"].mean()),
        "fisher_trace_vs_every_step_position_std": float(
            trace["position_std"].mean() / every["position_std"].mean()
        ),
        "improved_vs_fisher_trace_position_std": float(
            improved["position_std"].mean() / trace["position_std"].mean()
        ),
        "improved_vs_fisher_trace_position_rms": float(
            improved["position_rms"].mean() / trace["position_rms"].mean()
        ),
        "improved_lower_std_fraction_of_runs": float(
            np.mean(improved["position_std"] < trace["position_std"])
        ),
    }
    return {
        "runs": int(study.draws.truth.shape[1]),
        "seed": study.seed,
        "settle_time_s": scenario.settle_step * dt,
        "s_max": scenario.s_max,
        "strategies": strategies,
        "comparison": comparison,
        "paper": PAPER,
        "elapsed_s": study.seconds,
    }
