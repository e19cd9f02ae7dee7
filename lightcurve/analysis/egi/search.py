"""The torque-free state of a tumbling object of unknown shape: a multi-start search scored by
the best EGI for each trial trajectory (variable projection), independent of any start shape.

The light curve of a convex body under a trial torque-free trajectory is fitted best by the
non-negative EGI of that trajectory (:func:`~lightcurve.analysis.egi.fit.egi_residuals`); its
χ² is the profile of the state with the shape projected out (Golub & Pereyra 1973, "The
differentiation of pseudo-inverses and nonlinear least squares problems whose variables
separate", SIAM J. Numer. Anal. 10, 413). The search minimises it from many random states:

1. **Screen.** :data:`SCREEN_STATES` random states (:func:`random_states`: uniform attitude,
   rates of uniform direction and magnitude in ``rate_range``, log-uniform inertia ratios
   of a physical body) are scored on :data:`SCREEN_NORMALS` normals and
   :data:`SCREEN_EPOCHS` epochs (evenly thinned; their trajectories integrated in one
   batch).
2. **Coarse descent.** The best ``starts`` are refined by trust-region least squares
   (:func:`refine_state`) on the same coarse grid.
3. **Fine descent.** The :data:`FINE_STARTS` lowest distinct minima (:func:`distinct`) are
   refined on :data:`FINE_NORMALS` normals and :data:`FINE_EPOCHS` epochs.
4. **Score and polish.** Each is scored by the χ² of the full EGI fit
   (:func:`~lightcurve.analysis.egi.fit.fit_egi`, ``normals`` normals, every epoch); those
   within :data:`POLISH_WITHIN` of the lowest (the lowest :data:`POLISH_MOST` of them) are
   refined once more on a finer grid (:data:`POLISH_NORMALS`) and kept when their full χ²
   falls; the lowest first.

A state is the first epoch's inertial → body attitude in the principal frame of the inertia,
the body rates there (rad/s) and the ratios ``J₂/J₁``, ``J₃/J₁``
(:func:`torque_free_attitudes`). Two minima are the same when
their attitudes at every epoch agree within :data:`SAME_DEG` after the best constant turn of
the body frame (the frame of a shape recovered with its attitude is arbitrary).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

import brdf
from filters.attitude import (
    attitude_matrix,
    quaternion_from_matrix,
    random_quaternion,
    rotation_vector_to_quaternion,
    torque_free_trajectory,
)
from lightcurve.analysis.egi.epochs import FitEpochs
from lightcurve.analysis.egi.fit import EGIFit, egi_residuals, fit_egi
from lightcurve.analysis.egi.grid import normal_grid
from lightcurve.analysis.egi.profile import EGIProfile
from lightcurve.io.observations import Observations

__all__ = [
    "StateHypothesis",
    "StateMinimum",
    "TorqueFreeState",
    "distinct",
    "frame_free_angles",
    "frame_turn",
    "proper_axis_turns",
    "random_states",
    "refine_state",
    "search_hypotheses",
    "search_states",
    "torque_free_attitudes",
]

#: Default range of the rates' magnitude (rad/s): 0.3–1.5 °/s.
RATE_RANGE = (math.radians(0.3), math.radians(1.5))
#: Range of ``J₂/J₁`` of the random states (``J₃/J₁`` between ``J₂/J₁`` and ``1 + J₂/J₁``).
RATIO_RANGE = (1.0, 3.0)
#: Random states screened, and their coarse grid and epochs.
SCREEN_STATES = 2048
SCREEN_NORMALS = 100
SCREEN_EPOCHS = 150
#: Default screened states refined on the coarse grid, and its evaluations at most.
STARTS = 32
COARSE_STEPS = 60
#: Minima refined on the fine grid, its normals, epochs and evaluations at most.
FINE_STARTS = 6
FINE_NORMALS = 300
FINE_EPOCHS = 300
FINE_STEPS = 20
#: Minima within this factor of the lowest χ² are polished on :data:`POLISH_NORMALS` normals
#: and :data:`POLISH_EPOCHS` epochs (at most :data:`POLISH_STEPS` evaluations): the fine
#: grid's own bias (a few degrees) is then gone, and near-ties are compared alike.
POLISH_WITHIN = 1.25
#: Minima polished at most (the lowest ones): bounds a run whose arc leaves many near-ties
#: (a polish costs about as much as the whole coarse descent of eight starts).
POLISH_MOST = 2
POLISH_NORMALS = 600
POLISH_EPOCHS = 600
POLISH_STEPS = 10
#: Minima whose attitudes agree within this (deg, every epoch, modulo a constant body turn)
#: are one.
SAME_DEG = 5.0
#: Pairings of another file's minimum and frame turn fitted in full (:func:`_joined`).
JOIN_FINALISTS = 4
#: Minima of each search carried as hypotheses (besides the best one's mirror).
KEPT = 3
#: Typical scales of a state's parameters: log ratios, rotation (rad), rates (rad/s).
_SCALES = (0.05, 0.05, 0.05, 0.05, 0.05, 1e-3, 1e-3, 1e-3)


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


@dataclass(frozen=True)
class TorqueFreeState:
    """A torque-free rotation in its principal frame.

    Attributes
    ----------
    first : (4,) float
        Inertial → body attitude at the file's first epoch.
    omega : (3,) float
        Body rates there (rad/s).
    ratios : (2,) float
        ``J₂/J₁``, ``J₃/J₁``.
    """

    first: np.ndarray
    omega: np.ndarray
    ratios: np.ndarray

    def attitudes(self, seconds: np.ndarray) -> np.ndarray:
        """Quaternions (E, 4) at ``seconds`` (s from the first epoch)."""
        return torque_free_attitudes(self.first, self.omega, self.ratios, seconds)


@dataclass(frozen=True)
class StateMinimum:
    """A minimum of the profile χ².

    Attributes
    ----------
    state : TorqueFreeState
    chi2 : float
        χ² of the full EGI fit on its attitudes.
    fit : EGIFit
        That fit.
    attitudes : (E, 4) float
        Its attitudes at every row of the file.
    """

    state: TorqueFreeState
    chi2: float
    fit: EGIFit
    attitudes: np.ndarray


def random_states(
    count: int, rng: np.random.Generator, rate_range: tuple[float, float] = RATE_RANGE
) -> list[TorqueFreeState]:
    """Random torque-free states (module docstring, step 1).

    Parameters
    ----------
    count : int
    rng : numpy.random.Generator
    rate_range : (2,) float
        Smallest and largest magnitude of the rates (rad/s).
    """
    first = random_quaternion(count, rng)
    direction = rng.standard_normal((count, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    omega = direction * rng.uniform(*rate_range, (count, 1))
    middle = np.exp(rng.uniform(*np.log(RATIO_RANGE), count))
    largest = middle * (1.0 + rng.uniform(0.0, 1.0, count) / middle)
    return [
        TorqueFreeState(q, w, np.array([b, c]))
        for q, w, b, c in zip(first, omega, middle, largest, strict=True)
    ]


def _screen(profile: EGIProfile, states: Sequence[TorqueFreeState]) -> np.ndarray:
    """Profile χ² (S,) of many states, their trajectories integrated in one batch."""
    first = np.array([s.first for s in states])
    omega = np.array([s.omega for s in states])
    inertia = np.zeros((len(states), 3, 3))
    inertia[:, 0, 0] = 1.0
    inertia[:, 1, 1], inertia[:, 2, 2] = np.array([s.ratios for s in states]).T
    batch = torque_free_trajectory(first, omega, profile.seconds, inertia)[0]
    return np.array([profile.chi2(attitude_matrix(q)) for q in batch])


def refine_state(
    obs: Observations,
    state: TorqueFreeState,
    material: brdf.BRDF,
    *,
    normals: int = FINE_NORMALS,
    epochs: int = FINE_EPOCHS,
    steps: int = FINE_STEPS,
) -> tuple[TorqueFreeState, float]:
    """A state refined by trust-region least squares on the profile residuals.

    The parameters are the log ratios, a small rotation composed with the first attitude
    on the body side and the rates; the areas are the non-negative EGI of each trial
    trajectory on ``normals`` grid normals and at most ``epochs`` epochs.

    Returns
    -------
    state : TorqueFreeState
    chi2 : float
        Its profile χ² on that grid and those epochs.
    """
    profile = EGIProfile(obs, material, normals=normals, epochs=epochs)
    base = attitude_matrix(state.first)

    def unpack(x: np.ndarray) -> TorqueFreeState:
        turn = attitude_matrix(rotation_vector_to_quaternion(x[2:5]))
        return TorqueFreeState(quaternion_from_matrix(turn @ base), x[5:], np.exp(x[:2]))

    def residuals(x: np.ndarray) -> np.ndarray:
        return profile.residuals(attitude_matrix(unpack(x).attitudes(profile.seconds)))

    x0 = np.concatenate([np.log(state.ratios), np.zeros(3), state.omega])
    found = least_squares(
        residuals, x0, x_scale=_SCALES, diff_step=1e-4, max_nfev=steps, method="trf"
    )
    return unpack(found.x), 2.0 * float(found.cost)


def frame_turn(first: np.ndarray, second: np.ndarray) -> np.ndarray:
    """The constant proper rotation ``R`` (3, 3) minimising ``Σ_e ‖A₁,e − R A₂,e‖²_F``: the
    turn of the body frame that maps the second attitude history onto the first best.

    The orthogonal Procrustes solution (Schönemann 1966, "A generalized solution of the
    orthogonal Procrustes problem", Psychometrika 31, 1) of ``M = Σ A₁ A₂ᵀ = U S Vᵀ``:
    ``R = U diag(1, 1, det(U Vᵀ)) Vᵀ``.

    Parameters
    ----------
    first, second : (E, 4) float
        Inertial → body quaternions at the same epochs.
    """
    u, _, vt = np.linalg.svd(
        np.einsum("eij,ekj->ik", attitude_matrix(first), attitude_matrix(second))
    )
    return u @ np.diag([1.0, 1.0, np.linalg.det(u @ vt)]) @ vt


def frame_free_angles(first: np.ndarray, second: np.ndarray) -> np.ndarray:
    """Angles (deg, E) between two attitude histories after :func:`frame_turn` (``A₁ ≈
    R A₂``): the attitudes compared modulo the body frame.

    Parameters
    ----------
    first, second : (E, 4) float
        Inertial → body quaternions at the same epochs.
    """
    turn = frame_turn(first, second)
    trace = np.einsum("eij,ik,ekj->e", attitude_matrix(first), turn, attitude_matrix(second))
    return np.degrees(np.arccos(np.clip((trace - 1.0) / 2.0, -1.0, 1.0)))


def distinct(histories: Sequence[np.ndarray], same_deg: float = SAME_DEG) -> list[int]:
    """Indices of the histories (in the given order) that differ from every earlier kept one
    by more than ``same_deg`` at some epoch, modulo a constant body turn
    (:func:`frame_free_angles`)."""
    kept: list[int] = []
    for k, q in enumerate(histories):
        if all(frame_free_angles(histories[j], q).max() > same_deg for j in kept):
            kept.append(k)
    return kept


def search_states(
    obs: Observations,
    material: brdf.BRDF,
    *,
    seed: int,
    starts: int = STARTS,
    screened: int = SCREEN_STATES,
    normals: int = 1000,
    rate_range: tuple[float, float] = RATE_RANGE,
) -> list[StateMinimum]:
    """The distinct minima of the profile χ² of one file from random states (module
    docstring), the lowest χ² first.

    Parameters
    ----------
    obs : Observations
        A torque-free arc.
    material : brdf.BRDF
    seed : int
        Seed of the random states.
    starts : int
        Screened states refined.
    screened : int
        Random states screened.
    normals : int
        Grid normals of the final EGI fits.
    rate_range : (2,) float
        Range of the rates' magnitude (rad/s).

    Returns
    -------
    list of StateMinimum
    """
    rng = np.random.default_rng(seed)
    candidates = random_states(max(screened, starts), rng, rate_range)
    coarse = EGIProfile(obs, material, normals=SCREEN_NORMALS, epochs=SCREEN_EPOCHS)
    order = np.argsort(_screen(coarse, candidates))[:starts]
    descended = [
        refine_state(
            obs,
            candidates[k],
            material,
            normals=SCREEN_NORMALS,
            epochs=SCREEN_EPOCHS,
            steps=COARSE_STEPS,
        )
        for k in order
    ]
    descended.sort(key=lambda item: item[1])
    histories = [state.attitudes(coarse.seconds) for state, _ in descended]
    chosen = [descended[k][0] for k in distinct(histories)[:FINE_STARTS]]
    minima = sorted(
        (
            scored_minimum(obs, refine_state(obs, state, material)[0], material, normals)
            for state in chosen
        ),
        key=lambda m: m.chi2,
    )
    minima = polished(obs, minima, material, normals, minima[0].chi2)
    keep = distinct([m.attitudes for m in minima])
    return [minima[k] for k in keep]


def scored_minimum(
    obs: Observations, state: TorqueFreeState, material: brdf.BRDF, normals: int
) -> StateMinimum:
    """A state with the full EGI fit of its attitudes (``normals`` normals, every epoch)."""
    attitudes = state.attitudes(_seconds(obs))
    fit = fit_egi(FitEpochs.from_observations([obs], [attitudes]), material, normals=normals)
    return StateMinimum(state, fit.chi2, fit, attitudes)


def polished(
    obs: Observations,
    minima: Sequence[StateMinimum],
    material: brdf.BRDF,
    normals: int,
    lowest: float,
) -> list[StateMinimum]:
    """The lowest :data:`POLISH_MOST` minima within :data:`POLISH_WITHIN` of ``lowest``
    refined on the polish grid (module docstring, step 4), each kept where its full χ²
    falls; lowest χ² first."""
    out = []
    for rank, minimum in enumerate(sorted(minima, key=_chi2)):
        if rank < POLISH_MOST and minimum.chi2 <= POLISH_WITHIN * lowest:
            state, _ = refine_state(
                obs,
                minimum.state,
                material,
                normals=POLISH_NORMALS,
                epochs=POLISH_EPOCHS,
                steps=POLISH_STEPS,
            )
            minimum = min(minimum, scored_minimum(obs, state, material, normals), key=_chi2)
        out.append(minimum)
    return sorted(out, key=_chi2)


def _chi2(minimum: StateMinimum) -> float:
    return minimum.chi2


@dataclass(frozen=True)
class StateHypothesis:
    """One answer of the search over all files: a state per file and their best EGI.

    Attributes
    ----------
    label : str
        ``"minimum k"`` (the ``k``-th lowest minimum of the first file, from 1) or
        ``"mirror"`` (the lowest one's mirror).
    states : list of TorqueFreeState
        Each file's state in its own principal frame.
    attitudes : list of (E_k, 4) float
        Each file's attitudes in the first file's principal frame.
    fit : EGIFit
        The EGI of all files together on those attitudes.
    epochs : FitEpochs
    """

    label: str
    states: list[TorqueFreeState]
    attitudes: list[np.ndarray]
    fit: EGIFit
    epochs: FitEpochs


def proper_axis_turns() -> np.ndarray:
    """The 24 proper rotations (24, 3, 3) that map the coordinate axes onto themselves (signed
    permutations of determinant 1): how two principal frames of one body can differ."""
    import itertools

    turns = []
    for order in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            turn = np.eye(3)[list(order)] * np.array(signs)[:, None]
            if np.linalg.det(turn) > 0:
                turns.append(turn)
    return np.array(turns)


def _in_frame(turn: np.ndarray, attitudes: np.ndarray) -> np.ndarray:
    """Attitudes ``turn · A`` (the body frame turned by ``turn``)."""
    return quaternion_from_matrix(np.einsum("ij,ejk->eik", turn, attitude_matrix(attitudes)))


def search_hypotheses(
    observations: Sequence[Observations],
    material: brdf.BRDF,
    mirrors: Sequence[np.ndarray],
    *,
    seed: int,
    starts: int = STARTS,
    normals: int = 1000,
    kept: int = KEPT,
) -> list[StateHypothesis]:
    """The search's hypotheses over several files of one object.

    Each file is searched on its own (:func:`search_states`, seed ``seed + k`` for file
    ``k``). The ``kept`` lowest minima of the first file are the hypotheses, with the lowest
    one's mirror (each file's state turned by its half turn in ``mirrors``:
    ``A(t) R_m`` is again torque-free with the same rates; refined by
    :func:`refine_state`). Every other file joins each hypothesis with the minimum of its
    own, and the turn of its principal frame onto the first file's
    (:func:`proper_axis_turns`), that fit best together (:func:`_joined`); the EGI of all
    files is then fitted on ``normals`` normals.

    Parameters
    ----------
    observations : sequence of Observations
        Torque-free arcs of one object.
    material : brdf.BRDF
    mirrors : sequence of (3, 3) float
        Each file's mirror half turn (:func:`lightcurve.analysis.egi.joint.mirror_turns`).
    seed : int
    starts : int
        Screened states refined per file.
    normals : int
    kept : int

    Returns
    -------
    list of StateHypothesis
        Lowest χ² first.
    """
    searched = [
        search_states(obs, material, seed=seed + k, starts=starts, normals=normals)
        for k, obs in enumerate(observations)
    ]
    best = searched[0][0]
    flipped = refine_state(observations[0], _mirror(best.state, mirrors[0]), material)[0]
    mirror = scored_minimum(observations[0], flipped, material, normals)
    (mirror,) = polished(observations[0], [mirror], material, normals, best.chi2)
    firsts = [*searched[0][:kept], mirror]
    labels = [*(f"minimum {k + 1}" for k in range(len(firsts) - 1)), "mirror"]
    hypotheses = []
    for label, first in zip(labels, firsts, strict=True):
        states, attitudes, fit = [first.state], [first.attitudes], first.fit
        for k in range(1, len(observations)):
            pool = [m.state for m in searched[k]]
            if label == "mirror":  # each file's mirror
                pool = [refine_state(observations[k], _mirror(pool[0], mirrors[k]), material)[0]]
            state, joined = _joined(observations[: k + 1], attitudes, pool, material, normals)
            states.append(state)
            attitudes.append(joined)
        epochs = FitEpochs.from_observations(list(observations), attitudes)
        if len(observations) > 1:
            fit = fit_egi(epochs, material, normals=normals)
        hypotheses.append(StateHypothesis(label, states, attitudes, fit, epochs))
    hypotheses.sort(key=lambda h: h.fit.chi2)
    return hypotheses


def _mirror(state: TorqueFreeState, turn: np.ndarray) -> TorqueFreeState:
    """The mirror hypothesis ``A(t) R_m`` of a state: torque-free with the same rates."""
    return TorqueFreeState(
        quaternion_from_matrix(attitude_matrix(state.first) @ turn), state.omega, state.ratios
    )


def _seconds(obs: Observations) -> np.ndarray:
    return (obs.mjd - obs.mjd[0]) * 86400.0


def _joined(
    observations: Sequence[Observations],
    fixed: list[np.ndarray],
    pool: Sequence[TorqueFreeState],
    material: brdf.BRDF,
    normals: int = FINE_NORMALS,
) -> tuple[TorqueFreeState, np.ndarray]:
    """The state of the last file from ``pool`` and the turn of its frame that fit best with
    the other files' ``fixed`` attitudes; its attitudes in the common frame.

    Every pair is scored by the profile χ² on :data:`FINE_NORMALS` normals and thinned
    epochs; the :data:`JOIN_FINALISTS` lowest by the full EGI fit (``normals`` normals,
    every epoch), whose refined normals remove the grid's bias that can hide the right turn.
    """
    step = max(1, math.ceil(max(len(obs) for obs in observations) / FINE_EPOCHS))
    parts = [Observations(obs.table.iloc[::step], obs.meta) for obs in observations]
    grid = normal_grid(FINE_NORMALS)
    last = observations[-1]
    tried = []
    for state in pool:
        own = state.attitudes(_seconds(last))
        for turn in proper_axis_turns():
            turned = _in_frame(turn, own)
            thinned = [q[::step] for q in [*fixed, turned]]
            epochs = FitEpochs.from_observations(parts, thinned)
            tried.append((float(np.sum(egi_residuals(epochs, material, grid) ** 2)), state, turned))
    tried.sort(key=lambda item: item[0])

    def full_chi2(turned: np.ndarray) -> float:
        epochs = FitEpochs.from_observations(list(observations), [*fixed, turned])
        return fit_egi(epochs, material, normals=normals).chi2

    _, state, turned = min(tried[:JOIN_FINALISTS], key=lambda item: full_chi2(item[2]))
    return state, turned
