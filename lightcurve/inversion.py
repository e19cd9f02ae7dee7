"""Photometric attitude inversion: the programmatic API behind ``lightcurve invert``.

:func:`invert` estimates the attitude, body rates (and optionally inertia ratios,
albedo–area scale and shape) of an object from one light curve with one of three
estimators (``docs/inversion.md`` has the equations and measured figures):

``"ukf"``
    One shape. A batch maximum-a-posteriori fit of the initial state on the first part
    of the data (:mod:`filters.global_search`: prior-centred screening and batched
    Levenberg–Marquardt; uniform on SO(3) without ``q0``), then the USQUE attitude UKF
    (:mod:`filters.ukf`) on the rest.
``"mmae"``
    Several shapes: the same initial fit per shape, then a bank of UKFs with model
    probabilities, the fused attitude and a consistency test that reports ``none_fits``
    (:mod:`filters.mmae`).
``"pf"``
    One or several shapes, with or without a prior: global search of the initial state
    (uniform on SO(3), rates in a ball, shape index per candidate), particles seeded
    around the best distinct candidates, then the regularised particle filter with
    tempering (:mod:`filters.particle`); the result lists the posterior modes with their
    symmetry-equivalent attitudes.

Every estimator runs on :class:`~lightcurve.measurement.PhotometricModel`. The result,
:class:`InversionResult`, holds the final state at the LAST measurement epoch and a table
of per-epoch estimates.

Conventions: quaternions scalar-last, ``A(q)`` inertial → body, sign-canonical
(``q4 ≥ 0``); rates in rad/s in the body frame; ``attitude_sigma_deg`` is the total 1σ
attitude uncertainty ``√(tr P_δθ)`` in degrees (``P_δθ`` the covariance of the body-frame
attitude-error vector); ``sigma_att_x/y/z`` in the table are its per-axis square roots.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd
import torch

import brdf
from filters.attitude import (
    attitude_angle,
    quaternion_canonical,
    quaternion_conjugate,
    quaternion_multiply,
    quaternion_normalize,
    quaternion_to_rotation_vector,
    rotation_vector_to_quaternion,
    tanh_from_inertia,
)
from filters.gaussian import chi2_band
from filters.global_search import (
    BatchProblem,
    Candidates,
    Prior,
    SearchResult,
    distinct_states,
    global_search,
    refine,
)
from filters.mmae import MultipleModelBank
from filters.particle import AttitudeParticleFilter, Mode
from filters.symmetry import SymmetryGroup, symmetry_group
from filters.ukf import AttitudeUKF, ProcessNoise, default_gate, torque_free_dynamics
from lightcurve.geometry import reciprocity_twin
from lightcurve.measurement import PhotometricModel
from lightcurve.observations import Observations
from shapes import FacetModel, get_library

__all__ = [
    "METHODS",
    "InversionOptions",
    "InversionResult",
    "invert",
    "shape_symmetry",
]

METHODS = ("ukf", "mmae", "pf")
#: Fewest measurements an inversion accepts (six unknowns and a consistency check).
MIN_MEASUREMENTS = 30

Progress = Callable[[float, str], None]


#: Default candidates refined per window by the UKF/MMAE search (see ``refine_keep``).
FILTER_REFINE_KEEP = (128, 128, 128, 24, 6)
#: Default for the PF's search, whose windows run on to the whole arc.
PF_REFINE_KEEP = (128, 128, 128, 128, 128, 24, 6)


@dataclass(frozen=True)
class InversionOptions:
    """Tuning of :func:`invert` (defaults are the ones measured in ``docs/inversion.md``).

    Attributes
    ----------
    init : {"search", "none"}
        ``"search"``: fit the initial state on the first ``init_window_s`` of data before
        filtering (always done when ``q0`` is not given); ``"none"``: start the UKF/MMAE
        filters at the prior ``q0``, ``omega0`` directly.
    init_window_s : float
        Longest window of the UKF/MMAE initial fit (s); at most half the data span is
        used, the filter takes over after it.
    pf_window_s : float
        Longest window of the PF's initial search (s), at most the whole arc. The search
        only proposes where the particles start (they are weighted back to the prior) and
        the filter then weighs them by every measurement, so the search may use all the
        data: on a box at up to 5°/s a wrong state fitted the first 300 s better than the
        truth (χ² 78.3 against 79.8 on 90 measurements) and only the 480 s window told
        them apart.
    pf_window_growth : float
        Growth factor of the PF search's successive windows (the UKF/MMAE search doubles
        them). A fit to a short window leaves a rate error that a longer window turns into
        an attitude error; at 4°/s the 120 s fit nearest the truth was 12.7° and 0.62°/s
        off and lost the truth's basin on the 240 s window, while growing 1.5-fold reached
        it at 152 s.
    local_candidates : int
        Prior draws screened per shape when ``q0`` is given.
    global_candidates : int
        Uniform candidates screened (per shape) without ``q0`` and for the PF.
    refine_keep : tuple of int, optional
        Candidates (per shape) refined on each growing window (30 s, doubling up to
        ``init_window_s``, or growing ``pf_window_growth``-fold up to ``pf_window_s``);
        default ``(128, 128, 128, 24, 6)`` for the UKF/MMAE and
        ``(128, 128, 128, 128, 128, 24, 6)`` for the PF, whose windows 30, 45, 68, 101 and
        152 s then carry 128 candidates. The first count on the first window, the last on
        the last and the ones between on the windows between (the last of them repeated).
        Short windows are fitted equally well by many states, so many candidates go on until
        a window of 120–150 s ranks them. The photometric twins of the candidates kept at the
        first hard cut are refined too: the mirror twins of a mirror-symmetric shape and,
        in a search without ``q0``, the reciprocity twins of every candidate.
    hypotheses : int
        Distinct initial fits each UKF keeps as weighted hypotheses (multiple-hypothesis
        UKF) and the PF seeds particles around.
    search_tolerance : float
        Model tolerance (mag) of the screening (see :func:`filters.global_search.screen`).
    search_rounds : int
        Screening rounds with fresh candidates while the best initial fit is poor
        (``χ²`` above twice the number of measurements).
    search_min_improvement : float
        The UKF/MMAE search stops after a round that lowers the best fit by less than
        this fraction (see :func:`filters.global_search.global_search`): with a truth
        outside the bank every round fits poorly, and further rounds cost time without
        changing the answer. The PF's search runs all its rounds while the fit is poor.
    search_contention : float
        MMAE search: a shape whose best fit of a window is worse than this many times the
        best shape's (``χ²``, or the window's number of measurements if larger) goes on
        with ``hypotheses`` candidates and no twins (see
        :func:`filters.global_search.global_search`); ``inf`` gives every shape the full
        schedule.
    max_epochs : int
        Measurements per refinement window, at least.
    max_sample_rotation_deg : float
        Longest rotation (deg) at ``omega_max`` between the measurements of a refinement
        window: longer windows get more than ``max_epochs`` measurements, so that a fast
        rotator's light curve is not aliased (see
        :func:`filters.global_search.global_search`).
    process_noise_attitude : float
        UKF attitude noise density, rad²/s.
    process_noise_rate : float
        UKF angular-acceleration noise density, rad²/s³.
    alpha, beta, kappa : float
        Sigma-point parameters.
    underweighting : float
        UKF underweighting ``γ``.
    gate_probability : float
        False-rejection probability of the innovation gate (0 disables it).
    estimate_inertia : bool
        Estimate the tanh inertia parameters ``k`` (UKF/PF; principal axes from the shape).
    inertia_sigma : float
        Prior 1σ of ``k`` around the shape's value.
    estimate_offset : bool
        Estimate a magnitude offset (the albedo–area scale ``s``: ``Δm = −2.5 log10 s``).
    offset_sigma_mag : float
        Prior 1σ of the offset (mag).
    probability_floor : float
        MMAE probability floor.
    consistency_window : int
        Measurements in the NIS consistency window (MMAE, UKF and PF).
    consistency_level : float
        Quantile of the windowed NIS above which a model does not fit.
    likelihood : {"gaussian", "student"}
        PF measurement likelihood.
    student_nu : float
        Degrees of freedom of the Student-t likelihood.
    ess_threshold : float
        PF resampling / tempering threshold (fraction of N).
    bandwidth : float
        PF roughening shrink factor.
    moves : int
        PF Metropolis–Hastings moves per resampling (0: roughening only).
    mixture_tracking : bool
        PF mixture tracking (Vermaak, Doucet & Pérez 2003): the particles seeded around
        each search candidate form a mixture component that is resampled within itself,
        so a mode that the early measurements disfavour keeps its particles and can win
        later (see :mod:`filters.particle`).
    move_window : int
        Past measurements in the resample-move target.
    mode_angle_deg, mode_rate_deg_s : float
        PF clustering radii.
    min_mode_weight : float
        Modes lighter than this are not reported.
    polish : bool
        With the Gaussian likelihood, refine every PF cluster by Levenberg–Marquardt on
        the whole arc and weigh the distinct optima by their Laplace evidence (see
        :func:`_polish`); the summary then reports the heaviest optimum and its
        Gauss–Newton covariance.
    faint_margin : float
        Magnitudes between the faintest measurement and the prediction floor.
    compile : bool
        Compile the renderers' kernels (pays off for PF runs with many particles).
    mode_offset_sigma_deg : float
        ``modes=True``: 1σ per axis (deg) of the prior of a stabilised profile's offset
        (:mod:`lightcurve.attitude_modes`).
    mode_consistency_level : float
        ``modes=True``: quantile of ``χ²`` (``n − k`` degrees of freedom) above which a
        stabilised hypothesis does not fit and is discarded.
    """

    init: str = "search"
    init_window_s: float = 300.0
    pf_window_s: float = 1200.0
    pf_window_growth: float = 1.5
    local_candidates: int = 1024
    global_candidates: int = 20_000
    refine_keep: tuple[int, ...] | None = None
    hypotheses: int = 6
    search_tolerance: float = 0.0
    search_rounds: int = 3
    search_min_improvement: float = 0.1
    search_contention: float = 10.0
    max_epochs: int = 90
    max_sample_rotation_deg: float = 20.0
    process_noise_attitude: float = 1e-12
    process_noise_rate: float = 1e-16
    alpha: float = 1.0
    beta: float = 2.0
    kappa: float = 0.0
    underweighting: float = 0.0
    gate_probability: float = 1e-4
    estimate_inertia: bool = False
    inertia_sigma: float = 0.5
    estimate_offset: bool = False
    offset_sigma_mag: float = 0.5
    probability_floor: float = 1e-3
    consistency_window: int = 60
    consistency_level: float = 0.99
    likelihood: str = "gaussian"
    student_nu: float = 4.0
    ess_threshold: float = 0.5
    bandwidth: float = 0.5
    moves: int = 0
    mixture_tracking: bool = True
    move_window: int = 8
    mode_angle_deg: float = 10.0
    mode_rate_deg_s: float = 0.5
    min_mode_weight: float = 0.01
    polish: bool = True
    faint_margin: float = 7.5
    compile: bool = False
    mode_offset_sigma_deg: float = 10.0
    mode_consistency_level: float = 0.999

    def __post_init__(self) -> None:
        if not (self.mode_offset_sigma_deg > 0 and 0 < self.mode_consistency_level < 1):
            raise ValueError("mode_offset_sigma_deg must be > 0, mode_consistency_level in (0, 1)")
        if self.init not in ("search", "none"):
            raise ValueError(f"init must be 'search' or 'none', got {self.init!r}")
        if self.likelihood not in ("gaussian", "student"):
            raise ValueError(f"likelihood must be 'gaussian' or 'student', got {self.likelihood!r}")


@dataclass
class InversionResult:
    """Outcome of :func:`invert` (the fields the batch command writes).

    Attributes
    ----------
    method : str
    shape : str or None
        Most probable (or only) shape.
    shape_probabilities : dict
        Shape name → posterior probability.
    none_fits : bool
        No candidate shape is consistent with the last measurements.
    epoch_mjd : float
        Epoch of the LAST measurement (UTC MJD); the state below holds there.
    quaternion : (4,) numpy.ndarray
        Attitude, inertial → body, sign-canonical.
    omega_rad_s : (3,) numpy.ndarray
        Body rates (rad/s).
    attitude_sigma_deg : float
        Total 1σ attitude uncertainty ``√(tr P_δθ)`` (deg).
    omega_sigma_rad_s : (3,) numpy.ndarray
        1σ of the rates (rad/s).
    modes : list of dict
        PF posterior modes: ``quaternion``, ``omega_rad_s``, ``weight`` plus ``shape``,
        ``attitude_sigma_deg`` and ``equivalent_quaternions`` (the symmetry-equivalent
        attitudes of the mode's shape); empty for UKF/MMAE.
    residual_rms_mag : float
        RMS of the measured − predicted magnitudes (gated measurements excluded).
    n_measurements : int
    estimates : pandas.DataFrame
        One row per epoch: ``mjd, q1..q4, wx, wy, wz, sigma_att_x/y/z`` (deg),
        ``sigma_wx/wy/wz`` (rad/s), ``predicted_mag, residual, gated`` and ``p_<shape>``
        with several shapes.
    notes : list of str
    parameters : dict
        Other estimates: ``k1, k2`` (tanh inertia), ``magnitude_offset`` (mag).
    symmetry : dict
        Symmetry group of the reported shape (order, continuous axis, quaternions).
    covariance : (6, 6) numpy.ndarray
        Final covariance of ``[δθ (rad, body frame), ω (rad/s)]``.
    runtime_s : float
    attitude_mode : dict or None
        With ``modes=True``: the summary of :func:`lightcurve.attitude_modes.identify_attitude_mode`
        (``attitude_mode``, ``attitude_mode_probability``, ``attitude_offsets_deg``, …).
    """

    method: str
    shape: str | None
    shape_probabilities: dict[str, float]
    none_fits: bool
    epoch_mjd: float
    quaternion: np.ndarray
    omega_rad_s: np.ndarray
    attitude_sigma_deg: float
    omega_sigma_rad_s: np.ndarray
    modes: list[dict[str, Any]]
    residual_rms_mag: float
    n_measurements: int
    estimates: pd.DataFrame
    notes: list[str] = field(default_factory=list)
    parameters: dict[str, float] = field(default_factory=dict)
    symmetry: dict[str, Any] = field(default_factory=dict)
    covariance: np.ndarray = field(default_factory=lambda: np.full((6, 6), np.nan))
    runtime_s: float = 0.0
    attitude_mode: dict[str, Any] | None = None

    def summary(self) -> dict[str, Any]:
        """JSON-ready dictionary of the scalar fields (no table)."""
        return {
            "method": self.method,
            "shape": self.shape,
            "shape_probabilities": {k: float(v) for k, v in self.shape_probabilities.items()},
            "none_fits": bool(self.none_fits),
            "epoch_mjd": float(self.epoch_mjd),
            "quaternion": [float(v) for v in self.quaternion],
            "omega_rad_s": [float(v) for v in self.omega_rad_s],
            "attitude_sigma_deg": float(self.attitude_sigma_deg),
            "omega_sigma_rad_s": [float(v) for v in self.omega_sigma_rad_s],
            "modes": self.modes,
            "residual_rms_mag": float(self.residual_rms_mag),
            "n_measurements": int(self.n_measurements),
            "notes": list(self.notes),
            "parameters": {k: float(v) for k, v in self.parameters.items()},
            "symmetry": self.symmetry,
            "runtime_s": float(self.runtime_s),
            **(self.attitude_mode or {}),
        }


# ----------------------------------------------------------------------------- helpers
def shape_symmetry(shape: FacetModel) -> SymmetryGroup:
    """Rotational symmetry group of a shape (facets, materials, tangents, inertia)."""
    compiled = shape.compiled()
    anisotropic = np.array(
        [
            brdf.get(compiled.materials[i].brdf, **compiled.materials[i].params).anisotropic
            for i in compiled.material_index
        ]
    )
    com = shape.center_of_mass
    return symmetry_group(
        compiled.centroids - com,
        compiled.normals,
        compiled.areas,
        compiled.material_index,
        compiled.tangents,
        anisotropic,
        shape.inertia,
        vertices=shape.vertices - com,
    )


def _resolve_shapes(shapes: Any) -> dict[str, FacetModel]:
    if isinstance(shapes, FacetModel):
        return {shapes.name: shapes}
    if isinstance(shapes, str):
        shapes = [shapes]
    if isinstance(shapes, Mapping):
        resolved = dict(shapes)
    else:
        library = get_library()
        resolved = {}
        for name in shapes:
            try:
                resolved[name] = library.load(name)
            except (ValueError, OSError) as exc:
                raise ValueError(f"shape {name!r} cannot be loaded: {exc}") from None
    if not resolved:
        raise ValueError("no candidate shape given")
    for name, model in resolved.items():
        if not isinstance(model, FacetModel):
            raise ValueError(f"shape {name!r} is not a FacetModel")
    return resolved


def _check_observations(observations: Observations) -> None:
    where = observations.source or observations.name
    if not observations.has_magnitudes:
        raise ValueError(f"{where}: no 'mag'/'mag_err' columns: nothing to invert")
    n = len(observations)
    if n < MIN_MEASUREMENTS:
        raise ValueError(
            f"{where}: {n} measurement(s); at least {MIN_MEASUREMENTS} are needed to invert"
        )
    for column in ("mag", "mag_err"):
        values = observations.table[column].to_numpy(dtype=float)
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            raise ValueError(f"{where}: row {bad[0] + 1}, column '{column}': value is not finite")
    if observations.relative.any():
        raise ValueError(
            f"{where}: relative (uncalibrated) light curves cannot be inverted for attitude "
            "with a fixed shape; use calibrated magnitudes"
        )


@dataclass
class _Context:
    """Everything the estimators share for one run."""

    observations: Observations
    model: PhotometricModel
    options: InversionOptions
    progress: Progress | None
    rng: np.random.Generator
    seed: int
    notes: list[str]
    start: float
    omega_max: float
    _groups: dict[int, SymmetryGroup] = field(default_factory=dict)

    def symmetry(self, s: int) -> SymmetryGroup:
        """Symmetry group of shape ``s`` (computed once)."""
        if s not in self._groups:
            self._groups[s] = shape_symmetry(self.model.shapes[self.names[s]])
        return self._groups[s]

    def report(self, fraction: float, message: str) -> None:
        if self.progress is not None:
            self.progress(min(max(fraction, 0.0), 1.0), message)

    @property
    def names(self) -> list[str]:
        return self.model.names

    def problem(self) -> BatchProblem:
        return batch_problem(self.model, self.options.estimate_inertia)

    def windows(self, longest: float, growth: float = 2.0) -> tuple[float, ...]:
        """Growing fit windows (s): 30 s, growing ``growth``-fold, up to ``longest``."""
        windows = [30.0] if longest > 30.0 else []
        while windows and growth * windows[-1] < longest:
            windows.append(growth * windows[-1])  # grow gently: LM stays in its basin
        return (*windows, longest)


def batch_problem(model: PhotometricModel, estimate_inertia: bool = False) -> BatchProblem:
    """The torque-free batch problem (:class:`filters.global_search.BatchProblem`) of a
    photometric model's measurements and shapes."""

    def measure(q: torch.Tensor, epochs: np.ndarray, shape: torch.Tensor) -> torch.Tensor:
        return model.magnitude_by_shape(q.to(model.dtype), epochs, shape).to(torch.float64)

    shapes = list(model.shapes.values())
    return BatchProblem(
        model.times,
        model.magnitudes,
        model.errors,
        measure,
        [s.inertia for s in shapes],
        principal_axes=[s.principal_axes for s in shapes],
        estimate_inertia=estimate_inertia,
    )


def _search(
    ctx: _Context,
    prior: Prior | None,
    shapes: Sequence[int],
    candidates: int,
    keep_last: int,
    per_shape: bool = False,
    for_pf: bool = False,
) -> SearchResult:
    """Initial-state search on the first window (prior-centred or uniform); the PF's
    search runs on longer windows (``pf_window_s``, see :class:`InversionOptions`)."""
    opt = ctx.options
    span = float(ctx.model.times[-1] - ctx.model.times[0])
    windows = (
        ctx.windows(min(opt.pf_window_s, span), opt.pf_window_growth)
        if for_pf
        else ctx.windows(min(opt.init_window_s, 0.5 * span))
    )
    counts = opt.refine_keep or (PF_REFINE_KEEP if for_pf else FILTER_REFINE_KEEP)
    # First window: counts[0]; last: counts[-1]; windows between: the counts between.
    keep = [counts[min(i, len(counts) - 2)] for i in range(len(windows) - 1)] + [counts[-1]]
    keep[-1] = max(keep[-1], keep_last)
    keep = [max(k, keep[-1]) for k in keep]
    problem = ctx.problem()
    if len(shapes) != ctx.model.n_shapes or list(shapes) != list(range(ctx.model.n_shapes)):
        # One shape of several: give the search that shape's index space only.
        problem = dataclasses.replace(
            problem,
            measure=_remapped(problem.measure, shapes),
            inertias=[problem.inertias[s] for s in shapes],
            principal_axes=[problem.principal_axes[s] for s in shapes],
        )
    result = global_search(
        problem,
        n_candidates=candidates,
        omega_max=ctx.omega_max,
        n_shapes=len(shapes),
        seed=ctx.rng,
        prior=prior,
        screen_duration=windows[0],
        windows=windows,
        keep=keep,
        max_epochs=ctx.options.max_epochs,
        max_rotation=math.radians(ctx.options.max_sample_rotation_deg),
        tolerance=ctx.options.search_tolerance,
        twins=_twin_function(ctx, shapes, reciprocity=prior is None),
        groups=[ctx.symmetry(s) for s in shapes],
        rounds=ctx.options.search_rounds,
        min_improvement=0.0 if for_pf else ctx.options.search_min_improvement,
        per_shape=per_shape,
        contention=ctx.options.search_contention,
        progress=lambda message: ctx.report(0.0, message),
    )
    result.shape = np.asarray(shapes)[result.shape]
    return result


def _twin_function(ctx: _Context, shapes: Sequence[int], reciprocity: bool) -> Callable | None:
    """The photometric twins of search candidates, at the first epoch's geometry: mirror
    twins for the shapes that have them and, with ``reciprocity``, the reciprocity twin
    (:func:`lightcurve.geometry.reciprocity_twin`) of every candidate and of its mirror
    twin. A search from a prior leaves out the reciprocity twin: it is half a turn away."""
    groups = [ctx.symmetry(s) for s in shapes]
    mirrors = any(len(g.reflections) for g in groups)
    if not (mirrors or reciprocity):
        return None
    sun = ctx.model.observations.sun_vectors[0]
    observer = ctx.model.observations.observer_vectors[0]

    def mirrored(q: np.ndarray, omega: np.ndarray, shape: np.ndarray) -> tuple:
        q_out, w_out = q.copy(), omega.copy()
        has = np.zeros(len(q), dtype=bool)
        for local, group in enumerate(groups):
            rows = shape == local
            twin = group.mirror_twin(q[rows], omega[rows], sun, observer)
            if twin is not None and rows.any():
                q_out[rows], w_out[rows] = twin
                has |= rows
        return q_out, w_out, has

    def twins(q: np.ndarray, omega: np.ndarray, shape: np.ndarray) -> list[tuple]:
        found = [mirrored(q, omega, shape)] if mirrors else []
        if reciprocity:
            everyone = np.ones(len(q), dtype=bool)
            found += [
                (reciprocity_twin(q_, sun, observer), w_, has)
                for q_, w_, has in [(q, omega, everyone), *found]
            ]
        return found

    return twins


def _remapped(measure: Callable, shapes: Sequence[int]) -> Callable:
    table = torch.as_tensor(list(shapes), dtype=torch.long)

    def remapped(q: torch.Tensor, epochs: np.ndarray, shape: torch.Tensor) -> torch.Tensor:
        return measure(q, epochs, table[shape])

    return remapped


def _prior(q0: Any, omega0: Any, attitude_sigma: float, omega_sigma: float, omega_max: float):
    if q0 is None:
        return None
    q = quaternion_canonical(quaternion_normalize(np.asarray(q0, dtype=float)))
    if omega0 is None:
        return Prior(q, np.zeros(3), attitude_sigma, omega_max)
    return Prior(q, np.asarray(omega0, dtype=float), attitude_sigma, omega_sigma)


def _symmetry_note(name: str, group: SymmetryGroup) -> str | None:
    if group.is_trivial:
        return None
    if group.axis is not None:
        return (
            f"{name} has a continuous rotational symmetry about body axis "
            f"{np.round(group.axis, 3).tolist()}: the rotation about it is unobservable"
        )
    return (
        f"{name} has {group.order} rotational symmetries: the attitude is determined only "
        "up to them (see 'symmetry')"
    )


# ----------------------------------------------------------------------------- UKF/MMAE
@dataclass
class _UKFSetup:
    """A shape's UKF (one member per hypothesis), its measurement function, the initial
    log-weights of the hypotheses and the end of the initial fit."""

    ukf: AttitudeUKF
    hx: Callable[[int], Callable]
    fit_end: float
    log_prior: np.ndarray
    offset_index: int | None
    k_index: tuple[int, int] | None


def _ukf_for_shape(
    ctx: _Context,
    s: int,
    prior: Prior | None,
    prior_covariance: np.ndarray,
    found: SearchResult | None,
) -> _UKFSetup:
    """The USQUE filter of shape ``s``: one member per distinct initial fit of the shape
    in ``found``, or one member at the prior (``found`` None)."""
    opt = ctx.options
    name = ctx.names[s]
    shape = ctx.model.shapes[name]
    attitude_cap = math.sqrt(prior_covariance[0, 0]) if prior is not None else math.radians(5.0)
    omega_cap = math.sqrt(prior_covariance[3, 3]) if prior is not None else math.radians(0.05)
    params: list[float] = []
    variances: list[float] = []
    k_index = offset_index = None
    if opt.estimate_inertia:
        k_index = (0, 1)
        params += list(tanh_from_inertia(np.diag(shape.principal_moments)))
        variances += [opt.inertia_sigma**2] * 2
    if opt.estimate_offset:
        offset_index = len(params)
        params.append(0.0)
        variances.append(opt.offset_sigma_mag**2)
    n = 6 + len(params)
    base = np.zeros((n, n))
    for i, v in enumerate(variances):
        base[6 + i, 6 + i] = v
    if found is None:
        q, omega = prior.q[None], prior.omega[None]
        covariance = base.copy()[None]
        covariance[0, :6, :6] = prior_covariance
        theta = np.tile(params, (1, 1))
        fit_end, log_prior = -math.inf, np.zeros(1)
    else:
        found = _subset(found, found.shape == s)
        h = min(opt.hypotheses, len(found))
        q, omega = found.q[:h], found.omega[:h]
        m = found.covariance.shape[1]  # 6, or 8 with k
        covariance = np.repeat(base[None], h, axis=0)
        # Rotation vector ≈ GRP (f = 4). Directions the fit does not determine (the
        # rotation about a symmetry axis, a shape that fits nowhere) have huge
        # Gauss–Newton variances: capped at the prior's, or at 30° and ω_max/2.
        cap = np.array(
            [attitude_cap] * 3 + [omega_cap] * 3 + [opt.inertia_sigma] * (m - 6), dtype=float
        )
        covariance[:, :m, :m] = _capped(found.covariance[:h], cap)
        theta = np.tile(params, (h, 1))
        if found.k is not None:
            theta[:, :2] = found.k[:h]
        fit_end = float(ctx.model.times[found.epochs[-1]])
        log_prior = -0.5 * found.chi2[:h]
        close = found.chi2[1:h] - found.chi2[0] < 9.0
        if close.any():
            ctx.notes.append(
                f"{name}: {int(close.sum()) + 1} distinct states fit the first {fit_end:.0f} s "
                f"within Δχ² < 9 (χ² {', '.join(f'{c:.0f}' for c in found.chi2[:h])}); "
                "the filter keeps them as hypotheses"
            )
    noise = ProcessNoise(
        opt.process_noise_attitude, opt.process_noise_rate, params=(0.0,) * len(params)
    )
    dynamics = torque_free_dynamics(
        shape.inertia,
        max_step=1.0,
        tanh_index=k_index,
        principal_axes=shape.principal_axes if k_index else None,
    )
    ukf = AttitudeUKF(
        q,
        omega,
        0.5 * (covariance + np.swapaxes(covariance, 1, 2)),
        dynamics,
        params=theta if params else None,
        process_noise=noise,
        alpha=opt.alpha,
        beta=opt.beta,
        kappa=opt.kappa,
        gate=default_gate(opt.gate_probability) if opt.gate_probability > 0 else math.inf,
        underweighting=opt.underweighting,
    )
    model = ctx.model

    def hx_at(k: int) -> Callable:
        def hx(qs: np.ndarray, theta: np.ndarray) -> np.ndarray:
            m = model.magnitude(qs, k, s)
            return m if offset_index is None else m + theta[..., offset_index]

        return hx

    return _UKFSetup(ukf, hx_at, fit_end, log_prior, offset_index, k_index)


def _run_bank(
    ctx: _Context, method: str, q0: Any, omega0: Any, attitude_sigma: float, omega_sigma: float
) -> InversionResult:
    opt = ctx.options
    model = ctx.model
    prior = _prior(q0, omega0, attitude_sigma, omega_sigma, ctx.omega_max)
    if opt.init == "none" and prior is None:
        raise ValueError("init='none' needs q0 (and omega0) as the filter's starting point")
    prior_covariance = np.diag(
        [attitude_sigma**2] * 3 + list(np.broadcast_to(np.asarray(omega_sigma) ** 2, (3,)))
    )
    found = None
    if opt.init == "search" or prior is None:
        ctx.report(0.0, "initial fit")
        n = opt.local_candidates if prior is not None else opt.global_candidates * model.n_shapes
        found = _search(
            ctx, prior, range(model.n_shapes), n, keep_last=opt.hypotheses, per_shape=True
        )
        missing = [ctx.names[s] for s in range(model.n_shapes) if not (found.shape == s).any()]
        if missing:
            raise RuntimeError(f"the initial search kept no candidate of {', '.join(missing)}")
    setups = [_ukf_for_shape(ctx, s, prior, prior_covariance, found) for s in range(model.n_shapes)]
    bank = MultipleModelBank(
        [st.ukf for st in setups],
        ctx.names,
        log_prior=[st.log_prior for st in setups],
        floor=opt.probability_floor if model.n_shapes > 1 else 0.0,
        window=opt.consistency_window,
        level=opt.consistency_level,
    )
    times, z, r = model.times, model.magnitudes, model.errors**2
    rows = []
    gated_count = 0
    n = len(model)
    fit_end = max(st.fit_end for st in setups)
    for k in range(n):
        if k:
            bank.predict(times[k] - times[k - 1])
        if times[k] > fit_end:
            res = bank.update(z[k], r[k], [st.hx(k) for st in setups])[bank.best]
            gated = bool(res.gated[0])
        else:  # fitted by the search: only the table's prediction is needed
            res = bank.evaluate(z[k], r[k], setups[bank.best].hx(k), bank.best)
            gated = False
        q, omega, cov = bank.fused()
        gated_count += gated
        rows.append(
            _row(
                model.mjd[k],
                q,
                omega,
                cov,
                float(res.predicted[0]),
                z[k],
                gated,
                bank.probabilities if model.n_shapes > 1 else None,
                ctx.names,
            )
        )
        if k % 50 == 0:
            ctx.report(0.3 + 0.7 * k / n, f"{method}: {k}/{n} measurements")
    estimates = pd.DataFrame(rows)
    q, omega, cov = bank.fused()
    best = bank.best
    name = ctx.names[best]
    group = ctx.symmetry(best)
    note = _symmetry_note(name, group)
    if note:
        ctx.notes.append(note)
    if gated_count:
        ctx.notes.append(f"{gated_count} measurement(s) rejected by the innovation gate")
    if opt.init == "search" or prior is None:
        ctx.notes.append(f"initial state fitted on the first {setups[best].fit_end:.0f} s of data")
    if bank.none_fits:
        pairs = zip(ctx.names, bank.windowed_nis, bank.windowed_misfit, strict=True)
        ctx.notes.append(
            "no candidate shape fits over the last "
            f"{bank.window} measurements (windowed mean NIS ν²/S above {bank.bound:.2f} or "
            f"mean ν²/R above {bank.residual_factor * bank.bound:.2f}): "
            + ", ".join(f"{m} {v:.2f}/{u:.2f}" for m, v, u in pairs)
        )
    parameters = {}
    st = setups[best]
    theta = bank.parameters(best)
    if st.k_index is not None:
        parameters["k1"], parameters["k2"] = (float(v) for v in theta[:2])
    if st.offset_index is not None:
        parameters["magnitude_offset"] = float(theta[st.offset_index])
    if bank.hypotheses(best) > 1:
        weights = np.exp(bank.log_weights[best])
        ctx.notes.append(
            f"{name}: heaviest of {len(st.ukf)} hypotheses carries {weights.max():.3f}"
        )
    return _result(
        ctx,
        method,
        name,
        dict(zip(ctx.names, bank.probabilities, strict=True)),
        bank.none_fits,
        q,
        omega,
        cov,
        [],
        estimates,
        parameters,
        group,
    )


# ----------------------------------------------------------------------------- PF
def _run_pf(
    ctx: _Context,
    q0: Any,
    omega0: Any,
    attitude_sigma: float,
    omega_sigma: float,
    particles: int,
) -> InversionResult:
    opt = ctx.options
    model = ctx.model
    prior = _prior(q0, omega0, attitude_sigma, omega_sigma, ctx.omega_max)
    shapes = list(range(model.n_shapes))
    ctx.report(0.0, "global search of the initial state")
    found = _search(
        ctx,
        prior,
        shapes,
        opt.local_candidates if prior is not None else opt.global_candidates,
        keep_last=2 * opt.hypotheses,
        for_pf=True,
    )
    found = _subset(found, slice(0, 2 * opt.hypotheses))
    q, omega, k, shape, component, log_w = _seed_particles(ctx, found, prior, particles)
    groups = [ctx.symmetry(s) for s in range(model.n_shapes)]
    pf = AttitudeParticleFilter(
        q,
        omega,
        [s.inertia for s in model.shapes.values()],
        log_weights=log_w,
        k=k,
        shape=shape,
        principal_axes=[s.principal_axes for s in model.shapes.values()],
        components=component if opt.mixture_tracking else None,
        likelihood=opt.likelihood,
        nu=opt.student_nu,
        ess_threshold=opt.ess_threshold,
        bandwidth=opt.bandwidth,
        mode_angle=math.radians(opt.mode_angle_deg),
        mode_rate=math.radians(opt.mode_rate_deg_s),
        seed=ctx.seed,
        dtype=torch.float64,
    )
    fold = _folder(groups)
    times, z, r = model.times, model.magnitudes, model.errors**2
    window = _NISWindow(opt.consistency_window, opt.consistency_level)
    rows = []
    n = len(model)
    move_target = _move_target(ctx, pf) if opt.moves > 0 else None
    for j in range(n):
        if j:
            pf.predict(times[j] - times[j - 1])

        def measure(qs: torch.Tensor, shape_index: torch.Tensor, j: int = j) -> torch.Tensor:
            return model.magnitude_by_shape(qs.to(model.dtype), j, shape_index).to(torch.float64)

        target = None if move_target is None else move_target(j)
        info = pf.update(z[j], r[j], measure, move_target=target, moves=opt.moves)
        mean = info.predicted
        window.add((z[j] - mean) ** 2 / (info.variance + r[j]))
        q_est, w_est, cov = pf.estimate(fold=fold)
        probabilities = pf.shape_probabilities(model.n_shapes)
        rows.append(
            _row(
                model.mjd[j],
                q_est,
                w_est,
                cov,
                mean,
                z[j],
                False,
                probabilities if model.n_shapes > 1 else None,
                ctx.names,
            )
        )
        if j % 50 == 0:
            ctx.report(0.3 + 0.7 * j / n, f"pf: {j}/{n} measurements, ESS {pf.ess:.0f}")
    estimates = pd.DataFrame(rows)
    probabilities = pf.shape_probabilities(model.n_shapes)
    if opt.polish and opt.likelihood == "gaussian":
        modes, covariances = _polish(ctx, pf.modes(min_weight=0.0, fold=fold))
        q_est, w_est, cov = modes[0].quaternion, modes[0].omega, covariances[0]
    else:
        modes = pf.modes(min_weight=opt.min_mode_weight, fold=fold)
        q_est, w_est, cov = pf.estimate(fold=fold)
    best = modes[0].shape if modes else int(np.argmax(probabilities))
    name = ctx.names[best]
    mode_dicts = []
    for mode in modes:
        g = groups[mode.shape]
        mode_dicts.append(
            {
                "quaternion": [float(v) for v in mode.quaternion],
                "omega_rad_s": [float(v) for v in mode.omega],
                "weight": float(mode.weight),
                "shape": ctx.names[mode.shape],
                "attitude_sigma_deg": math.degrees(mode.attitude_sigma),
                "equivalent_quaternions": quaternion_canonical(
                    g.equivalent_attitudes(mode.quaternion)
                ).tolist(),
                "equivalent_omega_rad_s": g.equivalent_rates(mode.omega).tolist(),
            }
        )
    if len(modes) > 1:
        ctx.notes.append(
            f"{len(modes)} posterior modes; the heaviest carries {modes[0].weight:.2f}"
        )
    note = _symmetry_note(name, groups[best])
    if note:
        ctx.notes.append(note)
    ctx.notes.append(
        f"{found.screened} candidates screened; the particles were seeded around "
        f"{len(found)} refined candidates"
    )
    if window.inconsistent:
        ctx.notes.append(
            f"the model does not fit: windowed mean NIS {window.mean:.2f} > {window.bound:.2f}"
        )
    parameters = {}
    if modes and modes[0].k is not None:
        parameters["k1"], parameters["k2"] = (float(v) for v in modes[0].k)
    return _result(
        ctx,
        "pf",
        name,
        dict(zip(ctx.names, probabilities, strict=True)),
        window.inconsistent,
        q_est,
        w_est,
        cov,
        mode_dicts,
        estimates,
        parameters,
        groups[best],
    )


def _polish(ctx: _Context, clusters: list[Mode]) -> tuple[list[Mode], list[np.ndarray]]:
    """The posterior's modes: the PF's clusters refined on the whole arc and weighed by
    their Laplace evidence.

    A few thousand particles in six or more dimensions leave a cluster's mean a few
    degrees from the best fit and its spread is no covariance (Itokawa, 20 min at 1 Hz,
    particle-filter study, random seed 0, run 1: the mean ended 5.0° from the truth with
    NEES 86). And a
    cluster's weight is its particles' likelihood, not its basin's: on the same scenario
    (run 14) the truth's component, its particles a few degrees off, fell below 1 % to the
    reciprocity twin that the whole arc fits worse. So every cluster's final state
    ``x = [q, ω(, k)]`` is refined by Levenberg–Marquardt on every measurement
    (:func:`filters.global_search.refine` with the states at the last epoch, earlier
    epochs reached backwards by the torque-free dynamics) under the search's weak rate
    prior ``N(0, ω_max²)``, clusters reaching the same optimum (3°, 0.05°/s, modulo the
    shape's symmetry) become one, and each distinct optimum ``x̂_i`` gets the Laplace
    approximation of its posterior mass under the flat prior on SO(3) × rate ball,

        w_i ∝ exp(−χ²_i / 2) · √det P_i,

    ``χ²_i`` the data misfit at ``x̂_i`` and ``P_i = (JᵀJ)⁻¹`` its Gauss–Newton covariance
    (body-frame rotation of the final attitude, rad; rates, rad/s; ``k``), the
    determinant taken over the directions the data and the rate prior constrain, times
    the order ``|G|`` of a finite symmetry group (a folded mode stands for ``|G|``
    equivalent basins). Across shapes with a continuous symmetry, whose attitude about
    the axis no datum constrains, the weights are approximate. Optima lighter than
    ``min_mode_weight`` are dropped.

    Returns
    -------
    modes : list of Mode
        Heaviest first; ``attitude_sigma`` and ``omega_sigma`` from ``P_i``.
    covariances : list of (6, 6) arrays
        ``P_i`` of ``[δθ, ω]`` for every mode.
    """
    problem = ctx.problem()
    q = torch.as_tensor(np.stack([m.quaternion for m in clusters]))
    k = None if clusters[0].k is None else torch.as_tensor(np.stack([m.k for m in clusters]))
    shape = torch.as_tensor([m.shape for m in clusters])
    weak = Prior.rates_only(ctx.omega_max)
    start = Candidates(
        q=q, omega=torch.as_tensor(np.stack([m.omega for m in clusters])), shape=shape, k=k
    )
    fit = refine(
        problem,
        start,
        np.arange(len(problem.times)),
        prior=weak,
        t_start=float(problem.times[-1]),
    )
    q2, w2, k2, chi2, covariance = fit.q, fit.omega, fit.k, fit.chi2, fit.covariance
    chi2 = (chi2 - (weak.residuals(q2, w2) ** 2).sum(dim=1)).numpy()
    q2 = quaternion_canonical(q2.numpy())
    order = np.argsort(chi2, kind="stable")
    kept = order[
        distinct_states(
            q2[order],
            w2.numpy()[order],
            shape.numpy()[order],
            math.radians(3.0),
            math.radians(0.05),
            [ctx.symmetry(s) for s in range(ctx.model.n_shapes)],
        )
    ]
    groups = [ctx.symmetry(int(shape[i])) for i in kept]
    log_w = np.array(
        [
            -0.5 * chi2[i]
            + 0.5 * _log_pseudo_det(covariance[i].numpy())
            # a folded mode stands for its |G| symmetry-equivalent basins
            + (math.log(g.order) if g.axis is None else 0.0)
            for i, g in zip(kept, groups, strict=True)
        ]
    )
    if not np.isfinite(log_w).any():
        log_w = np.zeros(len(kept))
    weights = np.exp(log_w - log_w[np.isfinite(log_w)].max())
    weights /= weights.sum()
    moved = np.degrees(attitude_angle(q.numpy()[kept], q2[kept]))
    modes, covariances = [], []
    for rank in np.argsort(-weights, kind="stable"):
        i = kept[rank]
        if weights[rank] < ctx.options.min_mode_weight:
            continue
        cov = covariance[i].numpy()
        modes.append(
            Mode(
                quaternion=q2[i],
                omega=w2[i].numpy(),
                weight=float(weights[rank]),
                shape=int(shape[i]),
                attitude_sigma=math.sqrt(max(float(np.trace(cov[:3, :3])), 0.0)),
                omega_sigma=np.sqrt(np.clip(np.diag(cov)[3:6], 0.0, None)),
                k=None if k2 is None else k2[i].numpy(),
            )
        )
        covariances.append(cov[:6, :6])
    ctx.notes.append(
        f"{len(clusters)} PF clusters polished on the whole arc into {len(kept)} distinct "
        f"optima (χ² {', '.join(f'{chi2[i]:.1f}' for i in kept[:4])}; moved "
        f"{', '.join(f'{a:.1f}°' for a in moved[:4])})"
    )
    return modes, covariances


def _log_pseudo_det(covariance: np.ndarray) -> float:
    """``log det`` over the eigenvalues above 10⁻¹² of the largest (a direction no datum
    constrains has none in the Gauss–Newton pseudo-inverse)."""
    eigenvalues = np.linalg.eigvalsh(0.5 * (covariance + covariance.T))
    return float(np.sum(np.log(eigenvalues[eigenvalues > 1e-12 * eigenvalues.max()])))


class _NISWindow:
    """Windowed mean of normalised innovations squared against its χ² bound."""

    def __init__(self, size: int, level: float) -> None:
        self.size = size
        self.values: list[float] = []
        self.bound = chi2_band(1, size, 1.0 - 2.0 * (1.0 - level))[1]

    def add(self, nis: float) -> None:
        self.values.append(min(float(nis), 25.0))
        del self.values[: -self.size]

    @property
    def mean(self) -> float:
        return float(np.mean(self.values)) if self.values else math.nan

    @property
    def inconsistent(self) -> bool:
        return len(self.values) == self.size and self.mean > self.bound


def _capped(covariance: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """Covariances ``(B, n, n)`` whose 1σ along any direction is at most ``sigma`` in the
    units of each component: eigenvalues of ``S⁻¹ P S⁻¹`` (``S = diag σ``) clipped to
    ``[0, 1]``."""
    scale = np.outer(sigma, sigma)
    scaled = covariance / scale
    values, vectors = np.linalg.eigh(0.5 * (scaled + np.swapaxes(scaled, -1, -2)))
    clipped = (vectors * np.clip(values, 0.0, 1.0)[..., None, :]) @ np.swapaxes(vectors, -1, -2)
    return clipped * scale


def _subset(found: SearchResult, keep: Any) -> SearchResult:
    """The candidates of ``found`` selected by an index, slice or mask."""
    return dataclasses.replace(
        found,
        q=found.q[keep],
        omega=found.omega[keep],
        k=None if found.k is None else found.k[keep],
        shape=found.shape[keep],
        chi2=found.chi2[keep],
        covariance=found.covariance[keep],
    )


def _seed_particles(
    ctx: _Context, found: SearchResult, prior: Prior | None, n: int
) -> tuple[np.ndarray, ...]:
    """Particles from a mixture of Gaussians around the search candidates.

    Each candidate gets ``n/M`` particles drawn from ``N(x_i, 4 C_i)`` (``C_i`` its
    Gauss–Newton covariance, every 1σ capped at 5° and 0.05°/s, floored at 0.5° and
    0.01°/s). The cap bounds the spread of the importance weights: a candidate the data
    barely constrain has a huge ``C_i`` and therefore a tiny mixture density, and the one
    of its particles that happened to fit then outweighed the whole cloud around the best
    fit (box, particle-filter study, random seed 0, run 16: the search's best was 2.5°
    from the truth, the PF ended 76° off; with the cap 1.8°). The log-weights
    ``log prior(x) − log q(x)`` (``q`` the mixture density) make the particles a sample of
    the prior, which the filter then updates with every measurement. The component each
    particle was drawn from is returned for mixture tracking.
    """
    m = len(found)
    d = found.covariance.shape[1]
    floor = np.array([math.radians(0.5)] * 3 + [math.radians(0.01)] * 3 + [0.05] * (d - 6))
    cap = np.array([math.radians(5.0)] * 3 + [math.radians(0.05)] * 3 + [0.5] * (d - 6))
    covariances = 4.0 * _capped(found.covariance, cap) + np.diag(floor**2)
    counts = np.full(m, n // m)
    counts[: n - counts.sum()] += 1
    chol = np.linalg.cholesky(covariances)
    component = np.repeat(np.arange(m), counts)
    steps = np.einsum("nij,nj->ni", chol[component], ctx.rng.standard_normal((n, d)))
    q = quaternion_multiply(rotation_vector_to_quaternion(steps[:, :3]), found.q[component])
    omega = found.omega[component] + steps[:, 3:6]
    k = None if found.k is None else found.k[component] + steps[:, 6:8]
    # Mixture density of every particle under every component.
    log_q = np.full((n, m), -np.inf)
    inverse = np.linalg.inv(covariances)
    _, logdet = np.linalg.slogdet(covariances)
    for i in range(m):
        dtheta = quaternion_to_rotation_vector(
            quaternion_multiply(q, quaternion_conjugate(found.q[i]))
        )
        parts = [dtheta, omega - found.omega[i]] + ([k - found.k[i]] if k is not None else [])
        dev = np.concatenate(parts, axis=1)
        same = found.shape[component] == found.shape[i]
        quad = np.einsum("ni,ij,nj->n", dev, inverse[i], dev)
        log_q[:, i] = np.where(same, -0.5 * (quad + logdet[i]), -np.inf)
    log_mixture = np.logaddexp.reduce(log_q, axis=1) - math.log(m)
    if prior is None:
        outside = np.linalg.norm(omega, axis=1) > ctx.omega_max
        log_prior = np.where(outside, -np.inf, 0.0)
    else:
        log_prior = -0.5 * np.sum(
            prior.residuals(torch.as_tensor(q), torch.as_tensor(omega)).numpy() ** 2, axis=1
        )
    return q, omega, k, found.shape[component], component, log_prior - log_mixture


def _folder(groups: Sequence[SymmetryGroup]) -> Callable:
    """``fold(q_ref, q, ω, shape)``: particles mapped to their symmetry-equivalent nearest
    the reference, shape by shape."""

    def fold(q_ref: np.ndarray, q: np.ndarray, omega: np.ndarray, shape: np.ndarray) -> tuple:
        q_out, w_out = q.copy(), omega.copy()
        for s, group in enumerate(groups):
            rows = shape == s
            if group.order == 1 or not rows.any():
                continue
            picked, index = group.closest(q_ref, q[rows])
            rates = group.equivalent_rates(omega[rows])
            q_out[rows] = picked
            w_out[rows] = rates[index, np.arange(int(rows.sum()))]
        return q_out, w_out

    return fold


def _move_target(ctx: _Context, pf: AttitudeParticleFilter) -> Callable[[int], Callable]:
    """Resample-move target at measurement ``j``: the likelihood of the last
    ``move_window`` measurements (reached by propagating backwards) plus the tempered
    current one."""
    problem = ctx.problem()
    size = ctx.options.move_window

    def at(j: int) -> Callable:
        epochs = np.arange(max(0, j - size), j + 1)
        t_now = float(ctx.model.times[j])

        def target(q: torch.Tensor, omega: torch.Tensor, k: Any, shape: torch.Tensor) -> Any:
            traj = problem.trajectory(q, omega, k, shape, epochs, t_start=t_now)
            r = problem.residuals_of(traj, shape, epochs)
            if pf.likelihood == "gaussian":
                return -0.5 * (r * r).sum(dim=1)
            return -0.5 * (pf.nu + 1.0) * torch.log1p(r * r / pf.nu).sum(dim=1)

        return target

    return at


# ----------------------------------------------------------------------------- results
def _row(
    mjd: float,
    q: np.ndarray,
    omega: np.ndarray,
    covariance: np.ndarray,
    predicted: float,
    measured: float,
    gated: bool,
    probabilities: np.ndarray | None,
    names: Sequence[str],
) -> dict[str, Any]:
    q = quaternion_canonical(np.asarray(q, dtype=float))
    sigma = np.sqrt(np.clip(np.diag(covariance)[:6], 0.0, None))
    row = {"mjd": mjd}
    row.update({f"q{i + 1}": float(q[i]) for i in range(4)})
    row.update({f"w{a}": float(omega[i]) for i, a in enumerate("xyz")})
    row.update({f"sigma_att_{a}": math.degrees(sigma[i]) for i, a in enumerate("xyz")})
    row.update({f"sigma_w{a}": float(sigma[3 + i]) for i, a in enumerate("xyz")})
    row["predicted_mag"] = predicted
    row["residual"] = float(measured - predicted)
    row["gated"] = gated
    if probabilities is not None:
        row.update({f"p_{n}": float(p) for n, p in zip(names, probabilities, strict=True)})
    return row


def _result(
    ctx: _Context,
    method: str,
    name: str,
    probabilities: dict[str, float],
    none_fits: bool,
    q: np.ndarray,
    omega: np.ndarray,
    covariance: np.ndarray,
    modes: list[dict[str, Any]],
    estimates: pd.DataFrame,
    parameters: dict[str, float],
    group: SymmetryGroup,
) -> InversionResult:
    used = ~estimates["gated"].to_numpy(dtype=bool)
    residuals = estimates["residual"].to_numpy()[used]
    sigma_att = math.degrees(math.sqrt(max(float(np.trace(covariance[:3, :3])), 0.0)))
    if sigma_att > 10.0:
        ctx.notes.append(f"weakly observable: final attitude 1σ is {sigma_att:.1f}°")
    return InversionResult(
        method=method,
        shape=name,
        shape_probabilities={k: float(v) for k, v in probabilities.items()},
        none_fits=bool(none_fits),
        epoch_mjd=float(ctx.model.mjd[-1]),
        quaternion=quaternion_canonical(np.asarray(q, dtype=float)),
        omega_rad_s=np.asarray(omega, dtype=float),
        attitude_sigma_deg=sigma_att,
        omega_sigma_rad_s=np.sqrt(np.clip(np.diag(covariance)[3:6], 0.0, None)),
        modes=modes,
        residual_rms_mag=float(np.sqrt(np.mean(residuals**2))) if residuals.size else math.nan,
        n_measurements=len(ctx.model),
        estimates=estimates,
        notes=ctx.notes,
        parameters=parameters,
        symmetry=group.to_dict(),
        covariance=np.asarray(covariance, dtype=float)[:6, :6],
        runtime_s=time.perf_counter() - ctx.start,
    )


# ----------------------------------------------------------------------------- API
def invert(
    observations: Observations,
    shapes: Mapping[str, FacetModel] | Sequence[str] | FacetModel | str,
    method: str = "ukf",
    q0: Any = None,
    omega0: Any = None,
    attitude_sigma_deg: float = 20.0,
    omega_sigma: float = math.radians(0.2),
    omega_max: float = math.radians(5.0),
    particles: int = 2000,
    seed: int = 0,
    progress: Progress | None = None,
    options: InversionOptions | None = None,
    modes: bool = False,
    **option_overrides: Any,
) -> InversionResult:
    """Estimate attitude, rates (and shape) from one light curve.

    Parameters
    ----------
    observations : Observations
        Measured ``mag``, ``mag_err`` and geometry (calibrated magnitudes).
    shapes : mapping name → FacetModel, FacetModel, name or sequence of names
        Candidate shape(s): one for ``"ukf"``, one or more for ``"mmae"`` and ``"pf"``.
        Names are loaded from the built-in library.
    method : {"ukf", "mmae", "pf"}
    q0 : (4,) array, optional
        Prior attitude at the FIRST measurement (scalar last, inertial → body). Without
        it the initial state is searched uniformly on SO(3).
    omega0 : (3,) array, optional
        Prior body rates at the first measurement (rad/s); without it rates are searched
        in the ball ``|ω| ≤ omega_max``.
    attitude_sigma_deg : float
        Prior 1σ per axis of the attitude error (deg).
    omega_sigma : float
        Prior 1σ per axis of the rates (rad/s).
    omega_max : float
        Radius of the rate ball of the global search (rad/s).
    particles : int
        PF particles.
    seed : int
        Seed of every random draw (search candidates, particles, resampling).
    progress : callable, optional
        ``progress(fraction, message)`` with ``fraction`` in ``[0, 1]``.
    options : InversionOptions, optional
        Tuning; keyword arguments override single fields (``estimate_inertia=True``).
    modes : bool
        Also weigh stabilised attitude profiles against tumbling
        (:mod:`lightcurve.attitude_modes`): the result's ``attitude_mode`` holds the mode,
        its probability and the fitted offsets; when a stabilised mode is the more probable,
        the shape, attitude, rates and their 1σ come from its fit.

    Returns
    -------
    InversionResult

    Raises
    ------
    ValueError
        Unknown method or option, observations without magnitudes, with fewer than
        ``MIN_MEASUREMENTS`` points or non-finite values, relative light curves, a shape
        that cannot be loaded, or the wrong number of shapes for the method.
    """
    start = time.perf_counter()
    if method not in METHODS:
        raise ValueError(f"method must be one of {', '.join(METHODS)}, got {method!r}")
    options = options or InversionOptions()
    unknown = set(option_overrides) - {f.name for f in dataclasses.fields(InversionOptions)}
    if unknown:
        raise ValueError(f"unknown inversion option(s): {', '.join(sorted(unknown))}")
    options = dataclasses.replace(options, **option_overrides)
    _check_observations(observations)
    resolved = _resolve_shapes(shapes)
    if method == "ukf" and len(resolved) != 1:
        raise ValueError(f"method 'ukf' takes exactly one shape, got {len(resolved)}")
    if not (attitude_sigma_deg > 0 and omega_sigma > 0 and omega_max > 0 and particles > 0):
        raise ValueError("attitude_sigma_deg, omega_sigma, omega_max and particles must be > 0")
    model = PhotometricModel(
        observations, resolved, compile=options.compile, faint_margin=options.faint_margin
    )
    ctx = _Context(
        observations=observations,
        model=model,
        options=options,
        progress=progress,
        rng=np.random.default_rng(seed),
        seed=seed,
        notes=[],
        start=start,
        omega_max=float(omega_max),
    )
    sigma = math.radians(attitude_sigma_deg)
    if method == "pf":
        result = _run_pf(ctx, q0, omega0, sigma, omega_sigma, particles)
    else:
        result = _run_bank(ctx, method, q0, omega0, sigma, omega_sigma)
    if modes:
        ctx.report(0.95, "attitude modes")
        _attitude_modes(ctx, result)
        result.runtime_s = time.perf_counter() - start
    ctx.report(1.0, "done")
    return result


def _attitude_modes(ctx: _Context, result: InversionResult) -> None:
    """Weigh stabilised profiles against the tumbling fit (:mod:`lightcurve.attitude_modes`)
    and fill ``result.attitude_mode`` (and the state, when a profile wins)."""
    from lightcurve.attitude_modes import TUMBLING, identify_attitude_mode

    obs = ctx.observations
    first = result.estimates.iloc[0]
    starts = [
        (
            first[["q1", "q2", "q3", "q4"]].to_numpy(float),
            first[["wx", "wy", "wz"]].to_numpy(float),
            0.0,
        ),
        (result.quaternion, result.omega_rad_s, float(ctx.model.times[-1])),
    ]
    found = identify_attitude_mode(
        ctx.model,
        ctx.problem(),
        dict.fromkeys(range(ctx.model.n_shapes), starts),
        [ctx.symmetry(s).order for s in range(ctx.model.n_shapes)],
        omega_max=ctx.omega_max,
        offset_sigma_deg=ctx.options.mode_offset_sigma_deg,
        consistency_level=ctx.options.mode_consistency_level,
        position=obs.object_positions if obs.has_object_position else None,
        velocity=obs.object_velocities if obs.has_object_velocity else None,
        max_epochs=ctx.options.max_epochs,
        max_rotation=math.radians(ctx.options.max_sample_rotation_deg),
        seed=ctx.seed,
    )
    ctx.notes.extend(found.notes)
    result.attitude_mode = found.summary()
    if found.mode != TUMBLING:
        best = found.best
        result.shape = best.shape
        result.quaternion = quaternion_canonical(best.quaternion)
        result.omega_rad_s = best.omega_rad_s
        result.attitude_sigma_deg = float(np.linalg.norm(best.offset_sigma_deg))
        result.omega_sigma_rad_s = np.zeros(3)
        ctx.notes.append(
            f"attitude mode {found.mode} (p = {found.probability:.3f}): the state is the "
            "profile's with the fitted offset; the rates follow the profile"
        )
    result.none_fits = bool(result.none_fits and found.none_fits)
