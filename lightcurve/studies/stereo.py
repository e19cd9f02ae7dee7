"""Monte Carlo study of the stereo relative-state and inertia EKF (Feng et al., tables 4–7).

One call simulates ``runs`` independent truths and filters *at once* (every array has a
leading run dimension): the target's relative attitude and rate with random disturbance
torques (RK4 sub-steps), the centre-of-mass motion with random accelerations (exact CW
discretisation), noisy stereo images, and the batched :class:`filters.navigation.stereo.StereoEKF`.

Figures of merit (Feng et al., eqs. 40–41), over the epochs of the final ``window``:

``RTMSE = √( (1 / (R T)) Σ_runs Σ_t |e|² )``

with ``e`` the attitude error angle ``2 arccos |δq4|`` (reported in degrees) or the error
vector of ``ω``, ``k``, ``ρ`` and ``ρ̇`` (Euclidean norm), and the 14-dimensional NEES
averaged over runs and window against the two-sided 95 % chi-square band of the run mean.
:class:`StereoScenario` is the study's definition (read from TOML by
:mod:`lightcurve.scenarios.stereo`); ``lightcurve stereo`` is a thin layer over this module.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from filters.attitude import (
    quaternion_multiply,
    ratios_from_tanh,
    rk4_step,
    rotation_vector_to_quaternion,
    tanh_from_inertia,
    validate_inertia,
)
from filters.gaussian import chi2_band, mahalanobis_squared
from filters.navigation.hill import cw_process_noise, cw_transition
from filters.navigation.stereo import (
    STATE_SIZE,
    StereoCamera,
    StereoEKF,
    feature_points,
    relative_attitude_derivative,
    state_error,
)

__all__ = ["QUANTITIES", "MonteCarloResult", "StereoScenario", "run_monte_carlo"]

QUANTITIES = ("attitude_deg", "omega_rad_s", "inertia_k", "position_m", "velocity_m_s")
"""Names of the RTMSE entries, in error-state order."""

_BLOCKS = ((0, 3), (3, 6), (6, 8), (8, 11), (11, 14))


@dataclass(frozen=True)
class StereoScenario:
    """Everything that defines one stereo study (SI units; see ``docs/stereo.md``).

    Parameters
    ----------
    mean_motion : float
        Mean motion of the circular reference orbit (rad/s).
    camera_from_hill : (3, 3) array
        Camera mounting ``M`` (``v_C = M v_H``), a rotation matrix.
    stereo : StereoCamera
        The stereo pair.
    feature_coordinates : (M, 3) array
        Body-frame feature positions in units of ``target_size`` (the first
        ``feature_count`` are used).
    feature_count : int
        Number of tracked features ``N`` (3 … M).
    target_size : float
        Target size (m); features are ``target_size × feature_coordinates``.
    inertia : (3,) array
        True principal moments (any unit; only ratios matter).
    attitude : (4,) array
        Initial relative attitude ``q_TC``.
    omega : (3,) array
        Initial target rate in the body frame (rad/s).
    position, velocity : (3,) array
        Initial centre-of-mass state in the Hill frame (m, m/s).
    angle_noise : float
        Angular measurement noise ``σ_θ`` (rad).
    angular_acceleration_psd : float
        Disturbance-torque density per unit inertia ``q_ω`` (rad²/s³).
    acceleration_psd : float
        Translational acceleration noise density ``q_a`` (m²/s³).
    duration, step, window : float
        Simulated time, measurement interval and the final evaluation window (s).
    truth_substeps : int
        RK4 sub-steps of the truth per measurement interval.
    initial_attitude_error : (3,) array
        Rotation vector added to the true initial attitude (rad), the same in every run.
    initial_k : (2,) array
        Initial tanh inertia estimate (the paper starts from zero: a sphere).
    sigma : dict
        Initial 1σ of ``attitude`` (rad), ``omega`` (rad/s), ``k``, ``position`` (m) and
        ``velocity`` (m/s); ``omega``, ``position`` and ``velocity`` estimates start at the
        truth plus a draw from these.
    """

    mean_motion: float
    camera_from_hill: np.ndarray
    stereo: StereoCamera
    feature_coordinates: np.ndarray
    feature_count: int
    target_size: float
    inertia: np.ndarray
    attitude: np.ndarray
    omega: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    angle_noise: float
    angular_acceleration_psd: float
    acceleration_psd: float
    duration: float
    step: float
    window: float
    truth_substeps: int
    initial_attitude_error: np.ndarray
    initial_k: np.ndarray
    sigma: dict[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        m = np.asarray(self.camera_from_hill, dtype=float)
        if m.shape != (3, 3) or not np.allclose(m @ m.T, np.eye(3), atol=1e-9):
            raise ValueError("camera_from_hill must be a 3x3 rotation matrix")
        if not np.isclose(np.linalg.det(m), 1.0):
            raise ValueError("camera_from_hill must be a proper rotation (det = +1)")
        coords = np.asarray(self.feature_coordinates, dtype=float)
        if coords.ndim != 2 or coords.shape[1] != 3:
            raise ValueError("feature_coordinates must be a list of [x, y, z] points")
        if not 3 <= self.feature_count <= len(coords):
            raise ValueError(
                f"feature_count must be between 3 and the {len(coords)} listed features, "
                f"got {self.feature_count}"
            )
        validate_inertia(self.inertia)
        for name in ("target_size", "duration", "step", "window", "angle_noise"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be positive, got {value}")
        if self.window > self.duration:
            raise ValueError(f"window ({self.window} s) is longer than duration")
        if self.truth_substeps < 1:
            raise ValueError("truth_substeps must be >= 1")
        missing = {"attitude", "omega", "k", "position", "velocity"} - set(self.sigma)
        if missing:
            raise ValueError(f"initial sigma missing for {sorted(missing)}")

    @property
    def features(self) -> np.ndarray:
        """The tracked body-frame feature positions ``(N, 3)`` in metres."""
        coords = np.asarray(self.feature_coordinates, dtype=float)
        return self.target_size * coords[: self.feature_count]

    @property
    def initial_covariance(self) -> np.ndarray:
        """Diagonal initial covariance of ``[δθ, δω, δk, δρ, δρ̇]``."""
        names = ("attitude", "omega", "k", "position", "velocity")
        sizes = (3, 3, 2, 3, 3)
        return np.diag(np.repeat([self.sigma[n] ** 2 for n in names], sizes))

    def with_(self, **changes: Any) -> StereoScenario:
        """A copy with some fields changed (for the sweeps)."""
        return replace(self, **changes)


@dataclass
class MonteCarloResult:
    """Outcome of :func:`run_monte_carlo`.

    Attributes
    ----------
    runs, seed : int
    rtmse : dict[str, float]
        RTMSE over the window for each of :data:`QUANTITIES`.
    rtmse_standard_error : dict[str, float]
        Monte Carlo standard error of each RTMSE (delta method over runs).
    nees_mean : float
        NEES averaged over runs and window epochs.
    nees_band : tuple[float, float]
        95 % band of a ``runs``-average of ``χ²(14)``.
    nees_fraction_in_band : float
        Fraction of window epochs whose run-averaged NEES is inside the band.
    features_in_view : float
        Fraction of feature observations inside both images (a scenario sanity check).
    history : dict[str, numpy.ndarray]
        Per epoch: ``time_s``, the run-RMS error of each quantity, the run-RMS filter 1σ
        (``sigma_<quantity>``) and ``nees`` (run mean).
    elapsed_s : float
        Wall time of the study.
    """

    runs: int
    seed: int
    rtmse: dict[str, float]
    rtmse_standard_error: dict[str, float]
    nees_mean: float
    nees_band: tuple[float, float]
    nees_fraction_in_band: float
    features_in_view: float
    history: dict[str, np.ndarray]
    elapsed_s: float

    @property
    def nees_inside_band(self) -> bool:
        """Whether the window-averaged NEES lies inside the 95 % band."""
        return self.nees_band[0] <= self.nees_mean <= self.nees_band[1]

    def summary(self) -> dict[str, Any]:
        """JSON-ready summary (the ``lightcurve stereo`` contract)."""
        return {
            "runs": self.runs,
            "seed": self.seed,
            "rtmse": dict(self.rtmse),
            "rtmse_standard_error": dict(self.rtmse_standard_error),
            "nees": {
                "mean": self.nees_mean,
                "dof": STATE_SIZE,
                "band_95": list(self.nees_band),
                "inside_band": self.nees_inside_band,
                "fraction_of_epochs_in_band": self.nees_fraction_in_band,
            },
            "features_in_view": self.features_in_view,
            "elapsed_s": self.elapsed_s,
        }


def _psd_sqrt(cov: np.ndarray) -> np.ndarray:
    values, vectors = np.linalg.eigh(cov)
    return vectors * np.sqrt(np.clip(values, 0.0, None))


def run_monte_carlo(
    scenario: StereoScenario,
    runs: int,
    seed: int = 0,
    progress: Callable[[int], None] | None = None,
) -> MonteCarloResult:
    """Run ``runs`` seeded truth/filter pairs of a scenario, batched over runs.

    Parameters
    ----------
    scenario : StereoScenario
    runs : int
        Number of Monte Carlo runs (the paper uses 200).
    seed : int
        Seed of the single ``numpy.random.Generator`` that draws every random number
        (results depend on ``(seed, runs)``).
    progress : callable, optional
        Called with the number of steps done after each measurement step.

    Returns
    -------
    MonteCarloResult
    """
    if runs < 1:
        raise ValueError(f"runs must be >= 1, got {runs}")
    start = time.perf_counter()
    sc = scenario
    rng = np.random.default_rng(seed)
    dt = float(sc.step)
    n_steps = round(sc.duration / dt)
    features = sc.features
    n_feat = len(features)
    m = np.asarray(sc.camera_from_hill, dtype=float)
    omega_c = m @ np.array([0.0, 0.0, sc.mean_motion])
    camera = sc.stereo.camera

    k_true = tanh_from_inertia(np.asarray(sc.inertia, dtype=float))
    ratios_true = ratios_from_tanh(k_true)
    x_rot = np.tile(np.concatenate([sc.attitude, sc.omega]), (runs, 1))
    x_trans = np.tile(np.concatenate([sc.position, sc.velocity]), (runs, 1))
    phi_cw = cw_transition(sc.mean_motion, dt)
    sqrt_q_cw = _psd_sqrt(cw_process_noise(sc.mean_motion, dt, sc.acceleration_psd))
    h = dt / sc.truth_substeps
    sd_disturbance = math.sqrt(sc.angular_acceleration_psd / h)

    sigma = sc.sigma
    q_hat = quaternion_multiply(
        rotation_vector_to_quaternion(sc.initial_attitude_error), sc.attitude
    )
    ekf = StereoEKF(
        np.tile(q_hat, (runs, 1)),
        sc.omega + sigma["omega"] * rng.standard_normal((runs, 3)),
        np.tile(np.asarray(sc.initial_k, dtype=float), (runs, 1)),
        sc.position + sigma["position"] * rng.standard_normal((runs, 3)),
        sc.velocity + sigma["velocity"] * rng.standard_normal((runs, 3)),
        np.tile(sc.initial_covariance, (runs, 1, 1)),
        stereo=sc.stereo,
        features=features,
        mean_motion=sc.mean_motion,
        camera_from_hill=m,
        angle_noise=sc.angle_noise,
        angular_acceleration_psd=sc.angular_acceleration_psd,
        acceleration_psd=sc.acceleration_psd,
    )

    times = dt * np.arange(1, n_steps + 1)
    in_window = times > sc.duration - sc.window + 1e-9
    sq_error_sum = np.zeros((runs, len(QUANTITIES)))
    hist_error = np.zeros((n_steps, len(QUANTITIES)))
    hist_sigma = np.zeros((n_steps, len(QUANTITIES)))
    hist_nees = np.zeros(n_steps)
    visible = 0.0
    k_batch = np.broadcast_to(k_true, (runs, 2))

    for i in range(n_steps):
        for _ in range(sc.truth_substeps):
            disturbance = sd_disturbance * rng.standard_normal((runs, 3))
            f = relative_attitude_derivative(ratios_true, omega_c, disturbance)
            x_rot = rk4_step(f, x_rot, h)
        x_trans = x_trans @ phi_cw.T + rng.standard_normal((runs, 6)) @ sqrt_q_cw.T
        points = feature_points(x_rot[:, :4], x_trans[:, :3] @ m.T, features)
        pixels = sc.stereo.project(points)
        pixels = pixels + ekf.pixel_sigma * rng.standard_normal((runs, n_feat, 4))
        visible += float(
            np.mean(camera.in_view(points) & camera.in_view(points - [sc.stereo.baseline, 0, 0]))
        )

        ekf.predict(dt)
        ekf.update(pixels)

        truth = {
            "q": x_rot[:, :4],
            "omega": x_rot[:, 4:],
            "k": k_batch,
            "position": x_trans[:, :3],
            "velocity": x_trans[:, 3:],
        }
        e = state_error(ekf.as_dict(), truth)
        nees = mahalanobis_squared(e, ekf.P)
        sq = np.stack([np.sum(e[:, a:b] ** 2, axis=-1) for a, b in _BLOCKS], axis=-1)
        var = np.stack(
            [np.trace(ekf.P[:, a:b, a:b], axis1=-2, axis2=-1) for a, b in _BLOCKS], axis=-1
        )
        hist_error[i] = np.mean(sq, axis=0)
        hist_sigma[i] = np.mean(var, axis=0)
        hist_nees[i] = float(np.mean(nees))
        if in_window[i]:
            sq_error_sum += sq
        if progress is not None:
            progress(i + 1)

    n_window = int(np.count_nonzero(in_window))
    per_run_mse = sq_error_sum / n_window
    mse = per_run_mse.mean(axis=0)
    se_mse = per_run_mse.std(axis=0, ddof=1) / math.sqrt(runs) if runs > 1 else np.zeros_like(mse)
    rtmse = np.sqrt(mse)
    se = se_mse / (2 * np.maximum(rtmse, 1e-300))
    to_deg = np.array([math.degrees(1.0), 1, 1, 1, 1])
    band = chi2_band(STATE_SIZE, runs)
    window_nees = hist_nees[in_window]
    history = {"time_s": times, "nees": hist_nees}
    for j, name in enumerate(QUANTITIES):
        history[name] = np.sqrt(hist_error[:, j]) * to_deg[j]
        history[f"sigma_{name}"] = np.sqrt(hist_sigma[:, j]) * to_deg[j]
    return MonteCarloResult(
        runs=runs,
        seed=seed,
        rtmse={n: float(v) for n, v in zip(QUANTITIES, rtmse * to_deg, strict=True)},
        rtmse_standard_error={n: float(v) for n, v in zip(QUANTITIES, se * to_deg, strict=True)},
        nees_mean=float(np.mean(window_nees)),
        nees_band=band,
        nees_fraction_in_band=float(np.mean((window_nees >= band[0]) & (window_nees <= band[1]))),
        features_in_view=visible / n_steps,
        history=history,
        elapsed_s=time.perf_counter() - start,
    )
