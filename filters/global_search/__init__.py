"""Global initialisation of attitude, rates (and shape) from a light curve.

A light curve's likelihood over ``(q, ω)`` is a sharp, multi-modal 6-D landscape: a
particle filter started uniform on SO(3) × a rate ball does not find its peak (measured on
a tumbling box-wing: final error ~100° after 40 min with 2·10⁴ particles). What
works is a search over the *initial* state ``x₀ = (q₀, ω₀[, k][, shape])`` at the first
measurement epoch, which determines the whole trajectory under torque-free motion:

1. **Screen** many candidates (uniform attitudes, rates uniform in the ball
   ``|ω| ≤ ω_max``, a shape index per candidate) on a short window of data with one
   batched propagation and one rendering call per shape, ranking them by a robust misfit
   (Student-t negative log-likelihood of the normalised residuals ``r = (m̂ − m)/σ``, so a
   misplaced glint does not dominate). Screening is successive: all candidates on a few
   epochs, the best fraction on more.
2. **Refine** the best few hundred by Levenberg–Marquardt, batched: every candidate's
   residual vector and its Jacobian with respect to ``[η (3, body-frame rotation of the
   initial attitude), ω (3), k (2, optional)]`` come from central differences of the
   measurements in the attitude (six extra predictions for all candidates and epochs at
   once) and an exact attitude sensitivity (see :func:`residual_jacobian`); each candidate
   solves its own damped normal equations ``(JᵀJ + μ diag JᵀJ) Δ = −Jᵀr`` (Marquardt
   1963). The window then grows (continuation) and the surviving candidates are refined
   again, so that the rate estimate improves before the long-arc attitude drift becomes
   non-linear.
3. **Rank** the refined candidates by ``χ² = Σ r²`` on the final window, merge duplicates
   and return them with their Gauss–Newton covariances ``(JᵀJ)⁻¹``, to seed a particle
   filter or a UKF bank.

The problem enters as callables: ``measure(q (N, E, 4), epochs (E,), shape (N,)) →
(N, E)`` predicted measurements (torch; no derivatives needed), the epochs' times, the
measurements and their 1σ errors, and the inertia of each shape.

Modules
-------
- :mod:`~filters.global_search.problem` — The global search's problem and candidate types: the
  batch problem (measurements and the model predicting them from initial states), the Gaussian
  prior on the initial state, batches of candidates and the ranked result.
- :mod:`~filters.global_search.refinement` — Batched Levenberg–Marquardt refinement of candidate
  initial states (Marquardt 1963) with an exact attitude sensitivity, and the refinement of
  their photometric twins.
- :mod:`~filters.global_search.screening` — Candidate initial states and their screening:
  uniform (scrambled Sobol') and prior draws, ranked by a robust misfit on a short window.
- :mod:`~filters.global_search.search` — The global search's driver: screening rounds and
  continuation over growing windows.
- :mod:`~filters.global_search.selection` — Distinct candidates (modulo the shapes' symmetry
  groups) and the refilling of a candidate set around its distinct survivors.
"""

from __future__ import annotations

from filters.global_search.problem import BatchProblem, Candidates, Prior, SearchResult
from filters.global_search.refinement import refine, residual_jacobian
from filters.global_search.screening import (
    low_discrepancy_states,
    prior_candidates,
    screen,
    uniform_candidates,
    uniform_rates,
)
from filters.global_search.search import global_search
from filters.global_search.selection import distinct_states

__all__ = [
    "BatchProblem",
    "Candidates",
    "Prior",
    "SearchResult",
    "distinct_states",
    "global_search",
    "low_discrepancy_states",
    "prior_candidates",
    "refine",
    "residual_jacobian",
    "screen",
    "uniform_candidates",
    "uniform_rates",
]
