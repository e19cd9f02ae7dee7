"""Shape and attitude together: the joint EGI mode for tumbling objects of unknown attitude.

**The first round: a search that needs no start shape.** Each file's torque-free state is
searched from many random states, each scored by the best EGI for its trajectory
(:func:`~lightcurve.analysis.egi.search.search_hypotheses`): the lowest minima of the first
file and the lowest one's mirror (below) are the round's hypotheses, each with its EGI on
the full grid; the lowest χ² is returned, and the others are reported
(:attr:`JointFit.hypotheses`, :attr:`JointFit.ambiguous`).

**Further rounds (inversion rounds)**, or every round when a start shape is given, alternate
the two problems that are easy when the other is solved: the attitude for a given shape, and
the EGI for given attitudes (for satellites with known attitudes: Fan, Friedman & Frueh
2019, "Satellite shape recovery from light curves with noise", AMOS Conference; Little 1983
for the EGI):

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

**The mirror.** Over an arc whose Sun and observer
directions stay in one inertial plane (normal ``m``), the attitudes ``A(t) R_m`` with
``R_m = 2 m mᵀ − I`` (a half turn about ``m``) turn the body-frame Sun and observer
directions into their opposites, and the point-reflected (mirror-image) shape then gives the
same light curve (the flux depends only on ``n·L``, ``n·V`` and ``L·V``): a one-arc
ambiguity that only the slow turn of that plane over the arc (a few degrees on a 40-minute
geostationary arc) breaks. The body rates are the same. In an inversion round steps 2
and 3 run for both the estimator's state and its mirror (:func:`mirror_turns`). The
hypotheses are told apart by χ² at the end; the fit is reported as ambiguous
(:attr:`JointFit.ambiguous`) when another hypothesis is within :data:`TIE_DELTA_CHI2` (in
units of the best one's reduced χ²) and its attitude differs by more than
:data:`DISAGREE_DEG`.

Convergence rule: the rounds stop when the best hypothesis's χ² fails to fall by more than
:data:`CHI2_TOLERANCE` (relative) below the best round's, or after ``rounds``; the round with
the lowest χ² is returned.

The frame of the result is the principal frame of the fitted inertia; the attitude is
defined only up to what the light curve can tell apart: the symmetries of the recovered
shape, and the mirror above (docs/shape.md, "Joint mode").
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import least_squares

import brdf
from filters.attitude import (
    attitude_matrix,
    quaternion_from_matrix,
    rotation_vector_to_quaternion,
)
from lightcurve.analysis.egi.epochs import FitEpochs
from lightcurve.analysis.egi.fit import EGIFit, check_epochs, egi_residuals, fit_egi
from lightcurve.analysis.egi.grid import normal_grid
from lightcurve.analysis.egi.search import (
    STARTS,
    frame_free_angles,
    search_hypotheses,
    torque_free_attitudes,
)
from lightcurve.analysis.egi.solid import convex_solid
from lightcurve.io.observations import Observations
from shapes import FacetModel, Material, primitives

__all__ = [
    "Hypothesis",
    "JointFit",
    "JointRound",
    "StateEstimator",
    "fit_joint",
    "mirror_turns",
    "principal_axes",
    "principal_start",
    "refine_states",
    "start_shape",
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
#: Default number of rounds at most (the search alone).
ROUNDS = 1
#: Grid normals and most epochs (evenly thinned) of the variable-projection refinement.
REFINE_NORMALS = 300
REFINE_EPOCHS = 600
#: Residual evaluations of one refinement at most (besides its finite-difference Jacobians).
REFINE_STEPS = 40
#: Typical scales of the refined parameters: rotation (rad), rates (rad/s), log ratios.
_SCALES = (0.05, 0.05, 0.05, 1e-3, 1e-3, 1e-3)
_RATIO_SCALE = 0.05
#: Hypotheses whose χ² exceeds the best one's by less than this many reduced χ² are tied:
#: the light curve does not tell them apart (Δχ² = 9: three standard deviations of one
#: parameter).
TIE_DELTA_CHI2 = 9.0
#: The hypotheses of each inversion round: the estimator's state and its mirror.
HYPOTHESES = ("direct", "mirror")
#: Reduced χ² above which the returned fit is a misfit (the magnitude residuals twice the
#: noise).
MISFIT_REDUCED_CHI2 = 4.0
#: Tied hypotheses whose attitudes differ by more than this (deg) make the fit ambiguous.
DISAGREE_DEG = 5.0


@dataclass(frozen=True)
class Hypothesis:
    """The best fit of one hypothesis in a round (over its refined and estimated attitudes).

    Attributes
    ----------
    label : str
        The search's ``"minimum k"`` or ``"mirror"``
        (:func:`~lightcurve.analysis.egi.search.search_hypotheses`), or in an inversion
        round ``"direct"`` (the estimator's state) or ``"mirror"`` (:func:`mirror_turns`).
    chi2 : float
        χ² of its best EGI.
    residual_rms_mag : float
    round : int
        Round of that fit.
    angle_to_best_deg : float
        Largest angle (deg) at a file's last epoch between its attitudes and the returned
        hypothesis's, after the constant body turn that maps one onto the other best
        (:func:`~lightcurve.analysis.egi.search.frame_free_angles`).
    """

    label: str
    chi2: float
    residual_rms_mag: float
    round: int
    angle_to_best_deg: float


@dataclass(frozen=True)
class JointRound:
    """One round of the joint fit.

    Attributes
    ----------
    chi2 : float
        χ² of the round's best EGI (over hypotheses and the refined or estimated attitudes).
    residual_rms_mag : float
        rms of its magnitude residuals.
    hypothesis : str
        The hypothesis of that EGI (:data:`HYPOTHESES`).
    inversion_rms_mag : float
        rms residual of the attitude inversion on the round's starting shape (mean over
        files).
    seconds : float
        Wall time of the round.
    """

    chi2: float
    residual_rms_mag: float
    hypothesis: str
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
    hypotheses : list of Hypothesis
        The best fit of each hypothesis in the returned round, lowest χ² first (the
        returned one). The hypotheses are relative to each round's estimated state: the
        mirror of one round is the state of the next when the mirror won.
    """

    fit: EGIFit
    epochs: FitEpochs
    attitudes: list[np.ndarray]
    inertia_ratios: np.ndarray
    rounds: list[JointRound]
    best_round: int
    hypotheses: list[Hypothesis]

    @property
    def reduced_chi2(self) -> float:
        """χ² of the returned fit per degree of freedom (epochs less the non-zero areas)."""
        free = int(np.count_nonzero(self.fit.areas))
        return self.fit.chi2 / max(len(self.epochs) - free, 1)

    @property
    def misfit(self) -> bool:
        """True when the returned fit's reduced χ² exceeds :data:`MISFIT_REDUCED_CHI2`: no
        hypothesis explains the light curve, and the attitude found is not an answer (on
        the benchmark's arcs, a search that missed the true state's basin)."""
        return self.reduced_chi2 > MISFIT_REDUCED_CHI2

    @property
    def ambiguous(self) -> bool:
        """True when another hypothesis's χ² is within :data:`TIE_DELTA_CHI2` reduced χ²
        of the returned one's and its attitude differs by more than :data:`DISAGREE_DEG`:
        the light curve does not choose the attitude."""
        best = self.hypotheses[0].chi2
        reduced = max(self.reduced_chi2, 1.0)
        return any(
            (h.chi2 - best) / reduced < TIE_DELTA_CHI2 and h.angle_to_best_deg > DISAGREE_DEG
            for h in self.hypotheses[1:]
        )


def start_shape(material: brdf.BRDF, name: str | None = None) -> FacetModel:
    """The starting shape of the inversion rounds: a library shape ``name``, else (None or
    ``"ellipsoid"``) the ellipsoid of :data:`START_RADII`, with ``material`` on every
    facet."""
    paint = Material(material.name, material.params)
    if name in (None, "ellipsoid"):
        return primitives.ellipsoid(START_RADII, 3, materials=paint, name="start_ellipsoid")
    from shapes import get_library

    model = get_library().load(name)
    return FacetModel(model.vertices, model.faces, materials=paint, name=name)


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


def mirror_turns(observations: Sequence[Observations]) -> list[np.ndarray]:
    """Each file's half turn ``R_m = 2 m mᵀ − I`` (3, 3) about the normal ``m`` of the
    inertial plane nearest its Sun and observer directions (the right singular vector of the
    smallest singular value of the stacked unit vectors): ``A(t) R_m`` is the mirror
    hypothesis of attitudes ``A(t)`` (module docstring)."""
    turns = []
    for obs in observations:
        directions = np.vstack(
            [
                obs.sun_vectors / np.linalg.norm(obs.sun_vectors, axis=1, keepdims=True),
                obs.observer_vectors / np.linalg.norm(obs.observer_vectors, axis=1, keepdims=True),
            ]
        )
        normal = np.linalg.svd(directions, full_matrices=False)[2][-1]
        turns.append(2.0 * np.outer(normal, normal) - np.eye(3))
    return turns


def _mirrored(
    states: list[tuple[np.ndarray, np.ndarray]],
    estimated: list[np.ndarray],
    turns: list[np.ndarray],
) -> tuple[list[tuple[np.ndarray, np.ndarray]], list[np.ndarray]]:
    """The mirror hypothesis ``A R_m`` of first states and per-epoch attitudes (rates
    unchanged)."""
    mirrored_states = [
        (quaternion_from_matrix(attitude_matrix(first) @ turn), omega)
        for (first, omega), turn in zip(states, turns, strict=True)
    ]
    mirrored = [
        quaternion_from_matrix(attitude_matrix(q) @ turn)
        for q, turn in zip(estimated, turns, strict=True)
    ]
    return mirrored_states, mirrored


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
    estimate_states: StateEstimator | None = None,
    normals: int = 1000,
    start: str | None = None,
    rounds: int = ROUNDS,
    seed: int = 0,
    starts: int = STARTS,
) -> JointFit:
    """Shape and attitude of a tumbling object together (module docstring).

    Parameters
    ----------
    observations : sequence of Observations
        Light curves of one object, each a torque-free arc.
    material : brdf.BRDF
        The material (given; the joint mode does not fit it).
    estimate_states : StateEstimator, optional
        The attitude step of the inversion rounds (module docstring); needed for
        ``rounds > 1`` or a ``start`` shape.
    normals : int
        Grid normals of each round's EGI.
    start : str, optional
        Start the inversion rounds from this shape (a library name, or ``"ellipsoid"``: the
        ellipsoid of :data:`START_RADII`) instead of the search.
    rounds : int
        Rounds at most.
    seed : int
        Seed of the search and of the attitude step.
    starts : int
        Screened states the search refines per file.

    Returns
    -------
    JointFit
    """
    if rounds < 1:
        raise ValueError(f"the joint fit needs at least one round, got {rounds}")
    if estimate_states is None and (rounds > 1 or start is not None):
        raise ValueError("the inversion rounds (rounds > 1 or a start shape) need estimate_states")
    check_epochs(sum(len(obs) for obs in observations), normals)
    turns = mirror_turns(observations)
    shape = None if start is None else start_shape(material, start)
    history: list[JointRound] = []
    best: JointFit | None = None
    for index in range(rounds):
        began = time.perf_counter()
        if shape is None:
            candidates, inversion_rms = _searched(observations, material, turns, seed, starts)
        else:
            states, ratios, inversion_rms, estimated = estimate_states(observations, shape, seed)
            candidates = _inverted(observations, material, turns, states, ratios, estimated)
        candidates = [
            (fit_egi(epochs, material, normals=normals) if fit is None else fit, epochs, *rest)
            for fit, epochs, *rest in candidates
        ]
        fit, epochs, attitudes, ratios, label = min(candidates, key=lambda item: item[0].chi2)
        history.append(
            JointRound(
                fit.chi2,
                fit.residual_rms_mag(epochs),
                label,
                inversion_rms,
                time.perf_counter() - began,
            )
        )
        if best is not None and fit.chi2 >= best.fit.chi2 * (1.0 - CHI2_TOLERANCE):
            return replace(best, rounds=history)
        ranked = _ranked(candidates, index)
        best = JointFit(fit, epochs, attitudes, ratios, history, index, ranked)
        solid = convex_solid(fit.normals, fit.areas)
        body = solid.model.vertices @ solid.principal_axes.T + solid.centroid
        paint = Material(material.name, material.params)
        shape = FacetModel(body, solid.model.faces, materials=paint, name=f"joint_round_{index}")
    return best


#: One candidate of a round: its EGI (None: still to fit), epochs, per-file attitudes, the
#: inertia ratios and the hypothesis's label.
_Candidate = tuple[EGIFit | None, FitEpochs, list[np.ndarray], np.ndarray, str]


def _searched(
    observations: Sequence[Observations],
    material: brdf.BRDF,
    turns: list[np.ndarray],
    seed: int,
    starts: int,
) -> tuple[list[_Candidate], float]:
    """The search's hypotheses (:func:`~lightcurve.analysis.egi.search.search_hypotheses`)
    as candidates; no inversion residual (NaN)."""
    found = search_hypotheses(observations, material, turns, seed=seed, starts=starts)
    return [(h.fit, h.epochs, h.attitudes, h.states[0].ratios, h.label) for h in found], math.nan


def _inverted(
    observations: Sequence[Observations],
    material: brdf.BRDF,
    turns: list[np.ndarray],
    states: list[tuple[np.ndarray, np.ndarray]],
    ratios: np.ndarray,
    estimated: list[np.ndarray],
) -> list[_Candidate]:
    """The estimator's state and its mirror, each refined (steps 2 and 3): the refined and
    the estimator's own attitudes as candidates, their EGI still to fit."""
    candidates: list[_Candidate] = []
    for label in HYPOTHESES:
        if label == "mirror":
            states, estimated = _mirrored(states, estimated, turns)
        refined, fitted_ratios = refine_states(observations, states, ratios, material)
        for attitudes in (refined, estimated):
            epochs = FitEpochs.from_observations(list(observations), attitudes)
            candidates.append((None, epochs, attitudes, fitted_ratios, label))
    return candidates


def _ranked(candidates: list, index: int) -> list[Hypothesis]:
    """Each label's lowest-χ² candidate as a hypothesis, lowest first, with its attitudes'
    largest angle at a file's last epoch from the lowest one's (modulo a constant body
    turn)."""
    leaders: dict[str, tuple] = {}
    for candidate in candidates:
        label = candidate[4]
        if label not in leaders or candidate[0].chi2 < leaders[label][0].chi2:
            leaders[label] = candidate
    order = sorted(leaders.values(), key=lambda c: c[0].chi2)
    lowest = order[0][2]
    return [
        Hypothesis(
            label,
            fit.chi2,
            fit.residual_rms_mag(epochs),
            index,
            max(
                float(frame_free_angles(np.concatenate(lowest), np.concatenate(attitudes))[e])
                for e in np.cumsum([len(q) for q in attitudes]) - 1
            ),
        )
        for fit, epochs, attitudes, _, label in order
    ]
