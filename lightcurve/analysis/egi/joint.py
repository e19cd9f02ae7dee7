"""Shape and attitude together: the joint EGI mode for tumbling objects of unknown attitude.

Each round alternates the two problems that are easy when the other is solved: the attitude
for a given shape, and the EGI for given attitudes (for satellites with known attitudes:
Fan, Friedman & Frueh 2019, "Satellite shape recovery from light curves with noise", AMOS
Conference; Little 1983 for the EGI):

1. **Attitude on the current shape.** An attitude estimator (``estimate_states``; the
   command and :mod:`lightcurve.joint_shape` pass the project's attitude inversion,
   ``invert``'s UKF) runs on each file with the current convex shape and the material; its
   first-epoch state is carried to the principal frame of the shape's inertia
   (:func:`principal_start`).
2. **Torque-free state against the best EGI (variable projection).** The first epoch's
   attitude, the body rates and two log inertia ratios of each file (a torque-free
   rotation, integrated by :func:`filters.attitude.torque_free_trajectory`) are refined by
   Levenberg–Marquardt on the weighted flux residuals of the EGI fitted for each trial
   trajectory (:func:`~lightcurve.analysis.egi.fit.egi_residuals`, on a coarse grid and on
   at most :data:`REFINE_EPOCHS` epochs): the shape is projected out of the problem, as in
   Golub & Pereyra (1973, "The differentiation of pseudo-inverses and nonlinear least
   squares problems whose variables separate", SIAM J. Numer. Anal. 10, 413), so the
   attitude is fitted to the best shape rather than to the current one.
3. **EGI on the refined attitudes**, at the full grid (:func:`~lightcurve.analysis.egi.fit_egi`),
   and on the estimator's own attitudes; the lower χ² is kept (the refinement's coarse grid
   can bias the state it finds), and its Minkowski solid becomes the next round's shape.

Convergence rule: the rounds stop when the EGI's χ² fails to fall by more than
:data:`CHI2_TOLERANCE` (relative) below the best round's, or after ``rounds``; the round with
the lowest χ² is returned.

The frame of the result is the principal frame of the fitted inertia; the attitude is
defined only up to what the light curve can tell apart: the symmetries of the recovered
shape, and a mirror image of shape and attitude together (docs/shape.md, "Joint mode").
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

import brdf
from filters.attitude import (
    attitude_matrix,
    quaternion_from_matrix,
    rotation_vector_to_quaternion,
    torque_free_trajectory,
)
from lightcurve.analysis.egi.epochs import FitEpochs
from lightcurve.analysis.egi.fit import EGIFit, check_epochs, egi_residuals, fit_egi
from lightcurve.analysis.egi.grid import normal_grid
from lightcurve.analysis.egi.solid import convex_solid
from lightcurve.io.observations import Observations
from shapes import FacetModel, Material, primitives

__all__ = [
    "JointFit",
    "JointRound",
    "StateEstimator",
    "fit_joint",
    "principal_axes",
    "principal_start",
    "refine_states",
    "start_shape",
    "torque_free_attitudes",
]

#: ``estimate_states(observations, shape, seed) → (states, ratios, rms, attitudes)``: each
#: file's first-epoch (attitude (4,), rates (3,) rad/s) in the principal frame of
#: ``shape``'s inertia, the inertia ratios ``J₂/J₁``, ``J₃/J₁``, the mean rms residual
#: (mag), and each file's estimated attitudes (E_k, 4) in that frame.
StateEstimator = Callable[
    [Sequence[Observations], FacetModel, int],
    tuple[list[tuple[np.ndarray, np.ndarray]], np.ndarray, float, list[np.ndarray]],
]

#: Semi-axes (m) of the default starting ellipsoid; the inversion fits the albedo–area scale.
START_RADII = (1.5, 1.0, 0.7)
#: Relative χ² improvement below which the rounds stop.
CHI2_TOLERANCE = 0.01
#: Default number of rounds at most.
ROUNDS = 3
#: Grid normals and most epochs (evenly thinned) of the variable-projection refinement.
REFINE_NORMALS = 300
REFINE_EPOCHS = 600
#: Residual evaluations of one refinement at most (besides its finite-difference Jacobians).
REFINE_STEPS = 40
#: Typical scales of the refined parameters: rotation (rad), rates (rad/s), log ratios.
_SCALES = (0.05, 0.05, 0.05, 1e-3, 1e-3, 1e-3)
_RATIO_SCALE = 0.05


@dataclass(frozen=True)
class JointRound:
    """One round of the joint fit.

    Attributes
    ----------
    chi2 : float
        χ² of the round's EGI on its refined attitudes.
    residual_rms_mag : float
        rms of its magnitude residuals.
    inversion_rms_mag : float
        rms residual of the attitude inversion on the round's starting shape (mean over
        files).
    seconds : float
        Wall time of the round.
    """

    chi2: float
    residual_rms_mag: float
    inversion_rms_mag: float
    seconds: float


@dataclass(frozen=True)
class JointFit:
    """Result of :func:`fit_joint`: the best round's EGI and attitudes.

    Attributes
    ----------
    fit : EGIFit
        Normals in the principal frame of the fitted inertia.
    epochs : FitEpochs
        The epochs with the fitted attitudes.
    attitudes : list of (E_k, 4) float
        Fitted inertial → body quaternions at each file's rows.
    inertia_ratios : (2,) float
        Fitted ``J₂/J₁`` and ``J₃/J₁`` of the torque-free rotation.
    rounds : list of JointRound
    best_round : int
        Index of the returned round.
    """

    fit: EGIFit
    epochs: FitEpochs
    attitudes: list[np.ndarray]
    inertia_ratios: np.ndarray
    rounds: list[JointRound]
    best_round: int


def start_shape(material: brdf.BRDF, name: str | None = None) -> FacetModel:
    """The starting shape: a library shape ``name``, else the ellipsoid of
    :data:`START_RADII`, with ``material`` on every facet."""
    paint = Material(material.name, material.params)
    if name is None:
        return primitives.ellipsoid(START_RADII, 3, materials=paint, name="start_ellipsoid")
    from shapes import get_library

    model = get_library().load(name)
    return FacetModel(model.vertices, model.faces, materials=paint, name=name)


def torque_free_attitudes(
    first: np.ndarray, omega: np.ndarray, ratios: np.ndarray, seconds: np.ndarray
) -> np.ndarray:
    """Quaternions (E, 4) of a torque-free rotation in its principal frame.

    Parameters
    ----------
    first : (4,) float
        Inertial → body attitude at ``seconds = 0``.
    omega : (3,) float
        Body rates there (rad/s).
    ratios : (2,) float
        ``J₂/J₁``, ``J₃/J₁``.
    seconds : (E,) float
        Times (s) from the first epoch.
    """
    inertia = np.diag([1.0, *ratios])
    return torque_free_trajectory(first, omega, seconds, inertia)[0]


def principal_start(
    shape: FacetModel, q: np.ndarray, w: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A first-epoch state of ``shape``'s body frame in the principal frame of its
    inertia: the attitude (4,), the rates (3,) and the ratios ``J₂/J₁``, ``J₃/J₁``."""
    moments = np.linalg.eigvalsh(shape.inertia)
    axes = principal_axes(shape)
    first = quaternion_from_matrix(axes.T @ attitude_matrix(q))
    return first, axes.T @ w, moments[1:] / moments[0]


def principal_axes(shape: FacetModel) -> np.ndarray:
    """Columns (3, 3): the principal axes of ``shape``'s inertia in its body frame,
    right-handed, in increasing order of the moments."""
    axes = np.linalg.eigh(shape.inertia)[1]
    return axes * np.sign(np.linalg.det(axes))


def refine_states(
    observations: Sequence[Observations],
    states: list[tuple[np.ndarray, np.ndarray]],
    ratios: np.ndarray,
    material: brdf.BRDF,
) -> tuple[list[np.ndarray], np.ndarray]:
    """Torque-free states and inertia ratios refined against the best EGI (module docstring,
    step 2).

    Parameters
    ----------
    observations : sequence of Observations
    states : list of (first attitude (4,), rates (3,) rad/s), one per file
    ratios : (2,) float
        Starting ``J₂/J₁``, ``J₃/J₁``.
    material : brdf.BRDF

    Returns
    -------
    attitudes : list of (E_k, 4) float
        At every row of each file.
    ratios : (2,) float
    """
    seconds = [(obs.mjd - obs.mjd[0]) * 86400.0 for obs in observations]
    step = max(1, math.ceil(sum(len(obs) for obs in observations) / REFINE_EPOCHS))
    grid = normal_grid(REFINE_NORMALS)
    base = [attitude_matrix(first) for first, _ in states]

    def trajectories(x: np.ndarray, thin: int) -> list[np.ndarray]:
        log_ratios, out = x[:2], []
        for k, time_k in enumerate(seconds):
            turn, omega = x[2 + 6 * k : 5 + 6 * k], x[5 + 6 * k : 8 + 6 * k]
            first = quaternion_from_matrix(
                attitude_matrix(rotation_vector_to_quaternion(turn)) @ base[k]
            )
            out.append(torque_free_attitudes(first, omega, np.exp(log_ratios), time_k[::thin]))
        return out

    thinned = [obs.table.iloc[::step] for obs in observations]
    parts = [Observations(t, o.meta) for t, o in zip(thinned, observations, strict=True)]

    def residuals(x: np.ndarray) -> np.ndarray:
        epochs = FitEpochs.from_observations(parts, trajectories(x, step))
        return egi_residuals(epochs, material, grid)

    x0 = np.concatenate([np.log(ratios), *[np.r_[0.0, 0.0, 0.0, w] for _, w in states]])
    scales = np.concatenate([[_RATIO_SCALE] * 2, np.tile(_SCALES, len(states))])
    found = least_squares(
        residuals, x0, x_scale=scales, diff_step=1e-4, max_nfev=REFINE_STEPS, method="trf"
    )
    return trajectories(found.x, 1), np.exp(found.x[:2])


def fit_joint(
    observations: Sequence[Observations],
    material: brdf.BRDF,
    *,
    estimate_states: StateEstimator,
    normals: int = 1000,
    start: str | None = None,
    rounds: int = ROUNDS,
    seed: int = 0,
) -> JointFit:
    """Shape and attitude of a tumbling object together (module docstring).

    Parameters
    ----------
    observations : sequence of Observations
        Light curves of one object, each a torque-free arc.
    material : brdf.BRDF
        The material (given; the joint mode does not fit it).
    estimate_states : StateEstimator
        The attitude step (module docstring, step 1).
    normals : int
        Grid normals of each round's EGI.
    start : str, optional
        Library shape to start from (default: the ellipsoid of :data:`START_RADII`).
    rounds : int
        Rounds at most.
    seed : int
        Seed of the attitude step.

    Returns
    -------
    JointFit
    """
    if rounds < 1:
        raise ValueError(f"the joint fit needs at least one round, got {rounds}")
    check_epochs(sum(len(obs) for obs in observations), normals)
    shape = start_shape(material, start)
    history: list[JointRound] = []
    best: JointFit | None = None
    for index in range(rounds):
        began = time.perf_counter()
        states, ratios, inversion_rms, estimated = estimate_states(observations, shape, seed)
        refined, ratios = refine_states(observations, states, ratios, material)
        # the EGI on the refined attitudes and on the estimator's own; the lower χ² is kept
        fits = []
        for attitudes in (refined, estimated):
            epochs = FitEpochs.from_observations(list(observations), attitudes)
            fits.append((fit_egi(epochs, material, normals=normals), epochs, attitudes))
        fit, epochs, attitudes = min(fits, key=lambda item: item[0].chi2)
        history.append(
            JointRound(
                fit.chi2, fit.residual_rms_mag(epochs), inversion_rms, time.perf_counter() - began
            )
        )
        if best is not None and fit.chi2 >= best.fit.chi2 * (1.0 - CHI2_TOLERANCE):
            return JointFit(
                best.fit, best.epochs, best.attitudes, best.inertia_ratios, history, best.best_round
            )
        best = JointFit(fit, epochs, attitudes, ratios, history, index)
        solid = convex_solid(fit.normals, fit.areas)
        body = solid.model.vertices @ solid.principal_axes.T + solid.centroid
        paint = Material(material.name, material.params)
        shape = FacetModel(body, solid.model.faces, materials=paint, name=f"joint_round_{index}")
    return best
