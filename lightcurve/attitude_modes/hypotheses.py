"""The two kinds of hypothesis fitted to a whole arc: a stabilised profile with a fixed
offset, and torque-free tumbling grown from the inversion's states."""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import torch

from filters.attitude import (
    attitude_angle,
    quaternion_multiply,
    random_quaternion,
    rotation_vector_to_quaternion,
)
from filters.global_search import BatchProblem, Candidates, refine
from lightcurve.attitude_modes.evidence import (
    ATTITUDE_PRECISION,
    LOG_SO3_VOLUME,
    attitude_log_prior,
    consistent,
    log_evidence,
    offset_log_prior,
)
from lightcurve.attitude_modes.offsets import (
    OffsetFit,
    ProfileFit,
    descend_attitudes,
    distinct_lowest,
    fixed_attitude_residuals,
    local_fit,
    posterior_cost,
    shell_restarts,
)
from lightcurve.attitude_modes.posterior import sample_offset_posterior
from lightcurve.attitude_modes.results import TUMBLING, ModeHypothesis
from lightcurve.attitude_modes.weak_axes import weak_axes
from lightcurve.photometry.measurement import PhotometricModel
from lightcurve.photometry.profiles import body_rates, euler_offsets_deg, profile_attitude

#: Stabilised hypotheses: label → (profile, yaw steering).
MODE_HYPOTHESES = {
    "inertial": ("inertial", False),
    "nadir": ("nadir", False),
    "nadir yaw-steering": ("nadir", True),
    "sun-pointing": ("sun-pointing", False),
}
#: Distinct valleys of the coarse scan refined by the local step: offsets, inertial attitudes.
_OFFSET_VALLEYS = 4
_ATTITUDE_VALLEYS = 6
#: Epochs (at most) on which uniform inertial attitudes are screened and descended.
_SCREEN_EPOCHS = 60
#: Scale, in units of each measurement's σ, of the Cauchy loss that ranks the screen.
_SCREEN_SCALE = 3.0
#: Screened attitudes descended (one in this many, the lowest by the Cauchy loss), and
#: the batched Levenberg–Marquardt steps each takes before the valleys are chosen.
_DESCENT_FRACTION = 16
_DESCENT_STEPS = 12
#: Weak-axis restarts at most.
_WEAK_RESTARTS = 2


def _offset_scan(
    fit: ProfileFit, offset_sigma: float, count: int, rng: np.random.Generator
) -> tuple[np.ndarray, float]:
    """Starts of a profile's offset: the distinct valleys among zero and ``count`` offsets
    drawn uniformly in the prior's ±2σ cube (glints make the ``χ²`` surface rough within a
    few degrees), screened on every epoch; and the scan's spacing (rad)."""
    probes = np.concatenate([np.zeros((1, 3)), rng.uniform(-2.0, 2.0, (count, 3)) * offset_sigma])
    spacing = 4.0 * offset_sigma / len(probes) ** (1 / 3)
    values = posterior_cost(fit, probes, offset_sigma)
    return probes[distinct_lowest(probes, values, _OFFSET_VALLEYS, spacing)], spacing


def _attitude_scan(
    model: PhotometricModel,
    shape: int,
    q_ref: np.ndarray,
    candidates: np.ndarray,
) -> tuple[ProfileFit, OffsetFit, float]:
    """Best local fit of an inertial attitude started from ``candidates``; and the
    screen's spacing (rad).

    The glints of flat panels make ``χ²`` sharp on the scale of a degree, while its
    valleys draw a local fit in from 15–20°: an attitude of the screen a few degrees from
    the truth can mistime a glint by many magnitudes and rank below broad wrong attitudes
    that match the mean brightness. So the screen (on a subset of epochs) ranks by the
    Cauchy loss ``Σ ln(1 + (r/c)²)``, ``r`` the whitened residuals and ``c`` =
    :data:`_SCREEN_SCALE` (Holland & Welsch 1977, "Robust regression using iteratively
    reweighted least-squares"), which a few mistimed glints cannot dominate; the lowest
    ``1/``:data:`_DESCENT_FRACTION` of the candidates then go :data:`_DESCENT_STEPS`
    batched Levenberg–Marquardt steps downhill (:func:`descend_attitudes`) on the same
    epochs, and the local fit on every epoch starts from the distinct valleys they reach
    — a clustering multistart (Rinnooy Kan & Timmer 1987, "Stochastic global optimization
    methods part I: clustering methods").
    """
    n = len(model)
    pick = np.unique(np.linspace(0, n - 1, min(n, _SCREEN_EPOCHS)).astype(int))
    r = fixed_attitude_residuals(model, shape, candidates, pick)
    screen = np.sum(np.log1p((r / _SCREEN_SCALE) ** 2), axis=1)
    count = max(_ATTITUDE_VALLEYS, len(candidates) // _DESCENT_FRACTION)
    lowest = np.argsort(screen, kind="stable")[:count]
    reached, chi2 = descend_attitudes(model, shape, candidates[lowest], pick, _DESCENT_STEPS)
    spacing = math.exp(LOG_SO3_VOLUME / 3) / len(candidates) ** (1 / 3)
    # Descended attitudes within a quarter of the screen's spacing share a valley.
    valleys = distinct_lowest(reached, chi2, _ATTITUDE_VALLEYS, spacing / 4, attitude_angle)
    fits = [ProfileFit(model, shape, q_ref, q) for q in reached[valleys]]
    solutions = [local_fit(fit, np.zeros(3), None) for fit in fits]
    best = int(np.argmin([s.cost for s in solutions]))
    return fits[best], solutions[best], spacing


def stabilised(
    model: PhotometricModel,
    shape: int,
    label: str,
    *,
    position: np.ndarray | None,
    velocity: np.ndarray | None,
    symmetry_order: int,
    offset_sigma: float,
    consistency_level: float,
    search_candidates: int,
    rng: np.random.Generator,
    extra_starts: Sequence[np.ndarray],
    weak_sigma: float,
) -> ModeHypothesis:
    """Fit the stabilised hypothesis ``label`` (a key of :data:`MODE_HYPOTHESES`) of shape
    ``shape`` to the whole arc and weigh it (:mod:`lightcurve.attitude_modes`).

    The offset of the ``nadir`` and ``sun-pointing`` profiles (normal prior of
    ``offset_sigma`` rad per axis) starts from the distinct valleys of a scan of
    ``search_candidates // 4`` offsets; the ``inertial`` attitude (uniform prior) from
    the valleys reached by descending the lowest of ``search_candidates`` uniform
    attitudes plus ``extra_starts`` (:func:`_attitude_scan`). The best local
    optimum is then restarted from shells around it (:func:`shell_restarts`), and from a
    lower point on the line of a weak axis (:func:`weak_axes`, threshold ``weak_sigma``
    rad). ``position``, ``velocity`` (geocentric, any consistent units) are the nadir
    profiles'.
    """
    profile, yaw = MODE_HYPOTHESES[label]
    n = len(model)
    identity = np.array([0.0, 0.0, 0.0, 1.0])
    q_ref = profile_attitude(
        profile, position=position, velocity=velocity, sun=model.sun, n=n, yaw_steering=yaw
    )
    if profile == "inertial":
        candidates = np.concatenate(
            [random_quaternion(search_candidates, rng), np.reshape(extra_starts, (-1, 4))]
        )
        fit, solution, spacing = _attitude_scan(model, shape, q_ref, candidates)
        prior_sigma = None
        precision = np.eye(3) * ATTITUDE_PRECISION
    else:
        fit = ProfileFit(model, shape, q_ref, identity)
        starts, spacing = _offset_scan(fit, offset_sigma, search_candidates // 4, rng)
        solution = min((local_fit(fit, s, offset_sigma) for s in starts), key=lambda f: f.cost)
        prior_sigma = offset_sigma
        precision = np.eye(3) / offset_sigma**2
    solution = shell_restarts(fit, solution, prior_sigma, spacing)
    # Directions the light curve pins down poorly (e.g. the turn about the Sun line of a
    # Sun-pointing body whose lit faces are nearly perpendicular to it, or a curved valley
    # of glints): walk their profiles; a lower point on a profile restarts the fit there.
    for attempt in range(_WEAK_RESTARTS + 1):
        hessian = solution.information + precision
        weak, lower = weak_axes(
            fit,
            solution,
            np.linalg.inv(hessian),
            prior_sigma=prior_sigma,
            weak_sigma=weak_sigma,
            half_width=3.0 * offset_sigma,
            restart=attempt < _WEAK_RESTARTS,
        )
        if lower is None:
            break
        solution = shell_restarts(
            fit, local_fit(fit, lower.delta, prior_sigma), prior_sigma, spacing
        )
    delta, chi2 = solution.delta, solution.chi2
    if prior_sigma is None:
        log_prior = attitude_log_prior(symmetry_order)
    else:
        log_prior = offset_log_prior(delta, prior_sigma)
    q = fit.attitudes(delta)
    offset_quaternions = functools.partial(
        _offset_quaternions, base=fit.q_ref[0] if profile == "inertial" else identity
    )
    covariance = np.linalg.inv(hessian)
    return _weighed(
        label,
        model.names[shape],
        chi2,
        log_prior=log_prior,
        hessian=hessian,
        n_measurements=n,
        consistency_level=consistency_level,
        offsets_deg=euler_offsets_deg(offset_quaternions(delta)),
        offset_sigma_deg=np.rad2deg(np.sqrt(np.clip(np.diag(covariance), 0, None))),
        quaternion=q[-1],
        omega_rad_s=body_rates(model.times, q)[-1],
        weak_axes=weak,
        posterior_sampler=functools.partial(
            sample_offset_posterior,
            fit,
            solution,
            covariance,
            prior_sigma=prior_sigma,
            offset_quaternions=offset_quaternions,
        ),
    )


def _offset_quaternions(delta: np.ndarray, base: np.ndarray) -> np.ndarray:
    """Offset quaternions ``exp(δ) ⊗ base`` of small-angle offsets ``delta (..., 3)`` (rad):
    from the profile frame (``base`` the identity), or for ``inertial`` of the attitude
    from the inertial axes (``base`` the attitude ``δ`` is taken about)."""
    dq = rotation_vector_to_quaternion(np.asarray(delta, float))
    return quaternion_multiply(dq, np.broadcast_to(base, dq.shape))


def tumbling(
    model: PhotometricModel,
    problem: BatchProblem,
    shape: int,
    *,
    starts: Sequence[tuple[np.ndarray, np.ndarray, float]],
    symmetry_order: int,
    omega_max: float,
    consistency_level: float,
    min_epochs: int,
    max_rotation: float,
) -> ModeHypothesis:
    """Whole-arc torque-free fit of shape ``shape`` grown from the inversion's states.

    Each start ``(q, ω, t)`` is refined by batched Levenberg–Marquardt on windows around
    ``t`` doubling from 240 s to the whole arc, each sampled by at least ``min_epochs``
    measurements (more when a rotation at ``1.5 |ω|`` between them would exceed
    ``max_rotation`` rad); the lowest ``χ²`` is weighed with the uniform attitude prior and
    rates uniform in ``|ω| ≤ omega_max`` (rad/s).
    """
    times = problem.times
    span = float(times[-1] - times[0])
    best = None
    for q, omega, t_start in starts:
        cand = Candidates(
            torch.as_tensor(np.asarray(q, float)[None]),
            torch.as_tensor(np.asarray(omega, float)[None]),
            torch.tensor([shape]),
        )
        duration = 240.0
        while True:
            duration = min(duration, span)
            inside = np.flatnonzero(np.abs(times - t_start) <= duration)
            rate = max(float(np.linalg.norm(omega)), math.radians(0.05))
            count = max(min_epochs, math.ceil(duration * rate * 1.5 / max_rotation))
            if duration >= span:
                epochs = np.arange(len(times))
            elif len(inside) > count:
                epochs = inside[np.round(np.linspace(0, len(inside) - 1, count)).astype(int)]
            else:
                epochs = inside
            cand = refine(problem, cand, epochs, t_start=t_start)
            if duration >= span:
                break
            duration *= 2.0
        if best is None or float(cand.chi2[0]) < float(best[0].chi2[0]):
            best = (cand, t_start)
    cand, t_start = best
    chi2 = float(cand.chi2[0])
    covariance = cand.covariance[0].numpy()
    precision = np.diag([ATTITUDE_PRECISION] * 3 + [1.0 / omega_max**2] * 3)
    hessian = np.linalg.inv(covariance) + precision
    log_prior = attitude_log_prior(symmetry_order) - math.log(4.0 / 3.0 * math.pi * omega_max**3)
    last = np.array([len(times) - 2, len(times) - 1]) if len(times) > 1 else np.array([0])
    q_end = problem.trajectory(cand.q, cand.omega, cand.k, cand.shape, last, t_start)[0].numpy()
    return _weighed(
        TUMBLING,
        model.names[shape],
        chi2,
        log_prior=log_prior,
        hessian=hessian,
        n_measurements=len(times),
        consistency_level=consistency_level,
        offsets_deg=None,
        offset_sigma_deg=None,
        quaternion=q_end[-1],
        omega_rad_s=(
            cand.omega[0].numpy() if t_start == times[-1] else body_rates(times[last], q_end)[-1]
        ),
    )


def _weighed(
    mode: str,
    shape: str,
    chi2: float,
    *,
    log_prior: float,
    hessian: np.ndarray,
    n_measurements: int,
    consistency_level: float,
    **state: Any,
) -> ModeHypothesis:
    """The hypothesis ``mode`` of ``shape`` fitted with ``chi2``, weighed: its Laplace
    evidence (:func:`log_evidence`) and its ``χ²`` consistency test, with as many parameters
    as ``hessian`` (``k × k``) has rows; ``state`` holds the remaining fields of
    :class:`ModeHypothesis` (offsets, final attitude and rates)."""
    n_params = len(hessian)
    return ModeHypothesis(
        mode=mode,
        shape=shape,
        chi2=chi2,
        n_params=n_params,
        log_evidence=log_evidence(chi2, log_prior, hessian),
        consistent=consistent(chi2, n_measurements, n_params, consistency_level),
        **state,
    )
