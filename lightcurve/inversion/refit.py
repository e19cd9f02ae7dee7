"""The UKF/MMAE hypotheses refitted on the whole arc with the model adjustments.

The filters of a bank end at states that fit the measurements one at a time; the heaviest
hypotheses of every candidate are refined on the whole arc together with the candidate's
adjustments (:func:`lightcurve.inversion.model_fit.fit_arc`, the adjustments of the option
``estimate``), and the candidates are weighed by the Laplace evidence of their best fits,

``log w_j = −χ²_j/(2c) + ½ log det P_j + log |G_j|``,

``P_j`` the Gauss–Newton covariance, ``|G_j|`` the order of a finite symmetry group (a folded
optimum stands for ``|G_j|`` equivalent ones, as in :func:`lightcurve.inversion.polish.polish`)
and ``c ≥ 1`` the smallest reduced misfit of the candidates: the model error that even the
best candidate leaves is shared by all, and tempering by it keeps the weights from claiming
a certainty that an imperfect model does not give. A candidate fits when its rms model error
(the misfit beyond the measurement errors) is within ``model_tolerance_mag``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from filters.attitude import quaternion_canonical
from filters.global_search import SearchResult
from filters.mmae import MultipleModelBank
from lightcurve.inversion.context import Context
from lightcurve.inversion.model_fit import ArcFit, arc_states, fit_arc, fit_arc_growing
from lightcurve.photometry.adjusted import AdjustableShape

__all__ = ["Refit", "refit_arc"]

#: Hypotheses of the most probable candidate refitted, at most (heaviest first); the other
#: candidates refit their heaviest one (and their best initial fit): their best fits weigh
#: them and test them against the tolerance, the most probable one's gives the state.
MAX_STARTS = 3
#: Initial fits of a candidate continued to the whole arc, at most (best first).
SEARCH_STARTS = 2
#: Hypotheses lighter than this fraction of the heaviest are not refitted.
MIN_RELATIVE_WEIGHT = 1e-3
#: First window (s) of the rescue fit's continuation: short enough that the adjustments
#: and the state settle together before the long windows.
RESCUE_FIRST_WINDOW_S = 60.0
#: The rescue fit continues a start to the next window while its ``χ²`` is within this
#: many standard deviations of the best's (``fit_arc_growing``'s ``band``).
RESCUE_BAND = 3.0


@dataclass
class Refit:
    """The best whole-arc fit of every candidate and their weights.

    Attributes
    ----------
    fits : list of ArcFit or None
        Best fit of every candidate (None for a candidate dropped by the bank).
    adjustables : list of AdjustableShape
    probabilities : (S,) numpy.ndarray
    best : int
        Index of the most probable candidate.
    consistent : (S,) bool numpy.ndarray
        Candidates whose model error is within the tolerance.
    """

    fits: list[ArcFit | None]
    adjustables: list[AdjustableShape]
    probabilities: np.ndarray
    best: int
    consistent: np.ndarray

    @property
    def model_error_mag(self) -> float:
        """rms model error of the most probable candidate (mag)."""
        return self.fits[self.best].model_error_mag

    @property
    def residual_rms(self) -> float:
        """rms residual of the most probable candidate's fit (mag)."""
        return float(np.sqrt(np.mean(self.fits[self.best].residuals ** 2)))

    def table(self, ctx: Context, estimates: pd.DataFrame) -> pd.DataFrame:
        """The per-epoch table with the state, 1σ, prediction and residual of the most
        probable candidate's fitted trajectory (:func:`~lightcurve.inversion.model_fit.arc_states`)
        in place of the filter's; the gate and probability columns stay the filter's."""
        states = arc_states(ctx.model, self.adjustables[self.best], self.fits[self.best])
        out = estimates.copy()
        q = quaternion_canonical(states["q"])
        for i in range(4):
            out[f"q{i + 1}"] = q[:, i]
        for i, axis in enumerate("xyz"):
            out[f"w{axis}"] = states["omega"][:, i]
            out[f"sigma_att_{axis}"] = np.degrees(states["sigma"][:, i])
            out[f"sigma_w{axis}"] = states["sigma"][:, 3 + i]
        out["predicted_mag"] = states["predicted"]
        out["residual"] = ctx.model.magnitudes - states["predicted"]
        return out

    def fields(self, ctx: Context) -> dict[str, Any]:
        """The result fields (:func:`lightcurve.inversion.result.make_result`) of the fit."""
        fit = self.fits[self.best]
        return {
            "name": ctx.names[self.best],
            "probabilities": self.probabilities,
            "none_fits": not bool(self.consistent.any()),
            "q": fit.quaternion,
            "omega": fit.omega,
            "covariance": fit.covariance,
            "parameters": self.adjustables[self.best].describe(fit.theta, fit.covariance[6:, 6:]),
            "group": ctx.symmetry(self.best),
        }


def refit_arc(ctx: Context, bank: MultipleModelBank, found: SearchResult | None = None) -> Refit:
    """Refit the heaviest hypotheses of every live candidate of ``bank`` on the whole arc
    (see the module docstring; ``MAX_STARTS`` of the most probable, one of the others),
    and the best ``SEARCH_STARTS`` initial fits of the most probable (one of the others) in
    ``found`` continued from their window to the whole arc
    (:func:`~lightcurve.inversion.model_fit.fit_arc_growing`): a filter whose model is
    wrong in inertia can lose the state that its initial fit had found."""
    opt = ctx.options
    fits: list[ArcFit | None] = []
    adjustables = []
    for j, name in enumerate(ctx.names):
        adjustable = AdjustableShape(
            ctx.model.shapes[name],
            opt.estimate,
            inertia_sigma=opt.inertia_sigma,
            offset_sigma_mag=opt.offset_sigma_mag,
        )
        adjustables.append(adjustable)
        if name in bank.dropped:
            fits.append(None)
            continue
        members = bank.members[j]
        log_w = bank.log_weights[j]
        order = np.argsort(-log_w, kind="stable")
        keep = order[log_w[order] >= log_w[order[0]] + math.log(MIN_RELATIVE_WEIGHT)]
        leading = j == bank.best
        rows = members.start + keep[: MAX_STARTS if leading else 1]
        candidates = fit_arc(
            ctx.model,
            adjustable,
            bank.ukf.q[rows],
            bank.ukf.omega[rows],
            omega_max=ctx.omega_max,
        )
        if found is not None:
            mine = np.flatnonzero(found.shape == j)[: SEARCH_STARTS if leading else 1]
            window = float(ctx.model.times[found.epochs[-1]] - ctx.model.times[0])
            candidates += fit_arc_growing(
                ctx.model,
                adjustable,
                found.q[mine],
                found.omega[mine],
                window,
                omega_max=ctx.omega_max,
            )
        fits.append(min(candidates, key=lambda f: f.chi2))
    live = [j for j, f in enumerate(fits) if f is not None]
    tolerance = opt.model_tolerance_mag
    if (
        found is not None
        and opt.rescue_starts
        and all(fits[j].model_error_mag > tolerance for j in live)
    ):
        _rescue(ctx, found, live, fits, adjustables)
    tempering = min(fits[j].inflation for j in live)
    log_w = np.full(len(fits), -np.inf)
    for j in live:
        group = ctx.symmetry(j)
        order = math.log(group.order) if group.axis is None else 0.0
        log_w[j] = -0.5 * fits[j].chi2 / tempering + 0.5 * fits[j].log_det + order
    weights = np.exp(log_w - log_w.max())
    probabilities = weights / weights.sum()
    best = int(np.argmax(probabilities))
    consistent = np.array(
        [f is not None and f.model_error_mag <= opt.model_tolerance_mag for f in fits]
    )
    summary = ", ".join(
        f"{name} χ² {f.chi2:.0f}, model error {f.model_error_mag:.3f} mag"
        for name, f in zip(ctx.names, fits, strict=True)
        if f is not None
    )
    ctx.notes.append(
        f"filter hypotheses refitted on the whole arc with the adjustments "
        f"{', '.join(opt.estimate) or 'none'}: {summary}"
    )
    if not consistent.any():
        ctx.notes.append(
            f"no candidate fits within the model tolerance of {opt.model_tolerance_mag:.3f} mag"
        )
    return Refit(fits, adjustables, probabilities, best, consistent)


def _rescue(
    ctx: Context,
    found: SearchResult,
    live: list[int],
    fits: list[ArcFit | None],
    adjustables: list[AdjustableShape],
) -> None:
    """The rescue fit of the candidates ``live`` when none fits: the best
    ``rescue_starts`` initial fits of each continued from :data:`RESCUE_FIRST_WINDOW_S` to
    the whole arc with the adjustments ``rescue_estimate``, the clearly worse ones
    dropped at every window (:data:`RESCUE_BAND`); a fit with a smaller model error
    replaces the candidate's fit (in ``fits``) and adjustable shape (in ``adjustables``).

    Started from the true state, the growing whole-arc fit with every adjustment recovered
    five of nine perturbed library shapes (model error 0.002–0.03 mag) that the library
    model's filters lose, and from starts 10–20° off about half of the time; the search
    ranks its fits with the library's photometry, so the one in the truth's basin is rarely
    its first.
    """
    opt = ctx.options
    ctx.report(0.93, "rescue fit")
    replaced = []
    for j in live:
        starts = np.flatnonzero(found.shape == j)[: opt.rescue_starts]
        if len(starts) == 0:
            continue
        adjustable = AdjustableShape(
            ctx.model.shapes[ctx.names[j]],
            opt.rescue_estimate,
            inertia_sigma=opt.inertia_sigma,
            offset_sigma_mag=opt.offset_sigma_mag,
        )
        grown = fit_arc_growing(
            ctx.model,
            adjustable,
            found.q[starts],
            found.omega[starts],
            RESCUE_FIRST_WINDOW_S,
            omega_max=ctx.omega_max,
            band=RESCUE_BAND,
        )
        if not grown:
            continue
        best = min(grown, key=lambda f: f.chi2)
        if best.model_error_mag < fits[j].model_error_mag:
            replaced.append(
                f"{ctx.names[j]} {fits[j].model_error_mag:.3f} → {best.model_error_mag:.3f}"
            )
            fits[j], adjustables[j] = best, adjustable
    ctx.notes.append(
        f"no candidate fitted: {opt.rescue_starts} initial fits per candidate refitted with "
        f"the adjustments {', '.join(opt.rescue_estimate)}: "
        + (f"model error (mag) {'; '.join(replaced)}" if replaced else "no better fit")
    )
