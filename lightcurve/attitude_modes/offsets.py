"""Fit of a stabilised profile's fixed offset: whitened residuals of an offset, the local
least-squares step, and the multi-start that keeps it out of side valleys.

Glints of flat panels make the ``χ²`` surface of an offset rough: valleys a few degrees
wide, finer than any affordable coarse scan of the prior's range. :func:`refine_offset`
therefore starts the local step from several distinct valleys of the coarse scan, then
probes shells around the best optimum at fractions of the scan's spacing (the scale the
scan cannot resolve) and restarts from the lowest distinct probes while that lowers the
posterior — a few rounds of basin hopping (Wales & Doye 1997, "Global optimization by
basin-hopping and the lowest energy structures of Lennard-Jones clusters") with
deterministic moves.

A whole inertial attitude has no prior range to scan finely: :func:`descend_attitudes`
takes many screened attitudes a few batched Levenberg–Marquardt steps downhill at once, so
the valleys are chosen by where those attitudes lead rather than by the rough ``χ²`` at
the screen's points.
"""

from __future__ import annotations

import functools
import itertools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from filters.attitude import quaternion_multiply, rotation_vector_to_quaternion
from lightcurve.photometry.measurement import PhotometricModel

_CUBE_NEIGHBOURS = np.array([d for d in itertools.product((-1.0, 0.0, 1.0), repeat=3) if any(d)])
#: Unit directions of the local shells: towards the 26 neighbours of a cube grid point.
_SHELL_DIRECTIONS = _CUBE_NEIGHBOURS / np.linalg.norm(_CUBE_NEIGHBOURS, axis=1, keepdims=True)
#: Shell radii, in units of the coarse scan's spacing.
_SHELL_RADII = (0.25, 0.5, 1.0)
#: Restarts per shell round (the lowest probes at least a quarter spacing apart).
_SHELL_STARTS = 3
#: Shell rounds at most; a round that lowers ``−2 ln`` posterior by less than
#: :data:`_IMPROVEMENT` ends the search.
_SHELL_ROUNDS = 3
_IMPROVEMENT = 1e-3


class ProfileFit:
    """Whitened residuals of a profile with a small-angle offset ``δ`` (rad, body axes):
    ``q = exp(δ) ⊗ q_start ⊗ q_ref`` (``q_ref`` the identity for the inertial profile,
    whose ``δ`` is then the whole attitude about ``q_start``).

    Parameters
    ----------
    model : PhotometricModel
    shape : int
        Index of the candidate shape.
    q_ref : (n, 4) numpy.ndarray
        The profile's attitudes (inertial → profile frame) at the measurements.
    q_start : (4,) numpy.ndarray
        Fixed rotation composed on the body side of ``q_ref``.
    """

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


@dataclass
class OffsetFit:
    """A locally optimal offset.

    Attributes
    ----------
    delta : (3,) numpy.ndarray
        Offset (rad, small-angle rotation vector, body axes).
    cost : float
        ``−2 ln`` posterior (up to a constant): ``χ²`` plus ``|δ|²/σ²`` with a prior.
    chi2 : float
        Data ``χ²``.
    information : (3, 3) numpy.ndarray
        ``JᵀJ`` of the whitened residuals.
    """

    delta: np.ndarray
    cost: float
    chi2: float
    information: np.ndarray


def posterior_cost(fit: ProfileFit, delta: np.ndarray, prior_sigma: float | None) -> np.ndarray:
    """``−2 ln`` posterior (up to a constant) of offsets ``delta (..., 3)``: ``χ²`` plus the
    normal prior's ``|δ|²/σ²`` (``prior_sigma`` rad; None: a flat prior)."""
    r = fit.residuals(delta)
    value = np.sum(r**2, axis=-1)
    return value if prior_sigma is None else value + np.sum(delta**2, axis=-1) / prior_sigma**2


def local_fit(
    fit: ProfileFit,
    start: np.ndarray,
    prior_sigma: float | None,
    basis: np.ndarray | None = None,
) -> OffsetFit:
    """Levenberg–Marquardt from ``start`` (MAP with the normal prior of ``prior_sigma`` rad
    per axis; None: least squares).

    With ``basis`` (``(3, k)``, orthonormal columns) only ``δ = start + B x`` moves: the
    fit of the other components at a fixed position along the remaining direction (a step
    of a profile likelihood).
    """
    origin = np.asarray(start, float)
    basis = np.eye(3) if basis is None else np.asarray(basis, float)

    def fun(x: np.ndarray) -> np.ndarray:
        delta = origin + basis @ x
        r = fit.residuals(delta)
        return r if prior_sigma is None else np.concatenate([r, delta / prior_sigma])

    def jac(x: np.ndarray) -> np.ndarray:
        j = fit.jacobian(origin + basis @ x)
        j = j if prior_sigma is None else np.vstack([j, np.eye(3) / prior_sigma])
        return j @ basis

    solution = least_squares(
        fun, np.zeros(basis.shape[1]), jac=jac, method="lm", xtol=1e-10, ftol=1e-10
    )
    delta = origin + basis @ solution.x
    r = fit.residuals(delta)
    j = fit.jacobian(delta)
    chi2 = float(r @ r)
    prior = 0.0 if prior_sigma is None else float(delta @ delta) / prior_sigma**2
    return OffsetFit(delta, chi2 + prior, chi2, j.T @ j)


def fixed_attitude_residuals(
    model: PhotometricModel, shape: int, attitudes: np.ndarray, epochs: np.ndarray
) -> np.ndarray:
    """Whitened residuals ``(m̂ − m)/σ``, ``(..., E)``, of attitudes ``(..., 4)`` (inertial →
    body) held fixed over the measurements ``epochs`` (indices, ``(E,)``)."""
    m = model.magnitude(
        np.broadcast_to(attitudes[..., None, :], (*attitudes.shape[:-1], len(epochs), 4)),
        epochs,
        shape,
    )
    return (m - model.magnitudes[epochs]) / model.errors[epochs]


def descend_attitudes(
    model: PhotometricModel,
    shape: int,
    attitudes: np.ndarray,
    epochs: np.ndarray,
    steps: int,
    step: float = 1e-3,
) -> tuple[np.ndarray, np.ndarray]:
    """Batched Levenberg–Marquardt steps (Marquardt 1963, "An algorithm for least-squares
    estimation of nonlinear parameters") of many fixed inertial attitudes at once.

    Each attitude ``c`` moves by ``c ← exp(δ) ⊗ c``, ``δ`` (rad, body axes) the damped
    Gauss–Newton step of its whitened residuals on ``epochs``, with forward differences of
    ``step`` rad; a step that lowers its ``χ²`` is kept and divides its damping by 10,
    one that does not is dropped and multiplies it by 10. One batched render per
    difference and per trial.

    Parameters
    ----------
    model : PhotometricModel
    shape : int
        Index of the candidate shape.
    attitudes : (K, 4) numpy.ndarray
        Starting attitudes (inertial → body), constant over the arc.
    epochs : (E,) numpy.ndarray
        Indices of the measurements fitted.
    steps : int
        Trial steps per attitude.
    step : float
        Forward-difference step (rad).

    Returns
    -------
    (K, 4) numpy.ndarray, (K,) numpy.ndarray
        The attitudes reached and their ``χ²`` on ``epochs``.
    """
    residuals = functools.partial(fixed_attitude_residuals, model, shape, epochs=epochs)
    q = np.asarray(attitudes, float)
    r = residuals(q)
    chi2 = np.sum(r**2, axis=-1)
    damping = np.full(len(q), 1e-2)
    probes = rotation_vector_to_quaternion(np.eye(3) * step)
    for _ in range(steps):
        rp = residuals(quaternion_multiply(probes[None], q[:, None]))  # (K, 3, E)
        j = np.swapaxes(rp - r[:, None], 1, 2) / step  # (K, E, 3)
        normal = np.einsum("kei,kej->kij", j, j)
        scale = np.einsum("kii->ki", normal)[..., None] * np.eye(3) + 1e-12 * np.eye(3)
        delta = -np.linalg.solve(
            normal + damping[:, None, None] * scale, np.einsum("kei,ke->ki", j, r)[..., None]
        )[..., 0]
        trial = quaternion_multiply(rotation_vector_to_quaternion(delta), q)
        r_trial = residuals(trial)
        chi2_trial = np.sum(r_trial**2, axis=-1)
        better = chi2_trial < chi2
        q = np.where(better[:, None], trial, q)
        r = np.where(better[:, None], r_trial, r)
        chi2 = np.where(better, chi2_trial, chi2)
        damping = np.where(better, damping / 10.0, damping * 10.0)
    return q, chi2


def distinct_lowest(
    points: np.ndarray,
    values: np.ndarray,
    count: int,
    separation: float,
    distance: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
) -> np.ndarray:
    """Indices of the lowest ``values``, greedily, each at least ``separation`` from those
    already taken: one start per valley of a scan rather than several in the deepest.

    Parameters
    ----------
    points : (N, d) numpy.ndarray
    values : (N,) numpy.ndarray
    count : int
        At most this many indices.
    separation : float
        In the units of ``distance``.
    distance : callable, optional
        ``distance(point, points) → (N,)``; default Euclidean.
    """
    if distance is None:

        def distance(p: np.ndarray, others: np.ndarray) -> np.ndarray:
            return np.linalg.norm(others - p, axis=-1)

    taken: list[int] = []
    for i in np.argsort(values, kind="stable"):
        if not np.isfinite(values[i]):
            break
        if taken and np.min(distance(points[i], points[taken])) < separation:
            continue
        taken.append(int(i))
        if len(taken) == count:
            break
    return np.array(taken, dtype=int)


def shell_restarts(
    fit: ProfileFit, best: OffsetFit, prior_sigma: float | None, spacing: float
) -> OffsetFit:
    """Restart the local step from shells around ``best`` while that lowers the posterior
    (module doc).

    Parameters
    ----------
    fit : ProfileFit
    best : OffsetFit
        The best local optimum of the starts of a coarse scan.
    prior_sigma : float or None
        1σ (rad) of the offset's normal prior; None: flat.
    spacing : float
        Spacing (rad) of that coarse scan; the shells' radii are ``(¼, ½, 1) × spacing``,
        each with 26 directions, in one batched render per round.

    Returns
    -------
    OffsetFit
        The lowest optimum found (``best`` when no restart improves on it).
    """
    radii = np.asarray(_SHELL_RADII) * spacing
    shell = (radii[:, None, None] * _SHELL_DIRECTIONS[None]).reshape(-1, 3)
    for _ in range(_SHELL_ROUNDS):
        probes = best.delta + shell
        values = posterior_cost(fit, probes, prior_sigma)
        picks = distinct_lowest(probes, values, _SHELL_STARTS, radii[0])
        found = min((local_fit(fit, probes[i], prior_sigma) for i in picks), key=_cost)
        if not found.cost < best.cost - _IMPROVEMENT:
            break
        best = found
    return best


def _cost(solution: OffsetFit) -> float:
    return solution.cost
