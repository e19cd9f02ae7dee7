"""The initial-state search of an inversion (:func:`filters.global_search.global_search`
on the photometric model), with the photometric twins of its candidates.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from filters.global_search import (
    SearchResult,
    global_search,
)
from lightcurve.inversion.context import Context
from lightcurve.inversion.options import FILTER_REFINE_KEEP, PF_REFINE_KEEP
from lightcurve.sky.geometry import reciprocity_twin


def initial_search(
    ctx: Context, *, candidates: int, keep_last: int, per_shape: bool = False, for_pf: bool = False
) -> SearchResult:
    """Initial-state search of every candidate shape on the first window (around
    ``ctx.prior``, or uniform without it); the PF's search runs on longer windows
    (``pf_window_s``, see :class:`~lightcurve.inversion.InversionOptions`).

    Parameters
    ----------
    ctx : Context
    candidates : int
        Candidates screened per round.
    keep_last : int
        Candidates kept on the last window, at least.
    per_shape : bool
        Keep the counts for every shape (a bank needs fits of every shape; the PF gives
        every shape the search it would get alone), with the ``search_contention`` rule.
    for_pf : bool
        The PF's schedule: windows growing ``pf_window_growth``-fold up to ``pf_window_s``,
        every search round run while the fit is poor and, without a prior, each round run
        at every scale of the rate ball in ``pf_rate_scales``.
    """
    opt = ctx.options
    span = float(ctx.model.times[-1] - ctx.model.times[0])
    if for_pf:
        windows = ctx.windows(min(opt.pf_window_s, span), opt.pf_window_growth)
        return _search(ctx, windows, candidates, keep_last, per_shape, for_pf)
    longest = min(opt.init_window_s, 0.5 * span)
    found = _search(ctx, ctx.windows(longest), candidates, keep_last, per_shape, for_pf)
    needed = turn_window(found, math.radians(opt.search_turn_deg))
    if ctx.prior is None and needed > 1.05 * longest and longest < 0.5 * span:
        longest = min(needed, 0.5 * span)
        ctx.notes.append(
            f"the best initial fits turn less than {opt.search_turn_deg:.0f}° in "
            f"{opt.init_window_s:.0f} s: searched again on windows up to {longest:.0f} s"
        )
        found = _search(ctx, ctx.windows(longest), candidates, keep_last, per_shape, for_pf)
    return found


def turn_window(found: SearchResult, turn: float, ratio: float = 2.0) -> float:
    """The window (s) over which the slowest of the plausible initial fits of ``found``
    (data χ² within ``ratio`` times the best) turns by ``turn`` (rad); 0 for ``turn`` 0.

    A window shorter than a turn of the object leaves many states that fit it equally well
    (on a box-wing tumbling at 0.31 °/s, the eight best fits of a 300 s window were within
    Δχ² = 1 of each other on 90 measurements, none within 20° and 0.2 °/s of the truth; on
    1 200 s the truth's fit led by Δχ² = 14).
    """
    if turn <= 0.0 or len(found.chi2) == 0:
        return 0.0
    plausible = found.chi2 <= ratio * max(float(found.chi2.min()), 1.0)
    rate = float(np.min(np.linalg.norm(found.omega[plausible], axis=1)))
    return math.inf if rate <= 0.0 else turn / rate


def _search(
    ctx: Context,
    windows: tuple[float, ...],
    candidates: int,
    keep_last: int,
    per_shape: bool,
    for_pf: bool,
) -> SearchResult:
    """:func:`filters.global_search.global_search` on ``windows`` (see :func:`initial_search`)."""
    opt = ctx.options
    prior = ctx.prior
    shapes = range(ctx.model.n_shapes)
    counts = opt.refine_keep or (PF_REFINE_KEEP if for_pf else FILTER_REFINE_KEEP)
    # First window: counts[0]; last: counts[-1]; windows between: the counts between.
    keep = [counts[min(i, len(counts) - 2)] for i in range(len(windows) - 1)] + [counts[-1]]
    keep[-1] = max(keep[-1], keep_last)
    keep = [max(k, keep[-1]) for k in keep]
    return global_search(
        ctx.problem(),
        n_candidates=candidates,
        omega_max=ctx.omega_max,
        n_shapes=len(shapes),
        seed=ctx.rng,
        prior=prior,
        screen_duration=windows[0],
        windows=windows,
        keep=keep,
        min_epochs=ctx.options.min_epochs,
        max_rotation=math.radians(ctx.options.max_sample_rotation_deg),
        tolerance=ctx.options.search_tolerance,
        twins=_twin_function(ctx, shapes, reciprocity=prior is None),
        groups=[ctx.symmetry(s) for s in shapes],
        rounds=ctx.options.search_rounds,
        rate_scales=opt.pf_rate_scales if for_pf and prior is None else (1.0,),
        min_improvement=0.0 if for_pf else ctx.options.search_min_improvement,
        per_shape=per_shape,
        contention=ctx.options.search_contention,
        progress=lambda message: ctx.report(0.0, message),
    )


def _twin_function(ctx: Context, shapes: Sequence[int], reciprocity: bool) -> Callable | None:
    """The photometric twins of search candidates, at the first epoch's geometry: mirror
    twins for the shapes that have them and, with ``reciprocity``, the reciprocity twin
    (:func:`lightcurve.sky.geometry.reciprocity_twin`) of every candidate and of its mirror
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
