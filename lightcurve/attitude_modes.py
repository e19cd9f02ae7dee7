"""Attitude-mode identification: is the object held by a control system, or tumbling?

For each candidate shape, every stabilised hypothesis — a profile of
:mod:`lightcurve.profiles` (``inertial``, ``nadir``, ``nadir yaw-steering``,
``sun-pointing``) with an unknown fixed offset — is fitted to the whole arc, and weighed
against the tumbling hypothesis (a torque-free initial state ``[q₀, ω₀]``, found by
today's search and filter, then fitted to the whole arc by batched Levenberg–Marquardt).

Model comparison by the Laplace approximation of the evidence (MacKay 2003, "Information
Theory, Inference, and Learning Algorithms", ch. 28): for a hypothesis ``H`` with ``k``
parameters ``θ``, best fit ``θ̂``, whitened residuals of Jacobian ``J`` and prior ``p(θ)``,

``ln Z_H ≈ −½ χ²(θ̂) + ln p(θ̂) + (k/2) ln 2π − ½ ln det(JᵀJ + P)``

(``P`` the prior's precision, which bounds the determinant along directions the data do not
see). This is the BIC's ``−½ k ln n`` made exact for the priors at hand: a parameter the data
pin down to ``σ`` inside a prior range ``Δ`` costs ``ln(Δ/σ)``. The priors:

* offsets of the ``nadir`` and ``sun-pointing`` profiles: isotropic normal, ``σ_off`` per
  axis (default 10°, so offsets of a few degrees cost little);
* the ``inertial`` attitude: uniform on SO(3), density ``G/(8π²)`` in small-angle
  coordinates (``G`` the order of the shape's rotational symmetry group, whose equivalent
  attitudes are all fits);
* tumbling: the same uniform attitude and rates uniform in the ball ``|ω| ≤ ω_max``.

A stabilised object is then fitted as well by the tumbling hypothesis (``ω`` ≈ the
profile's slow turn) but pays for six free parameters with wide priors (about 25 nats more
on a night of GEO photometry), and a tumbling object cannot be fitted by any profile.
The hypotheses' prior probabilities are ½ for tumbling and ½ shared equally by the
stabilised profiles (shapes equally likely); the posterior of a mode sums over shapes.

A direction of a fitted offset whose Laplace 1σ exceeds ``weak_sigma_deg`` (the turn about
the Sun line of a Sun-pointing body whose lit face is perpendicular to it, say) is reported
as a weak axis with its 95 % profile-likelihood interval (:class:`WeakAxis`), so the offset
is a point across such axes and an interval along them.

A stabilised hypothesis must also pass a consistency test: ``χ²`` at most the
``consistency_level`` quantile of ``χ²`` with ``n − k`` degrees of freedom. One that fails
is discarded (a profile that does not reproduce the light curve to within its noise is no
evidence of control); the tumbling hypothesis is never discarded, so an object that nothing
fits is reported ``tumbling`` — not shown to be stabilised — with ``none_fits`` set.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch
from scipy.optimize import least_squares
from scipy.stats import chi2 as chi2_distribution

from filters.attitude import (
    attitude_angle,
    quaternion_multiply,
    random_quaternion,
    rotation_vector_to_quaternion,
)
from filters.global_search import BatchProblem, Candidates, refine
from lightcurve.measurement import PhotometricModel
from lightcurve.profiles import body_rates, euler_offsets_deg, offset_quaternion, profile_attitude

__all__ = [
    "MODE_HYPOTHESES",
    "ModeHypothesis",
    "ModeIdentification",
    "WeakAxis",
    "identify_attitude_mode",
    "offset_error_deg",
]

#: Stabilised hypotheses: label → (profile, yaw steering).
MODE_HYPOTHESES = {
    "inertial": ("inertial", False),
    "nadir": ("nadir", False),
    "nadir yaw-steering": ("nadir", True),
    "sun-pointing": ("sun-pointing", False),
}
TUMBLING = "tumbling"
_LOG_SO3_VOLUME = math.log(8.0 * math.pi**2)
_ATTITUDE_PRECISION = 1.0 / math.pi**2
#: ``χ²₁`` quantile of the weak axes' 95 % profile-likelihood intervals.
_INTERVAL_CHI2 = float(chi2_distribution.ppf(0.95, 1))


@dataclass
class WeakAxis:
    """A direction of a fitted offset that the light curve pins down poorly.

    The offset is ``δ = δ̂ + t v`` along the axis: ``u`` the unit eigenvector of the
    posterior covariance ``C`` (small-angle rotation axis, body axes of the profile frame),
    ``v = C u / (uᵀ C u)`` the line along which the other components follow ``t`` at their
    conditional optimum (the profile line of a quadratic posterior).

    Attributes
    ----------
    axis : (3,) numpy.ndarray
        ``u`` (unit, body axes).
    sigma_deg : float
        Laplace 1σ along ``u`` (deg).
    interval_deg : (2,) numpy.ndarray
        ``[t_lo, t_hi]`` (deg, relative to the fitted offset): the stretch of the profile
        line around the best point where ``−2 ln`` posterior stays within
        ``χ²₁(0.95) = 3.84`` of its minimum (the 95 % profile-likelihood interval, Wilks'
        theorem; not symmetric, and wider than ``±2σ`` where the ``χ²`` valley is
        flat-bottomed), clipped to ``±3 σ_off``.
    """

    axis: np.ndarray
    sigma_deg: float
    interval_deg: np.ndarray

    def to_dict(self) -> dict[str, Any]:
        return {
            "axis": [float(v) for v in self.axis],
            "sigma_deg": float(self.sigma_deg),
            "interval_deg": [float(v) for v in self.interval_deg],
        }


@dataclass
class ModeHypothesis:
    """One fitted hypothesis.

    Attributes
    ----------
    mode : str
        ``tumbling`` or a key of :data:`MODE_HYPOTHESES`.
    shape : str
    chi2 : float
        ``Σ ((m̂ − m)/σ)²`` over all measurements at the best fit.
    n_params : int
    log_evidence : float
        Laplace ``ln Z`` (module doc; the constant ``−½ Σ ln 2πσ²`` left out).
    consistent : bool
        Passes the ``χ²`` consistency test.
    offsets_deg : (3,) numpy.ndarray or None
        ``[roll, pitch, yaw]`` (deg) of the fitted offset from the profile frame (for
        ``inertial``: of the fitted attitude from the inertial axes); None for tumbling.
    offset_sigma_deg : (3,) numpy.ndarray or None
        1σ of the offset's small-angle components (deg, body axes).
    weak_axes : list of WeakAxis
        Directions of the offset the light curve pins down worse than ``weak_sigma_deg``
        (empty for tumbling).
    quaternion : (4,) numpy.ndarray
        Attitude at the last epoch (inertial → body).
    omega_rad_s : (3,) numpy.ndarray
        Body rates at the last epoch (rad/s).
    """

    mode: str
    shape: str
    chi2: float
    n_params: int
    log_evidence: float
    consistent: bool
    offsets_deg: np.ndarray | None
    offset_sigma_deg: np.ndarray | None
    quaternion: np.ndarray
    omega_rad_s: np.ndarray
    weak_axes: list[WeakAxis] = field(default_factory=list)
    probability: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        def listed(v: np.ndarray | None) -> list[float] | None:
            return None if v is None else [float(x) for x in v]

        return {
            "mode": self.mode,
            "shape": self.shape,
            "chi2": float(self.chi2),
            "n_params": int(self.n_params),
            "log_evidence": float(self.log_evidence),
            "consistent": bool(self.consistent),
            "probability": float(self.probability),
            "offsets_deg": listed(self.offsets_deg),
            "offset_sigma_deg": listed(self.offset_sigma_deg),
            "offset_weak_axes": [w.to_dict() for w in self.weak_axes],
        }


@dataclass
class ModeIdentification:
    """Outcome of :func:`identify_attitude_mode`.

    Attributes
    ----------
    mode : str
        Most probable mode: ``tumbling`` or a stabilised profile label.
    probability : float
        Its posterior probability (summed over shapes).
    probabilities : dict
        Mode → posterior probability.
    best : ModeHypothesis
        Most probable hypothesis of the most probable mode.
    hypotheses : list of ModeHypothesis
    none_fits : bool
        No hypothesis passes the consistency test.
    notes : list of str
    """

    mode: str
    probability: float
    probabilities: dict[str, float]
    best: ModeHypothesis
    hypotheses: list[ModeHypothesis]
    none_fits: bool
    notes: list[str] = field(default_factory=list)

    @property
    def offsets_deg(self) -> np.ndarray | None:
        """Fitted offsets of the best hypothesis (None when tumbling)."""
        return self.best.offsets_deg

    def summary(self) -> dict[str, Any]:
        """The summary keys ``attitude_mode``, ``attitude_mode_probability``,
        ``attitude_offsets_deg``, ``attitude_offset_sigma_deg``, ``attitude_offset_weak_axes``
        and the details."""
        stabilised = self.mode != TUMBLING
        offsets = self.best.offsets_deg if stabilised else None
        sigma = self.best.offset_sigma_deg if stabilised else None
        return {
            "attitude_mode": self.mode,
            "attitude_mode_probability": float(self.probability),
            "attitude_offsets_deg": None if offsets is None else [float(v) for v in offsets],
            "attitude_offset_sigma_deg": None if sigma is None else [float(v) for v in sigma],
            "attitude_offset_weak_axes": [w.to_dict() for w in self.best.weak_axes]
            if stabilised
            else [],
            "attitude_mode_shape": self.best.shape,
            "attitude_mode_probabilities": {k: float(v) for k, v in self.probabilities.items()},
            "attitude_hypotheses": [h.to_dict() for h in self.hypotheses],
        }


def _log_evidence(chi2: float, log_prior: float, hessian: np.ndarray) -> float:
    """Laplace ``ln Z = −½ χ² + ln p(θ̂) + (k/2) ln 2π − ½ ln det H`` (module doc)."""
    sign, log_det = np.linalg.slogdet(hessian)
    if sign <= 0:
        return -math.inf
    return -0.5 * chi2 + log_prior + 0.5 * len(hessian) * math.log(2 * math.pi) - 0.5 * log_det


class _ProfileFit:
    """Whitened residuals of a profile with a small-angle offset ``δ`` (body frame):
    ``q = exp(δ) ⊗ q_ref`` (``q_ref`` the identity for the inertial profile, whose ``δ``
    is then the whole attitude, started from ``q_start``)."""

    def __init__(
        self, model: PhotometricModel, shape: int, q_ref: np.ndarray, q_start: np.ndarray
    ) -> None:
        self.model, self.shape = model, shape
        self.q_ref = quaternion_multiply(np.broadcast_to(q_start, q_ref.shape), q_ref)
        self.measured = model.magnitudes
        self.sigma = model.errors

    def attitudes(self, delta: np.ndarray) -> np.ndarray:
        """Attitudes ``(..., n, 4)`` of offsets ``delta (..., 3)``."""
        dq = rotation_vector_to_quaternion(np.asarray(delta, float))[..., None, :]
        return quaternion_multiply(
            np.broadcast_to(dq, (*dq.shape[:-2], *self.q_ref.shape)),
            np.broadcast_to(self.q_ref, (*dq.shape[:-2], *self.q_ref.shape)),
        )

    def residuals(self, delta: np.ndarray) -> np.ndarray:
        """``(m̂ − m)/σ`` of offsets ``delta (..., 3)``, shape ``(..., n)``."""
        m = self.model.magnitude(self.attitudes(delta), slice(None), self.shape)
        return (m - self.measured) / self.sigma

    def jacobian(self, delta: np.ndarray, step: float = 1e-4) -> np.ndarray:
        """Central differences of the residuals, ``(n, 3)``, in one batched render."""
        probes = delta + np.concatenate([np.eye(3), -np.eye(3)]) * step
        r = self.residuals(probes)
        return ((r[:3] - r[3:]) / (2 * step)).T


def _fit_profile(
    fit: _ProfileFit,
    starts: np.ndarray,
    prior_sigma: float | None,
) -> tuple[np.ndarray, float, np.ndarray]:
    """Least squares (MAP with a normal prior of ``prior_sigma`` rad per axis) from several
    starts; returns the best ``δ``, its data ``χ²`` and ``JᵀJ``."""
    best = None
    for start in starts:

        def fun(delta: np.ndarray) -> np.ndarray:
            r = fit.residuals(delta)
            return r if prior_sigma is None else np.concatenate([r, delta / prior_sigma])

        def jac(delta: np.ndarray) -> np.ndarray:
            j = fit.jacobian(delta)
            return j if prior_sigma is None else np.vstack([j, np.eye(3) / prior_sigma])

        solution = least_squares(fun, start, jac=jac, method="lm", xtol=1e-10, ftol=1e-10)
        if best is None or solution.cost < best.cost:
            best = solution
    delta = best.x
    r = fit.residuals(delta)
    j = fit.jacobian(delta)
    return delta, float(r @ r), j.T @ j


def _objective(fit: _ProfileFit, delta: np.ndarray, prior_sigma: float | None) -> np.ndarray:
    """``−2 ln`` posterior (up to a constant) of offsets ``delta (..., 3)``: ``χ²`` plus the
    normal prior's ``|δ|²/σ²``."""
    r = fit.residuals(delta)
    value = np.sum(r**2, axis=-1)
    return value if prior_sigma is None else value + np.sum(delta**2, axis=-1) / prior_sigma**2


def _weak_axes(
    fit: _ProfileFit,
    delta: np.ndarray,
    covariance: np.ndarray,
    prior_sigma: float | None,
    weak_sigma: float,
    half_width: float,
    restart: bool,
    step: float = math.radians(0.25),
) -> tuple[list[WeakAxis], np.ndarray | None]:
    """Scan the profile line of every direction whose Laplace σ exceeds ``weak_sigma`` (rad)
    over ``±half_width`` (rad) in one batched render each (:class:`WeakAxis`).

    Returns the weak axes, and (with ``restart``) a better offset when a scan finds the
    posterior lower by more than ½ somewhere on the line (the fit stopped in a side valley;
    refit from there).
    """
    variances, vectors = np.linalg.eigh(covariance)
    t = np.linspace(-half_width, half_width, 2 * math.ceil(half_width / step) + 1)
    centre = len(t) // 2
    axes = []
    for variance, u in zip(variances, vectors.T, strict=True):
        if not math.sqrt(max(variance, 0.0)) > weak_sigma:
            continue
        u = u * np.sign(u[np.argmax(np.abs(u))])  # eigenvector sign made reproducible
        line = covariance @ u / variance
        probes = delta + t[:, None] * line
        value = _objective(fit, probes, prior_sigma)
        best = int(np.argmin(value))
        if restart and value[best] < value[centre] - 0.5:
            return [], probes[best]
        inside = value - value[best] <= _INTERVAL_CHI2
        lo = hi = best
        while lo > 0 and inside[lo - 1]:
            lo -= 1
        while hi < len(t) - 1 and inside[hi + 1]:
            hi += 1
        interval = np.degrees([t[lo], t[hi]])
        axes.append(WeakAxis(u, math.degrees(math.sqrt(variance)), interval))
    return axes, None


def _stabilised(
    model: PhotometricModel,
    shape: int,
    label: str,
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
    profile, yaw = MODE_HYPOTHESES[label]
    n = len(model)
    identity = np.array([0.0, 0.0, 0.0, 1.0])
    q_ref = profile_attitude(
        profile, position=position, velocity=velocity, sun=model.sun, n=n, yaw_steering=yaw
    )
    if profile == "inertial":
        # The whole attitude is unknown: screen uniform attitudes (and the given starts) on
        # a subset of epochs, fit the best few from there.
        candidates = np.concatenate(
            [random_quaternion(search_candidates, rng), np.reshape(extra_starts, (-1, 4))]
        )
        pick = np.unique(np.linspace(0, n - 1, min(n, 60)).astype(int))
        m = model.magnitude(
            np.broadcast_to(candidates[:, None], (len(candidates), len(pick), 4)), pick, shape
        )
        cost = np.sum(((m - model.magnitudes[pick]) / model.errors[pick]) ** 2, axis=1)
        fits = []
        for q_start in candidates[np.argsort(cost)[:6]]:
            fit = _ProfileFit(model, shape, q_ref, q_start)
            fits.append((fit, *_fit_profile(fit, np.zeros((1, 3)), None)))
        fit, delta, chi2, information = min(fits, key=lambda f: f[2])
        prior_sigma = None
        precision = np.eye(3) * _ATTITUDE_PRECISION
    else:
        fit = _ProfileFit(model, shape, q_ref, identity)
        # Glints make the χ² surface rough within a few degrees: screen offsets drawn in
        # the prior's ±2σ cube on every epoch, then fit from the best few.
        probes = np.concatenate(
            [np.zeros((1, 3)), rng.uniform(-2.0, 2.0, (search_candidates // 4, 3)) * offset_sigma]
        )
        cost = np.sum(fit.residuals(probes) ** 2, axis=1) + np.sum(
            (probes / offset_sigma) ** 2, axis=1
        )
        starts = probes[np.argsort(cost)[:4]]
        delta, chi2, information = _fit_profile(fit, starts, offset_sigma)
        prior_sigma = offset_sigma
        precision = np.eye(3) / offset_sigma**2
    # Directions the light curve pins down poorly (e.g. the turn about the Sun line of a
    # Sun-pointing body whose lit faces are nearly perpendicular to it): scan their profile
    # lines; a lower point on a line restarts the fit from there (at most twice).
    for attempt in range(3):
        hessian = information + precision
        weak, better = _weak_axes(
            fit,
            delta,
            np.linalg.inv(hessian),
            prior_sigma,
            weak_sigma,
            3.0 * offset_sigma,
            restart=attempt < 2,
        )
        if better is None:
            break
        delta, chi2, information = _fit_profile(fit, np.array([better]), prior_sigma)
    if prior_sigma is None:
        log_prior = math.log(symmetry_order) - _LOG_SO3_VOLUME
    else:
        log_prior = (
            -1.5 * math.log(2 * math.pi * prior_sigma**2)
            - 0.5 * float(delta @ delta) / prior_sigma**2
        )
    log_evidence = _log_evidence(chi2, log_prior, hessian)
    q = fit.attitudes(delta)
    q_offset = quaternion_multiply(
        rotation_vector_to_quaternion(delta), fit.q_ref[0] if profile == "inertial" else identity
    )
    covariance = np.linalg.inv(hessian)
    return ModeHypothesis(
        mode=label,
        shape=model.names[shape],
        chi2=chi2,
        n_params=3,
        log_evidence=log_evidence,
        consistent=_consistent(chi2, n, 3, consistency_level),
        offsets_deg=euler_offsets_deg(q_offset),
        offset_sigma_deg=np.rad2deg(np.sqrt(np.clip(np.diag(covariance), 0, None))),
        quaternion=q[-1],
        omega_rad_s=body_rates(model.times, q)[-1],
        weak_axes=weak,
    )


def _consistent(chi2: float, n: int, k: int, level: float) -> bool:
    return bool(chi2 <= chi2_distribution.ppf(level, max(n - k, 1)))


def _tumbling(
    model: PhotometricModel,
    problem: BatchProblem,
    shape: int,
    starts: Sequence[tuple[np.ndarray, np.ndarray, float]],
    symmetry_order: int,
    omega_max: float,
    consistency_level: float,
    max_epochs: int,
    max_rotation: float,
) -> ModeHypothesis:
    """Whole-arc torque-free fit grown from the inversion's states."""
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
            count = max(max_epochs, math.ceil(duration * rate * 1.5 / max_rotation))
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
    precision = np.diag([_ATTITUDE_PRECISION] * 3 + [1.0 / omega_max**2] * 3)
    hessian = np.linalg.inv(covariance) + precision
    log_prior = (
        math.log(symmetry_order) - _LOG_SO3_VOLUME - math.log(4.0 / 3.0 * math.pi * omega_max**3)
    )
    log_evidence = _log_evidence(chi2, log_prior, hessian)
    last = np.array([len(times) - 2, len(times) - 1]) if len(times) > 1 else np.array([0])
    q_end = problem.trajectory(cand.q, cand.omega, cand.k, cand.shape, last, t_start)[0].numpy()
    return ModeHypothesis(
        mode=TUMBLING,
        shape=model.names[shape],
        chi2=chi2,
        n_params=6,
        log_evidence=log_evidence,
        consistent=_consistent(chi2, len(times), 6, consistency_level),
        offsets_deg=None,
        offset_sigma_deg=None,
        quaternion=q_end[-1],
        omega_rad_s=(
            cand.omega[0].numpy() if t_start == times[-1] else body_rates(times[last], q_end)[-1]
        ),
    )


def identify_attitude_mode(
    model: PhotometricModel,
    problem: BatchProblem,
    tumbling_starts: dict[int, list[tuple[np.ndarray, np.ndarray, float]]],
    symmetry_orders: Sequence[int],
    *,
    omega_max: float = math.radians(5.0),
    offset_sigma_deg: float = 10.0,
    weak_sigma_deg: float = 1.0,
    consistency_level: float = 0.999,
    search_candidates: int = 4096,
    max_epochs: int = 90,
    max_rotation: float = math.radians(20.0),
    position: np.ndarray | None = None,
    velocity: np.ndarray | None = None,
    seed: int = 0,
) -> ModeIdentification:
    """Weigh stabilised attitude profiles against tumbling (see the module doc).

    Parameters
    ----------
    model : PhotometricModel
        Measurements and candidate shapes.
    problem : BatchProblem
        The torque-free batch problem of the same measurements (the inversion's).
    tumbling_starts : dict
        Shape index → list of ``(q, ω, t)`` states of the tumbling inversion (attitude,
        rad/s, at time ``t`` s on the problem's axis) to grow the whole-arc fit from.
    symmetry_orders : sequence of int
        Order of each shape's rotational symmetry group.
    omega_max : float
        Radius of the tumbling rate prior (rad/s).
    offset_sigma_deg : float
        1σ per axis of the profile offsets' prior (deg).
    weak_sigma_deg : float
        Offset directions whose Laplace 1σ exceeds this (deg) are reported as weak axes
        with a profile-likelihood interval (:class:`WeakAxis`).
    consistency_level : float
        Quantile of the consistency test.
    search_candidates : int
        Uniform attitudes screened for the inertial hypothesis.
    max_epochs, max_rotation
        Sampling of the tumbling fit's growing windows (as the global search's).
    position, velocity : (n, 3) arrays, optional
        Geocentric object position and velocity (any consistent units): without them the
        nadir hypotheses are left out (noted).
    seed : int

    Returns
    -------
    ModeIdentification
    """
    rng = np.random.default_rng(seed)
    sigma = math.radians(offset_sigma_deg)
    notes = []
    labels = list(MODE_HYPOTHESES)
    if position is None or velocity is None:
        labels = [lab for lab in labels if MODE_HYPOTHESES[lab][0] != "nadir"]
        notes.append("no object position/velocity columns: nadir hypotheses left out")
    hypotheses = []
    for s in range(model.n_shapes):
        starts = tumbling_starts.get(s, [])
        tumbling = (
            _tumbling(
                model,
                problem,
                s,
                starts,
                symmetry_orders[s],
                omega_max,
                consistency_level,
                max_epochs,
                max_rotation,
            )
            if starts
            else None
        )
        extra = [q for q, _, t in starts if t == 0.0]
        for label in labels:
            hypotheses.append(
                _stabilised(
                    model,
                    s,
                    label,
                    position,
                    velocity,
                    symmetry_orders[s],
                    sigma,
                    consistency_level,
                    search_candidates,
                    rng,
                    extra,
                    math.radians(weak_sigma_deg),
                )
            )
        if tumbling is not None:
            hypotheses.append(tumbling)
    log_prior = {TUMBLING: math.log(0.5)}
    log_prior.update({lab: math.log(0.5 / len(labels)) for lab in labels})
    log_shape = -math.log(model.n_shapes)
    scores = np.array(
        [
            h.log_evidence + log_prior[h.mode] + log_shape
            if (h.consistent or h.mode == TUMBLING)
            else -math.inf
            for h in hypotheses
        ]
    )
    if not np.isfinite(scores).any():
        scores = np.array([h.log_evidence for h in hypotheses])
    weights = np.exp(scores - scores.max())
    weights /= weights.sum()
    for h, w in zip(hypotheses, weights, strict=True):
        h.probability = float(w)
    probabilities: dict[str, float] = {}
    for h in hypotheses:
        probabilities[h.mode] = probabilities.get(h.mode, 0.0) + h.probability
    mode = max(probabilities, key=probabilities.get)
    best = max((h for h in hypotheses if h.mode == mode), key=lambda h: h.probability)
    return ModeIdentification(
        mode=mode,
        probability=probabilities[mode],
        probabilities=probabilities,
        best=best,
        hypotheses=hypotheses,
        none_fits=not any(h.consistent for h in hypotheses),
        notes=notes,
    )


def offset_error_deg(estimated_deg: Sequence[float], true_deg: Sequence[float]) -> float:
    """Angle (deg) between two offsets given as ``[roll, pitch, yaw]`` (deg)."""
    return math.degrees(
        float(attitude_angle(offset_quaternion(estimated_deg), offset_quaternion(true_deg)))
    )
