"""The global search's driver: screening rounds and continuation over growing windows."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np
import torch

from filters.global_search.problem import (
    BatchProblem,
    Candidates,
    Count,
    Prior,
    SearchResult,
    Twins,
)
from filters.global_search.refinement import (
    _with_twins,
    refine,
)
from filters.global_search.screening import (
    prior_candidates,
    screen,
    uniform_candidates,
)
from filters.global_search.selection import (
    _best_distinct,
    _replenish,
    distinct_states,
)
from filters.symmetry import SymmetryGroup


@dataclass(frozen=True)
class _Schedule:
    """Settings of a screening-and-continuation round (see :func:`global_search`)."""

    n_candidates: int
    omega_max: float
    rate_ball: float
    n_shapes: int
    prior: Prior | None
    screen_duration: float
    windows: tuple[float, ...]
    keep: tuple[int, ...]
    min_epochs: int
    max_rotation: float
    iterations: int
    tolerance: float
    twins: Twins | None
    per_shape: bool
    distinct_angle: float
    distinct_rate: float
    groups: Sequence[SymmetryGroup] | None
    contention: float

    def best_distinct(self, candidates: Candidates, count: Count) -> torch.Tensor:
        """:func:`_best_distinct` with this schedule's settings."""
        return _best_distinct(
            candidates,
            count,
            per_shape=self.per_shape,
            angle=self.distinct_angle,
            rate=self.distinct_rate,
            groups=self.groups,
        )

    def at_rate_scale(self, scale: float) -> _Schedule:
        """This schedule for rates up to ``scale · omega_max`` (``0 < scale ≤ 1``): the
        uniform candidates' rate ball shrinks by ``scale`` and the screening and refinement
        windows stretch by ``1/scale`` (the longest stays the last), so that each window
        spans the same rotation as at the full scale. The measurements per window, the
        rate prior of the fits and the last window are unchanged: the χ² of every scale's
        candidates on the last window compare."""
        if scale == 1.0:
            return self
        longest = self.windows[-1]
        stages = [i for i, w in enumerate(self.windows[:-1]) if w / scale < longest]
        return replace(
            self,
            rate_ball=scale * self.omega_max,
            screen_duration=min(self.screen_duration / scale, longest),
            windows=(*(self.windows[i] / scale for i in stages), longest),
            keep=(*(self.keep[i] for i in stages), self.keep[-1]),
        )


def _contending(
    candidates: Candidates, prior: Prior, n_epochs: int, ratio: float, n_shapes: int
) -> np.ndarray:
    """Shapes whose best data χ² is within ``ratio`` times the best shape's (or times
    ``n_epochs``, if larger), shape (n_shapes,)."""
    data = (candidates.chi2 - (prior.residuals(candidates.q, candidates.omega) ** 2).sum(1)).numpy()
    best = np.full(n_shapes, np.inf)
    np.minimum.at(best, candidates.shape.numpy(), np.nan_to_num(data, nan=np.inf))
    return best <= ratio * max(float(best.min()), n_epochs)


class _Round(NamedTuple):
    """One round's refined candidates (on the last window), that window's epochs, the
    number of candidates screened and the data part of χ²."""

    candidates: Candidates
    epochs: np.ndarray
    screened: int
    chi2_data: torch.Tensor


def global_search(
    problem: BatchProblem,
    *,
    n_candidates: int = 20_000,
    omega_max: float = math.radians(5.0),
    n_shapes: int = 1,
    seed: int | np.random.Generator | None = None,
    prior: Prior | None = None,
    screen_duration: float = 30.0,
    windows: Sequence[float] = (30.0, 90.0, 300.0),
    keep: Sequence[int] = (256, 24, 6),
    min_epochs: int = 90,
    max_rotation: float = math.radians(20.0),
    iterations: int = 15,
    tolerance: float = 0.0,
    twins: Twins | None = None,
    rounds: int = 1,
    rate_scales: Sequence[float] = (1.0,),
    good_fit: float = 2.0,
    min_improvement: float = 0.0,
    per_shape: bool = False,
    distinct_angle: float = math.radians(3.0),
    distinct_rate: float = math.radians(0.05),
    groups: Sequence[SymmetryGroup] | None = None,
    contention: float = math.inf,
    progress: Callable[[str], None] | None = None,
) -> SearchResult:
    """Screen initial states, refine the best by batched LM with continuation.

    Parameters
    ----------
    problem : BatchProblem
    n_candidates : int
        Candidates screened per round (per shape with a prior).
    omega_max : float
        Radius of the rate ball (rad/s) of uniform candidates.
    n_shapes : int
        Shape indices ``[0, n_shapes)`` searched.
    seed : int or numpy.random.Generator, optional
    prior : Prior, optional
        Draw the candidates from this Gaussian prior (for every shape) instead of
        uniformly, and refine maximum a posteriori. Without it the refinement still
        carries a weak rate prior ``N(0, omega_max²)`` (no attitude term), which bounds
        the rates along unobserved directions (the spin about a symmetry axis).
    screen_duration : float
        Window of the screening (s). Short enough that a candidate's rate error does not
        turn into a large attitude error within it.
    windows : sequence of float
        Growing refinement windows (s); the last one is the window of the returned χ².
    keep : sequence of int
        Candidates refined on each window (the best of the previous stage).
    min_epochs : int
        Measurements used per window (spread evenly over it), unless ``max_rotation``
        asks for more.
    max_rotation : float
        Longest rotation (rad) at ``omega_max`` between a window's measurements: a long
        window sampled by ``min_epochs`` measurements aliases a fast rotator's light curve
        (at 4°/s, 90 measurements over 1200 s are 53° apart, and states that fit them
        at χ²/E = 0.86 fit the whole arc at 1.29 while the truth fits it at 0.95), so it
        gets ``⌈duration · omega_max / max_rotation⌉`` measurements instead.
    iterations : int
        LM iterations per window.
    tolerance : float
        Screening tolerance (see :func:`screen`).
    twins : callable, optional
        ``twins(q, ω, shape) → [(q', ω', has_twin), …]``, one triple per kind of twin:
        states that fit short arcs as well as the given ones (the reciprocity twin of any
        shape, :func:`lightcurve.sky.geometry.reciprocity_twin`; the mirror twin of a
        mirror-symmetric one, :meth:`filters.symmetry.SymmetryGroup.mirror_twin`). At the
        first window after which ``keep`` drops fourfold or more, the twins of the
        survivors are refined too, so every member of an ambiguous set reaches the longer
        windows, where the data can tell them apart.
    rounds : int
        Further rounds with fresh candidates are run, up to this many in total, while the
        best fit is poor: ``χ²/E > good_fit`` on the final window of ``E`` measurements.
    rate_scales : sequence of float
        Every round searches each of these scales ``s`` (``0 < s ≤ 1``) of the rate ball
        in turn: candidates with rates up to ``s · omega_max``, screened and refined on
        windows stretched by ``1/s`` (up to the last window; see
        :meth:`_Schedule.at_rate_scale`). What a window tells about the state grows with
        the rotation it spans: over a 30 s screening window a rotator at a sixth of
        ``omega_max`` turns 24° and many states far from it fit as well as its own. On a
        20-min Itokawa light curve at 0.80°/s (``omega_max`` 5°/s, 0.05 mag noise) the
        states refined from the full ball fitted every window up to 342 s as well as the
        truth's own fit, none within 15° of the truth, and the search ended 155° off
        (χ² 351 against the truth's 327 on 300 measurements); the scale 0.25 (windows from
        120 s) found the truth's optimum, 0.6° off. The default searches the full ball
        only.
    good_fit : float
        ``χ²`` per measurement (measurement errors included, prior rows not counted) below
        which the search stops.
    min_improvement : float
        The search also stops when a further round lowers the best data ``χ²`` by less
        than this fraction: two rounds of fresh candidates that agree on a poor fit point
        to the model, not to the search (a shape outside a bank).
    per_shape : bool
        Every stage keeps its count of candidates for each shape (a multiple-model bank
        needs a fit for every candidate shape) instead of the best overall.
    distinct_angle, distinct_rate : float
        Candidates closer than this (rad; inertial rates, rad/s) to a better one are
        duplicates.
    groups : sequence of SymmetryGroup, optional
        Rotational symmetry group of each shape index: symmetry-equivalent candidates are
        duplicates (:func:`distinct_states`).
    contention : float
        With ``per_shape``: a shape whose best data ``χ²`` on a window exceeds this times
        the best shape's (or times the window's ``E`` measurements, if larger) is out of
        contention for the rest of the round: it goes on with ``keep[-1]`` candidates and
        no twins, enough to give a bank its fits while the shapes that can fit the data
        get the effort. On the rocket body's 10-min light curve of the README main job,
        three of six shapes are out after the 30 s window (best χ² 1.2·10⁴–7·10⁴ against
        21 on 30 measurements) and five after the 120 s window (1.2·10⁴ and more against
        79 on 90). ``inf`` (the default) keeps every shape in.
    progress : callable, optional
        Receives a short message after each stage.

    Returns
    -------
    SearchResult
        Distinct candidates of all rounds, best first.

    Raises
    ------
    ValueError
        ``rate_scales`` empty or a scale outside ``(0, 1]``.
    """
    if not (rate_scales and all(0.0 < s <= 1.0 for s in rate_scales)):
        raise ValueError(f"rate_scales must be in (0, 1], got {tuple(rate_scales)!r}")
    rng = np.random.default_rng(seed)
    schedule = _Schedule(
        n_candidates=n_candidates,
        omega_max=omega_max,
        rate_ball=omega_max,
        n_shapes=n_shapes,
        prior=prior,
        screen_duration=screen_duration,
        windows=tuple(windows),
        keep=tuple(keep),
        min_epochs=min_epochs,
        max_rotation=max_rotation,
        iterations=iterations,
        tolerance=tolerance,
        twins=twins,
        per_shape=per_shape,
        distinct_angle=distinct_angle,
        distinct_rate=distinct_rate,
        groups=groups,
        contention=contention,
    )
    found: list[Candidates] = []
    screened = 0
    best_data = math.inf
    for round_ in range(rounds):
        previous = best_data
        for scale in rate_scales:
            part = _search_round(problem, schedule.at_rate_scale(scale), rng, progress)
            found.append(part.candidates)
            screened += part.screened
            best_data = min(best_data, float(part.chi2_data.min()))
        if progress:
            progress(
                f"round {round_ + 1}: best χ² {best_data:.1f} on {len(part.epochs)} measurements"
            )
        if (
            best_data <= good_fit * len(part.epochs)
            or best_data > (1.0 - min_improvement) * previous
        ):
            break
    every = Candidates.concat(found)
    order = torch.argsort(every.chi2, stable=True).numpy()
    kept = order[
        distinct_states(
            every.q.detach().numpy()[order],
            every.omega.detach().numpy()[order],
            every.shape.numpy()[order],
            distinct_angle,
            distinct_rate,
            groups,
        )
    ]
    return SearchResult(
        q=every.q.detach().numpy()[kept],
        omega=every.omega.detach().numpy()[kept],
        k=None if every.k is None else every.k.detach().numpy()[kept],
        shape=every.shape.numpy()[kept],
        chi2=every.chi2.detach().numpy()[kept],
        covariance=every.covariance.detach().numpy()[kept],
        epochs=part.epochs,
        screened=screened,
    )


def _search_round(
    problem: BatchProblem,
    schedule: _Schedule,
    rng: np.random.Generator,
    progress: Callable[[str], None] | None,
) -> _Round:
    """One screening and continuation pass over the schedule's windows."""
    prior, keep, omega_max = schedule.prior, schedule.keep, schedule.omega_max
    if prior is None:
        candidates = uniform_candidates(
            problem, schedule.n_candidates, schedule.rate_ball, rng, schedule.n_shapes
        )
        fit_prior = Prior.rates_only(omega_max)
    else:
        candidates = prior_candidates(
            problem, schedule.n_candidates, prior, rng, range(schedule.n_shapes)
        )
        fit_prior = prior
    screened = len(candidates)
    candidates = screen(
        problem,
        candidates,
        schedule.screen_duration,
        keep[0],
        prior=prior,
        tolerance=schedule.tolerance,
        per_shape=schedule.per_shape,
    )
    if progress:
        progress(f"screened {screened} candidates")
    epochs = np.zeros(0, dtype=int)
    # Shapes in contention, and each one's multiple of the counts (1 + its kinds of twins).
    contending = np.ones(schedule.n_shapes, dtype=bool)
    factor = np.ones(schedule.n_shapes, dtype=int)
    # 1σ caps of the draws that refill the candidate set: the prior's, or 30° and a
    # tenth of the rate ball (and 0.5 in k).
    sigma_att = prior.attitude_sigma if prior is not None else math.radians(30.0)
    sigma_rate = prior.omega_sigma if prior is not None else 0.1 * schedule.rate_ball
    cap = np.concatenate(
        [np.full(3, sigma_att), np.broadcast_to(sigma_rate, (3,)), np.full(2, 0.5)]
    )[: problem.n_params]

    def counts(count: int) -> Count:
        """Candidates per shape (or overall) going on with ``count`` per contender."""
        if not schedule.per_shape:
            return int(factor[0]) * count
        return np.where(contending, factor * count, min(count, keep[-1]))

    # Twins join where the candidate count is first cut hard (fourfold or more): the
    # windows before it do not yet tell the many candidates apart.
    cuts = [i for i in range(len(keep) - 1) if 4 * keep[i + 1] <= keep[i]]
    twin_stage = cuts[0] if cuts else 0
    for stage, (duration, count) in enumerate(zip(schedule.windows, keep, strict=True)):
        if candidates.chi2 is not None:
            best = schedule.best_distinct(candidates, counts(count))
            candidates = _replenish(
                candidates.take(best),
                counts(count),
                per_shape=schedule.per_shape,
                cap=cap,
                rng=rng,
            )
        rotation_epochs = math.ceil(duration * omega_max / schedule.max_rotation)
        epochs = problem.window(duration, max(schedule.min_epochs, rotation_epochs))
        candidates = refine(
            problem, candidates, epochs, iterations=schedule.iterations, prior=fit_prior
        )
        if schedule.per_shape:
            contending &= _contending(
                candidates, fit_prior, len(epochs), schedule.contention, schedule.n_shapes
            )
        if stage == twin_stage and schedule.twins is not None and len(keep) > 1:
            # Twins of the contenders' candidates that go on, refined on the same window.
            chosen = candidates.take(schedule.best_distinct(candidates, counts(keep[stage + 1])))
            twinned = torch.as_tensor(contending[chosen.shape.numpy()])
            with_twins, kinds = _with_twins(
                problem,
                schedule.twins,
                chosen.take(twinned),
                epochs,
                iterations=schedule.iterations,
                prior=fit_prior,
            )
            candidates = Candidates.concat([with_twins, chosen.take(~twinned)])
            factor = np.where(contending, kinds, 1)
        if progress:
            progress(
                f"refined {len(candidates)} candidates on {duration:.0f} s, "
                f"best χ² {candidates.chi2.min():.1f}"
            )
    # The stopping test looks at the data part of χ² only.
    chi2_data = candidates.chi2 - (fit_prior.residuals(candidates.q, candidates.omega) ** 2).sum(
        dim=1
    )
    return _Round(candidates, epochs, screened, chi2_data)
