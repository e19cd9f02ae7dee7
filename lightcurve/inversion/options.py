"""Options of :func:`lightcurve.inversion.invert`, validated per method.

:class:`InversionOptions` holds every tuning knob; :data:`METHOD_OPTIONS` says which of
them each method reads, and :func:`validate_request` rejects an option set away from its
default for a method that would ignore it (``estimate_offset`` with ``"pf"``), together with
every other mistake in a request that can be caught before any data is read.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = [
    "FILTER_REFINE_KEEP",
    "METHODS",
    "METHOD_OPTIONS",
    "PF_REFINE_KEEP",
    "InversionOptions",
    "validate_request",
]

METHODS = ("ukf", "mmae", "pf")
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
    search_turn_deg : float
        UKF/MMAE without ``q0``: when the slowest plausible initial fit turns less than this in
        ``init_window_s``, the search is run again on windows up to the time it takes to
        turn this much (at most half the data span): a slow rotator seen over less than a
        turn leaves many states that fit equally well. 0 disables.
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
    pf_rate_scales : tuple of float
        Scales of the rate ball that the PF's search without ``q0`` runs through, each
        with its windows stretched by the inverse scale (see ``rate_scales`` of
        :func:`filters.global_search.global_search`): a window tells states apart by the
        rotation it spans, and over 30 s a slow rotator turns too little. With
        ``(1, 0.25)`` a rotator at any rate from ``omega_max/16`` up is searched at a scale
        where it turns per window at least a quarter of what one at ``omega_max`` turns at
        the full scale.
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
        MMAE and PF searches: a shape whose best fit of a window is worse than this many
        times the best shape's (``χ²``, or the window's number of measurements if larger)
        goes on with ``hypotheses`` candidates (the PF's: ``2 · hypotheses``) and no twins
        (see :func:`filters.global_search.global_search`); ``inf`` gives every shape the
        full schedule. The PF also seeds particles around the best fits of every shape in
        contention on the search's last window, and of no other.
    min_epochs : int
        Measurements per refinement window, at least (all of them in a shorter window).
    max_sample_rotation_deg : float
        Longest rotation (deg) at ``omega_max`` between the measurements of a refinement
        window: longer windows get more than ``min_epochs`` measurements, so that a fast
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
    estimate : tuple of str
        Model adjustments fitted with the state on the whole arc by the UKF/MMAE's final
        fit (see ``polish``), any of ``"inertia"`` (tanh parameters ``k``), ``"tilt"`` (of
        the principal axes from the mesh's), ``"scale"`` (albedo–area scale, as a magnitude
        offset), ``"stretch"`` (three principal-axis stretch factors: normals, areas,
        shadows and inertia follow) and ``"material"`` (every BRDF parameter within its
        physical range); see :class:`lightcurve.photometry.adjusted.AdjustableShape`.
        ``()`` fits the state only.
    model_tolerance_mag : float
        A candidate whose whole-arc fit leaves an rms model error (mag, beyond the
        measurement errors) above this does not fit: ``none_fits`` when no candidate
        passes.
    rescue_starts : int
        UKF/MMAE: when no candidate fits after the whole-arc fit, this many of each
        candidate's best initial fits are continued to the whole arc again, with the
        adjustments ``rescue_estimate`` freed, those clearly worse than the best dropped at
        every doubling of the window (:func:`lightcurve.inversion.model_fit.fit_arc_growing`);
        a fit with a smaller model error replaces the candidate's. 0 (the default) disables.
    rescue_estimate : tuple of str
        The adjustments of that second fit (as ``estimate``).
    adaptive_noise : bool
        UKF/MMAE: estimate each candidate's model-error variance online from its
        innovations (covariance matching, Mehra 1970; Mohamed & Schwarz 1999) and add it
        to the measurement variance, so that a filter facing an imperfect model widens its
        measurement noise instead of gating most measurements away.
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
        Refine the final states on the whole arc by Levenberg–Marquardt and report the
        best optimum with its Gauss–Newton covariance. PF (Gaussian likelihood): every
        cluster, the distinct optima weighed by their Laplace evidence
        (:func:`lightcurve.inversion.polish.polish`). UKF/MMAE: the filter's hypotheses,
        with the adjustments ``estimate`` (:mod:`lightcurve.inversion.model_fit`); the
        shapes are weighed by the Laplace evidence of their best fits and the residual
        misfit gives the model error (``model_tolerance_mag``).
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
    mode_weak_sigma_deg : float
        ``modes=True``: a direction of a fitted offset whose Laplace 1σ exceeds this (deg)
        is reported as a weak axis with its 95 % profile-likelihood interval, and its line
        is scanned for a lower posterior.
    """

    init: str = "search"
    init_window_s: float = 300.0
    search_turn_deg: float = 360.0
    pf_window_s: float = 1200.0
    pf_window_growth: float = 1.5
    pf_rate_scales: tuple[float, ...] = (1.0, 0.25)
    local_candidates: int = 1024
    global_candidates: int = 20_000
    refine_keep: tuple[int, ...] | None = None
    hypotheses: int = 6
    search_tolerance: float = 0.0
    search_rounds: int = 3
    search_min_improvement: float = 0.1
    search_contention: float = 10.0
    min_epochs: int = 90
    max_sample_rotation_deg: float = 20.0
    process_noise_attitude: float = 1e-12
    process_noise_rate: float = 1e-16
    alpha: float = 1.0
    beta: float = 2.0
    kappa: float = 0.0
    underweighting: float = 0.0
    gate_probability: float = 1e-4
    estimate: tuple[str, ...] = ("inertia", "scale")
    model_tolerance_mag: float = 0.03
    rescue_starts: int = 0
    rescue_estimate: tuple[str, ...] = ("inertia", "scale", "material")
    adaptive_noise: bool = True
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
    mode_weak_sigma_deg: float = 1.0

    def __post_init__(self) -> None:
        if not (self.mode_offset_sigma_deg > 0 and 0 < self.mode_consistency_level < 1):
            raise ValueError("mode_offset_sigma_deg must be > 0, mode_consistency_level in (0, 1)")
        if not (math.isfinite(self.mode_weak_sigma_deg) and self.mode_weak_sigma_deg > 0):
            raise ValueError(
                f"mode_weak_sigma_deg must be positive and finite, got {self.mode_weak_sigma_deg}"
            )
        if self.init not in ("search", "none"):
            raise ValueError(f"init must be 'search' or 'none', got {self.init!r}")
        if not (self.pf_rate_scales and all(0 < s <= 1 for s in self.pf_rate_scales)):
            raise ValueError(f"pf_rate_scales must be in (0, 1], got {self.pf_rate_scales!r}")
        from lightcurve.photometry.adjusted import ADJUSTMENTS

        for key in ("estimate", "rescue_estimate"):
            unknown = sorted(set(getattr(self, key)) - set(ADJUSTMENTS))
            if unknown:
                raise ValueError(
                    f"unknown adjustment(s) in {key}: {', '.join(unknown)}; choose from "
                    + ", ".join(ADJUSTMENTS)
                )
        if self.rescue_starts < 0:
            raise ValueError(f"rescue_starts must be ≥ 0, got {self.rescue_starts}")
        if not (math.isfinite(self.model_tolerance_mag) and self.model_tolerance_mag >= 0):
            raise ValueError(
                f"model_tolerance_mag must be finite and ≥ 0, got {self.model_tolerance_mag}"
            )
        if not (math.isfinite(self.search_turn_deg) and self.search_turn_deg >= 0):
            raise ValueError(f"search_turn_deg must be finite and ≥ 0, got {self.search_turn_deg}")
        if self.likelihood not in ("gaussian", "student"):
            raise ValueError(f"likelihood must be 'gaussian' or 'student', got {self.likelihood!r}")

    def changed(self) -> set[str]:
        """Names of the fields set away from their defaults."""
        return {f.name for f in dataclasses.fields(self) if getattr(self, f.name) != f.default}


#: Options every method reads: the initial search, the consistency window, the model.
_COMMON = frozenset(
    {
        "local_candidates",
        "global_candidates",
        "refine_keep",
        "hypotheses",
        "search_tolerance",
        "search_rounds",
        "min_epochs",
        "max_sample_rotation_deg",
        "estimate_inertia",
        "consistency_window",
        "consistency_level",
        "faint_margin",
        "compile",
        "polish",
    }
)
#: Options of the UKF and of the MMAE bank of UKFs.
_FILTER = frozenset(
    {
        "init",
        "init_window_s",
        "search_turn_deg",
        "search_min_improvement",
        "process_noise_attitude",
        "process_noise_rate",
        "alpha",
        "beta",
        "kappa",
        "underweighting",
        "gate_probability",
        "inertia_sigma",
        "estimate_offset",
        "offset_sigma_mag",
        "estimate",
        "model_tolerance_mag",
        "rescue_starts",
        "rescue_estimate",
        "adaptive_noise",
    }
)
#: Options of the particle filter and of its search.
_PARTICLE = frozenset(
    {
        "pf_window_s",
        "pf_window_growth",
        "pf_rate_scales",
        "likelihood",
        "student_nu",
        "ess_threshold",
        "bandwidth",
        "moves",
        "mixture_tracking",
        "move_window",
        "mode_angle_deg",
        "mode_rate_deg_s",
        "min_mode_weight",
    }
)
#: Options read only with ``modes=True`` (the attitude-mode test).
MODE_OPTIONS = frozenset({"mode_offset_sigma_deg", "mode_consistency_level", "mode_weak_sigma_deg"})
#: Method → the options it reads (with ``modes=True``, :data:`MODE_OPTIONS` too).
METHOD_OPTIONS: dict[str, frozenset[str]] = {
    "ukf": _COMMON | _FILTER,
    "mmae": _COMMON | _FILTER | {"probability_floor", "search_contention"},
    "pf": _COMMON | _PARTICLE | {"search_contention"},
}


def validate_request(
    method: str,
    options: InversionOptions | None = None,
    *,
    modes: bool = False,
    n_shapes: int | None = None,
    q0: Any = None,
    omega0: Any = None,
    attitude_sigma_deg: float | None = None,
    omega_sigma: float | None = None,
    omega_max: float | None = None,
    particles: int | None = None,
    **option_overrides: Any,
) -> InversionOptions:
    """Check an inversion request before any data is read; return its options.

    Parameters are those of :func:`lightcurve.inversion.invert` (``n_shapes`` the number of
    candidate shapes, None when not yet known); a 1σ, rate bound or particle count left None
    stands for :func:`~lightcurve.inversion.invert`'s default and is not checked.

    Returns
    -------
    InversionOptions
        ``options`` (default: the defaults) with ``option_overrides`` applied.

    Raises
    ------
    ValueError
        Unknown method or option; an option set away from its default that ``method`` (or
        ``modes=False``) does not read; ``init="none"`` without ``q0``; a number of shapes
        the method does not take; a non-positive or non-finite 1σ, rate bound or particle
        count; ``q0`` not four finite numbers of non-zero norm, ``omega0`` not three finite
        numbers.
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {', '.join(METHODS)}, got {method!r}")
    names = {f.name for f in dataclasses.fields(InversionOptions)}
    unknown = set(option_overrides) - names
    if unknown:
        raise ValueError(f"unknown inversion option(s): {', '.join(sorted(unknown))}")
    options = dataclasses.replace(options or InversionOptions(), **option_overrides)
    read = METHOD_OPTIONS[method] | (MODE_OPTIONS if modes else frozenset())
    ignored = sorted(options.changed() - read)
    if ignored:
        hint = " (they need modes=True)" if set(ignored) <= MODE_OPTIONS else ""
        raise ValueError(f"method {method!r} does not use the option(s) {', '.join(ignored)}{hint}")
    if method == "ukf" and n_shapes is not None and n_shapes != 1:
        raise ValueError(
            f"method 'ukf' takes exactly one shape, got {n_shapes} (use 'mmae' or 'pf')"
        )
    if options.init == "none" and q0 is None:
        raise ValueError("init='none' needs q0 (and omega0) as the filters' starting point")
    for name, value in (
        ("attitude_sigma_deg", attitude_sigma_deg),
        ("omega_sigma", omega_sigma),
        ("omega_max", omega_max),
        ("particles", particles),
    ):
        if value is not None and not (math.isfinite(value) and value > 0):
            raise ValueError(f"{name} must be positive and finite, got {value}")
    for name, value, size in (("q0", q0, 4), ("omega0", omega0, 3)):
        if value is None:
            continue
        array = np.asarray(value, dtype=float)
        if array.shape != (size,) or not np.isfinite(array).all():
            raise ValueError(f"{name} must be {size} finite numbers, got {value!r}")
    if q0 is not None and not np.linalg.norm(np.asarray(q0, dtype=float)) > 0:
        raise ValueError("q0 must have a non-zero norm")
    return options
