""":func:`invert`: the checks, the table of methods and the attitude-mode test."""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from filters.attitude import (
    quaternion_canonical,
)
from lightcurve.inversion.bank import run_bank
from lightcurve.inversion.context import (
    Context,
    Progress,
    batch_problem,
    check_observations,
    initial_prior,
    resolve_shapes,
)
from lightcurve.inversion.options import InversionOptions, validate_request
from lightcurve.inversion.particles import run_pf
from lightcurve.inversion.result import InversionResult, unknown_state_uncertainty
from lightcurve.io.observations import Observations
from lightcurve.photometry.measurement import PhotometricModel
from shapes import FacetModel

#: Method name → its estimator, ``runner(ctx) → InversionResult``.
RUNNERS: dict[str, Callable[[Context], InversionResult]] = {
    "ukf": run_bank,
    "mmae": run_bank,
    "pf": run_pf,
}


def invert(
    observations: Observations,
    shapes: Mapping[str, FacetModel] | Sequence[str] | FacetModel | str,
    method: str = "ukf",
    *,
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
        A request :func:`~lightcurve.inversion.validate_request` rejects (unknown method
        or option, an option the method does not use, ``init="none"`` without ``q0``, bad
        1σ, rate bound or particle count), observations without magnitudes, with fewer
        than ``MIN_MEASUREMENTS`` points or non-finite values, relative light curves, a
        shape that cannot be loaded, or the wrong number of shapes for the method.
    """
    start = time.perf_counter()
    request = {
        "q0": q0,
        "omega0": omega0,
        "attitude_sigma_deg": attitude_sigma_deg,
        "omega_sigma": omega_sigma,
        "omega_max": omega_max,
        "particles": particles,
    }
    check_observations(observations)
    resolved = resolve_shapes(shapes)
    options = validate_request(
        method, options, modes=modes, n_shapes=len(resolved), **request, **option_overrides
    )
    model = PhotometricModel(
        observations, resolved, compile=options.compile, faint_margin=options.faint_margin
    )
    attitude_sigma = math.radians(attitude_sigma_deg)
    ctx = Context(
        method=method,
        observations=observations,
        model=model,
        options=options,
        prior=initial_prior(q0, omega0, attitude_sigma, omega_sigma, omega_max),
        attitude_sigma=attitude_sigma,
        omega_sigma=omega_sigma,
        omega_max=float(omega_max),
        particles=int(particles),
        progress=progress,
        rng=np.random.default_rng(seed),
        seed=seed,
        notes=[],
        start=start,
    )
    result = RUNNERS[method](ctx)
    if modes:
        ctx.report(0.95, "attitude modes")
        _attitude_modes(ctx, result)
        result.runtime_s = time.perf_counter() - start
    unknown_state_uncertainty(ctx, result)
    ctx.report(1.0, "done")
    return result


def _attitude_modes(ctx: Context, result: InversionResult) -> None:
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
        batch_problem(ctx.model, ctx.options.estimate_inertia),
        dict.fromkeys(range(ctx.model.n_shapes), starts),
        [ctx.symmetry(s).order for s in range(ctx.model.n_shapes)],
        omega_max=ctx.omega_max,
        offset_sigma_deg=ctx.options.mode_offset_sigma_deg,
        consistency_level=ctx.options.mode_consistency_level,
        weak_sigma_deg=ctx.options.mode_weak_sigma_deg,
        position=obs.object_positions if obs.has_object_position else None,
        velocity=obs.object_velocities if obs.has_object_velocity else None,
        min_epochs=ctx.options.min_epochs,
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
