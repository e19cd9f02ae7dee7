"""Directions of a fitted offset that the light curve pins down poorly: the profile
likelihood along each principal direction of the Laplace covariance, its 95 % interval,
and the lower points a walk along it can reveal.

The Laplace covariance describes the ``χ²`` surface only near its minimum. Glints make
that surface rough, and its valleys can curve: a minimum sharp on the scale of a tenth of
a degree can sit in a valley along which ``χ²`` rises by a few units over degrees. The
profile likelihood sees such a valley — at each position ``t`` along a direction ``u`` the
other two components are refitted, warm-started from the previous position (Venzon &
Moolgavkar 1988, "A method for computing profile-likelihood-based confidence intervals") —
so a direction is weak when either its Laplace 1σ or the half-width of its 95 % interval
over ``√χ²₁(0.95)`` exceeds the threshold.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.stats import chi2 as chi2_distribution

from lightcurve.attitude_modes.offsets import OffsetFit, ProfileFit, local_fit, posterior_cost
from lightcurve.attitude_modes.results import WeakAxis

#: ``χ²₁`` quantile of the weak axes' 95 % profile-likelihood intervals.
INTERVAL_CHI2 = float(chi2_distribution.ppf(0.95, 1))
#: A profile this much (``−2 ln`` posterior) below the fit means the fit sits in a side
#: valley: refit from there.
_RESTART_DROP = 0.5


def profile_interval(
    fit: ProfileFit,
    solution: OffsetFit,
    axis: np.ndarray,
    *,
    prior_sigma: float | None,
    half_width: float,
    step: float,
    restart: bool,
) -> tuple[np.ndarray, OffsetFit | None]:
    """Walk the profile of ``−2 ln`` posterior along ``axis`` out from ``solution`` in
    steps of ``step`` (rad) until it rises by more than ``χ²₁(0.95)`` or reaches
    ``±half_width`` (rad).

    Returns
    -------
    numpy.ndarray, OffsetFit or None
        ``[t_lo, t_hi]`` (rad): the last positions on either side within ``χ²₁(0.95)``;
        and, with ``restart``, a refit point whose posterior is lower than the fit's by
        more than :data:`_RESTART_DROP` (the walk then stops; None when there is none).
    """
    complement = np.linalg.svd(axis[None, :])[2][1:].T  # (3, 2), orthonormal, ⊥ axis
    bounds = np.zeros(2)
    for side, sign in enumerate((-1.0, 1.0)):
        point = solution.delta
        steps = 0
        while (steps + 1) * step <= half_width:
            found = local_fit(fit, point + sign * step * axis, prior_sigma, complement)
            rise = found.cost - solution.cost
            if restart and rise < -_RESTART_DROP:
                return bounds, found
            if rise > INTERVAL_CHI2:
                break
            steps += 1
            point = found.delta
        bounds[side] = sign * steps * step
    return bounds, None


def weak_axes(
    fit: ProfileFit,
    solution: OffsetFit,
    covariance: np.ndarray,
    *,
    prior_sigma: float | None,
    weak_sigma: float,
    half_width: float,
    restart: bool,
    step: float = math.radians(0.25),
) -> tuple[list[WeakAxis], OffsetFit | None]:
    """The weak axes of a fitted offset (module doc; :class:`WeakAxis`).

    Parameters
    ----------
    fit : ProfileFit
    solution : OffsetFit
        The fitted offset.
    covariance : (3, 3) numpy.ndarray
        Its Laplace covariance (rad²); the profiles run along its eigenvectors.
    prior_sigma : float or None
        1σ (rad) of the offset's normal prior; None: flat.
    weak_sigma : float
        Threshold (rad) on the Laplace σ and on the interval's half-width over
        ``√χ²₁(0.95)``.
    half_width : float
        Longest walk (rad) on either side.
    restart : bool
        Stop at the first lower point a walk, or a scan of the Laplace profile line over
        ``±half_width`` (``δ̂ + t C u / uᵀCu``, past ridges the walk stops at), finds, and
        return it refitted.
    step : float
        Walk step (rad).

    Returns
    -------
    list of WeakAxis, OffsetFit or None
        The weak axes; or, with ``restart``, when a walk finds a lower posterior (the fit
        stopped in a side valley), no axes and the refit point to restart from.
    """
    variances, vectors = np.linalg.eigh(covariance)
    t = np.linspace(-half_width, half_width, 2 * math.ceil(half_width / step) + 1)
    axes = []
    for variance, u in zip(variances, vectors.T, strict=True):
        u = u * np.sign(u[np.argmax(np.abs(u))])  # eigenvector sign made reproducible
        if restart:
            # Beyond a ridge the walk cannot see: the whole line along which the other
            # components follow at their Laplace conditional optimum, in one batched render.
            probes = solution.delta + t[:, None] * (covariance @ u / variance)
            value = posterior_cost(fit, probes, prior_sigma)
            if value.min() < solution.cost - _RESTART_DROP:
                return [], local_fit(fit, probes[int(np.argmin(value))], prior_sigma)
        interval, lower = profile_interval(
            fit,
            solution,
            u,
            prior_sigma=prior_sigma,
            half_width=half_width,
            step=step,
            restart=restart,
        )
        if lower is not None:
            return [], lower
        sigma = math.sqrt(max(variance, 0.0))
        spread = (interval[1] - interval[0]) / (2.0 * math.sqrt(INTERVAL_CHI2))
        if max(sigma, spread) > weak_sigma:
            axes.append(WeakAxis(u, math.degrees(sigma), np.degrees(interval)))
    return axes, None
