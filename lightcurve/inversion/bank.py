"""The UKF and MMAE estimators: a USQUE filter per candidate shape, started at the search's
distinct fits (multiple-hypothesis UKF) or at the prior, run as a multiple-model bank.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from filters.attitude import (
    tanh_from_inertia,
)
from filters.global_search import (
    SearchResult,
)
from filters.mmae import MultipleModelBank
from filters.ukf import AttitudeUKF, ProcessNoise, default_gate, torque_free_dynamics
from lightcurve.inversion.context import Context, capped, subset, symmetry_note
from lightcurve.inversion.epochs import EpochEstimate, filter_epochs
from lightcurve.inversion.refit import refit_arc
from lightcurve.inversion.result import InversionResult, make_result
from lightcurve.inversion.search import initial_search


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
    ctx: Context, s: int, prior_covariance: np.ndarray, found: SearchResult | None
) -> _UKFSetup:
    """The USQUE filter of shape ``s``: one member per distinct initial fit of the shape
    in ``found``, or one member at the prior (``found`` None)."""
    opt = ctx.options
    prior = ctx.prior
    name = ctx.names[s]
    shape = ctx.model.shapes[name]
    attitude_cap = math.sqrt(prior_covariance[0, 0]) if prior is not None else math.radians(5.0)
    omega_cap = math.sqrt(prior_covariance[3, 3]) if prior is not None else math.radians(0.05)
    params: list[float] = []
    variances: list[float] = []
    k_index = offset_index = None
    if opt.estimate_inertia:
        k_index = (0, 1)
        params += list(tanh_from_inertia(np.diag(shape.principal_moments), margin=1e-6))
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
        found = subset(found, found.shape == s)
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
        covariance[:, :m, :m] = capped(found.covariance[:h], cap)
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


def run_bank(ctx: Context) -> InversionResult:
    """The ``"ukf"`` and ``"mmae"`` methods: initial search per shape (unless
    ``init="none"``), then the bank of multiple-hypothesis UKFs over every measurement."""
    opt = ctx.options
    model = ctx.model
    prior = ctx.prior
    prior_covariance = np.diag(
        [ctx.attitude_sigma**2] * 3 + list(np.broadcast_to(np.asarray(ctx.omega_sigma) ** 2, (3,)))
    )
    found = None
    searched = opt.init == "search" or prior is None
    if searched:
        ctx.report(0.0, "initial fit")
        n = opt.local_candidates if prior is not None else opt.global_candidates * model.n_shapes
        found = initial_search(ctx, candidates=n, keep_last=opt.hypotheses, per_shape=True)
        missing = [ctx.names[s] for s in range(model.n_shapes) if not (found.shape == s).any()]
        if missing:
            raise RuntimeError(f"the initial search kept no candidate of {', '.join(missing)}")
    setups = [_ukf_for_shape(ctx, s, prior_covariance, found) for s in range(model.n_shapes)]
    bank = MultipleModelBank(
        [st.ukf for st in setups],
        ctx.names,
        log_prior=[st.log_prior for st in setups],
        floor=opt.probability_floor if model.n_shapes > 1 else 0.0,
        window=opt.consistency_window,
        level=opt.consistency_level,
        adaptive=opt.adaptive_noise,
    )
    times, z, r = model.times, model.magnitudes, model.errors**2
    fit_end = max(st.fit_end for st in setups)
    gated_count = 0
    dropped_at: dict[str, float] = {}  # model → time (s) its last hypothesis diverged

    def update(k: int) -> EpochEstimate:
        nonlocal gated_count
        if times[k] > fit_end:
            res = bank.update(z[k], r[k], [st.hx(k) for st in setups])[bank.best]
            gated = bool(res.gated[0])
        else:  # fitted by the search: only the table's prediction is needed
            res = bank.evaluate(z[k], r[k], setups[bank.best].hx(k), bank.best)
            gated = False
        gated_count += gated
        for dropped in bank.dropped.keys() - dropped_at.keys():
            dropped_at[dropped] = float(times[k])
        q, omega, cov = bank.fused()
        return EpochEstimate(q, omega, cov, float(res.predicted[0]), gated, bank.probabilities)

    estimates = filter_epochs(ctx, predict=bank.predict, update=update)
    q, omega, cov = bank.fused()
    best = bank.best
    name = ctx.names[best]
    group = ctx.symmetry(best)
    note = symmetry_note(name, group)
    if note:
        ctx.notes.append(note)
    rejected = gated_count / len(times)
    if gated_count:
        ctx.notes.append(
            f"{gated_count} measurement(s) ({100 * rejected:.1f} %) rejected by the innovation gate"
        )
    if opt.adaptive_noise:
        ctx.notes.append(
            "model error estimated by the filters (rms, mag): "
            + ", ".join(f"{m} {e:.3f}" for m, e in zip(ctx.names, bank.model_error, strict=True))
        )
    for j, name_j in enumerate(ctx.names):
        lost = int(bank.ukf.diverged[bank.members[j]].sum())
        if name_j in bank.dropped:
            ctx.notes.append(
                f"{name_j}: every filter hypothesis diverged ({bank.dropped[name_j]}) by "
                f"t = {dropped_at[name_j]:.0f} s; dropped from the bank (probability 0)"
            )
        elif lost:
            ctx.notes.append(
                f"{name_j}: filter hypotheses diverged and dropped (weight 0): {lost} of "
                f"{bank.hypotheses(j)}"
            )
    if bank.all_diverged:
        ctx.notes.append(
            "every candidate's filter diverged: the estimate is the last finite state of the "
            "most probable one, and no candidate is taken to fit"
        )
    if searched:
        ctx.notes.append(f"initial state fitted on the first {setups[best].fit_end:.0f} s of data")
    if bank.none_fits and not bank.all_diverged:
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
    sigma = np.sqrt(np.clip(np.diag(bank.estimate(best)[2])[6:], 0.0, None))
    if st.k_index is not None:
        for i, key in enumerate(("k1", "k2")):
            parameters[key] = {"value": float(theta[i]), "sigma": float(sigma[i])}
    if st.offset_index is not None:
        i = st.offset_index
        parameters["magnitude_offset"] = {"value": float(theta[i]), "sigma": float(sigma[i])}
    if bank.hypotheses(best) > 1:
        weights = np.exp(bank.log_weights[best])
        ctx.notes.append(
            f"{name}: heaviest of {len(st.ukf)} hypotheses carries {weights.max():.3f}"
        )
    result_fields = {
        "name": name,
        "probabilities": bank.probabilities,
        "none_fits": bank.none_fits,
        "q": q,
        "omega": omega,
        "covariance": cov,
        "parameters": parameters,
        "group": group,
    }
    model_error = float(bank.model_error[best])
    residual_rms = None
    if opt.polish:
        ctx.report(0.9, "whole-arc fit")
        refit = refit_arc(ctx, bank, found)
        result_fields.update(refit.fields(ctx))
        estimates = refit.table(ctx, estimates)
        model_error, residual_rms = refit.model_error_mag, refit.residual_rms
    result = make_result(ctx, estimates=estimates, **result_fields)
    result.rejected_fraction = rejected
    result.model_error_mag = model_error
    if residual_rms is not None:
        result.residual_rms_mag = residual_rms
    return result
