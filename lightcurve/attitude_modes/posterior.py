"""Posterior intervals of a fitted profile offset by Markov chain Monte Carlo, where the
Laplace approximation does not hold.

The Laplace covariance ``(JᵀJ + P)⁻¹`` describes the ``−2 ln`` posterior only at its
minimum. Glints make that surface rough: a minimum can sit at a kink, sharp on one side
(1σ a few tenths of a degree) and opening into a valley along which ``χ²`` rises by only a
few units over degrees on the other; the Laplace intervals then exclude offsets the data
do not rule out. The three offset angles are therefore sampled from the posterior itself —
the likelihood the fit uses (``exp(−χ²/2)`` of the whitened residuals) times the same prior
— by the affine-invariant ensemble sampler of ``emcee`` (Foreman-Mackey, Hogg, Lang &
Goodman 2013, "emcee: The MCMC Hammer"; Goodman & Weare 2010, "Ensemble samplers with
affine invariance"), its walkers started from the Laplace normal around the fit, the
chain grown until its kept part spans twelve integrated autocorrelation times (or reaches
:data:`MAX_STEPS`; the chain-length advice of emcee's documentation). The
small-angle coordinates ``δ`` carry the Lebesgue measure; the Haar measure of SO(3)
differs from it by ``(2 − 2 cos|δ|)/|δ|²``, 1 % at 20°, and is left out.

From the samples (after the burn-in): equal-tailed 68 % and 95 % intervals of the roll,
pitch and yaw of the offset (3-2-1, as the fitted offsets), and the joint region as a rise
of ``−2 ln`` posterior above the fit (the highest-posterior-density region: an offset is
inside the region of level ``p`` when its ``−2 ln`` posterior exceeds the fit's by at most
the samples' ``p`` quantile of that rise; ``χ²₃(p)`` where the Laplace approximation
holds). ``laplace_ok`` compares the sampled 95 % intervals of the small-angle components
with the Laplace ones ``δ̂ ± 1.96 σ``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import emcee
import numpy as np

from lightcurve.attitude_modes.offsets import OffsetFit, ProfileFit, posterior_cost
from lightcurve.photometry.profiles import euler_offsets_deg

#: Credible levels of the reported intervals and regions.
LEVELS = (0.68, 0.95)
#: Ensemble size and chain length (steps) of the sampler: the walkers cross a glint valley
#: a few degrees long in ~30 steps (integrated autocorrelation time ``τ`` measured on a
#: nadir box-wing night), so 400 kept steps give several hundred independent samples.
#: The chain is extended by :data:`CHUNK` steps while the kept part is shorter than
#: :data:`AUTOCORRELATIONS` ``τ``, up to :data:`MAX_STEPS`; the first third is burn-in.
WALKERS = 32
STEPS = 600
CHUNK = 200
MAX_STEPS = 1200
AUTOCORRELATIONS = 12.0
#: ``laplace_ok`` when each sampled 95 % bound of every small-angle component lies within
#: this fraction of the Laplace half-width ``1.96 σ`` of the Laplace bound (the bounds'
#: Monte Carlo scatter is ~7 % of it with ~400 independent samples).
LAPLACE_TOLERANCE = 0.25
_Z95 = 1.959963984540054


@dataclass
class OffsetPosterior:
    """Sampled posterior of a fitted offset (module doc).

    Attributes
    ----------
    intervals_deg : dict
        Level label (``"68"``, ``"95"``) → ``(3, 2)`` array of ``[lo, hi]`` of roll, pitch
        and yaw (deg, 3-2-1 as the fitted offsets; for ``inertial`` of the attitude from the
        inertial axes), equal-tailed.
    region_rise : dict
        Level label → rise of ``−2 ln`` posterior above the fit's that bounds the joint
        (highest-posterior-density) region of that level.
    laplace_ok : bool
        The sampled 95 % intervals of the small-angle components agree with the Laplace
        ones to :data:`LAPLACE_TOLERANCE` of their half-widths.
    samples : int
        Posterior samples kept (walkers × steps after the burn-in).
    walkers, steps, burn_in : int
        Ensemble size, chain length and the steps discarded.
    acceptance : float
        Mean acceptance fraction of the walkers.
    autocorrelation_steps : float
        Largest integrated autocorrelation time ``τ`` of the three components (steps;
        Goodman & Weare 2010) over the kept steps.
    """

    intervals_deg: dict[str, np.ndarray]
    region_rise: dict[str, float]
    laplace_ok: bool
    samples: int
    walkers: int
    steps: int
    burn_in: int
    acceptance: float
    autocorrelation_steps: float

    def to_dict(self) -> dict[str, Any]:
        return {
            "sampler": "emcee",
            "samples": int(self.samples),
            "walkers": int(self.walkers),
            "steps": int(self.steps),
            "burn_in": int(self.burn_in),
            "acceptance": float(self.acceptance),
            "autocorrelation_steps": float(self.autocorrelation_steps),
            "effective_samples": float(self.effective_samples),
        }

    @property
    def effective_samples(self) -> float:
        """Independent samples, estimated: walkers × kept steps / ``τ``."""
        return self.walkers * (self.steps - self.burn_in) / max(self.autocorrelation_steps, 1.0)


def level_label(level: float) -> str:
    """``"68"`` for 0.68: the key of a credible level in the summaries."""
    return f"{100 * level:g}"


def sample_offset_posterior(
    fit: ProfileFit,
    solution: OffsetFit,
    covariance: np.ndarray,
    *,
    prior_sigma: float | None,
    offset_quaternions: Callable[[np.ndarray], np.ndarray],
    seed: int | np.random.SeedSequence,
    walkers: int = WALKERS,
    steps: int = STEPS,
    max_steps: int = MAX_STEPS,
) -> OffsetPosterior:
    """Sample the posterior of the offset ``δ`` (module doc).

    Parameters
    ----------
    fit : ProfileFit
        Residuals of an offset (any object with ``residuals(δ (..., 3)) → (..., n)``).
    solution : OffsetFit
        The fitted offset (the posterior's maximum found by the fit).
    covariance : (3, 3) numpy.ndarray
        Its Laplace covariance (rad²): the walkers start from this normal around the fit.
    prior_sigma : float or None
        1σ (rad) of the offset's normal prior; None: flat (``|δ| < π``).
    offset_quaternions : callable
        ``δ (..., 3) → (..., 4)`` offset quaternions whose 3-2-1 angles the intervals
        report.
    seed : int or numpy.random.SeedSequence
        Seeds the walkers' start and the sampler's moves.
    walkers : int
        Ensemble size (at least 8).
    steps, max_steps : int
        Shortest and longest chain; the chain grows from ``steps`` by :data:`CHUNK` while
        its kept two thirds are shorter than :data:`AUTOCORRELATIONS` ``τ``.

    Returns
    -------
    OffsetPosterior
    """
    if walkers < 8 or not 3 <= steps <= max_steps:
        raise ValueError(
            f"need walkers >= 8 and 3 <= steps <= max_steps, got {walkers}, {steps}, {max_steps}"
        )
    rng = np.random.default_rng(seed)

    def log_probability(delta: np.ndarray) -> np.ndarray:
        cost = posterior_cost(fit, delta, prior_sigma)
        value = -0.5 * (np.asarray(cost, float) - solution.cost)
        if prior_sigma is None:
            value = np.where(np.linalg.norm(delta, axis=-1) < math.pi, value, -np.inf)
        return np.where(np.isfinite(value), value, -np.inf)

    start = rng.multivariate_normal(solution.delta, covariance, size=walkers)
    sampler = emcee.EnsembleSampler(walkers, 3, log_probability, vectorize=True)
    sampler.random_state = np.random.RandomState(rng.integers(2**32)).get_state()
    state = sampler.run_mcmc(start, steps)
    while True:
        burn_in = sampler.iteration // 3
        chain = sampler.get_chain(discard=burn_in)  # (kept steps, walkers, 3)
        tau = float(np.max(emcee.autocorr.integrated_time(chain, tol=0)))
        if len(chain) >= AUTOCORRELATIONS * tau or sampler.iteration >= max_steps:
            break
        state = sampler.run_mcmc(state, min(CHUNK, max_steps - sampler.iteration))
    delta = chain.reshape(-1, 3)
    rise = -2.0 * sampler.get_log_prob(discard=burn_in, flat=True)
    angles = _unwrapped_deg(
        euler_offsets_deg(offset_quaternions(delta)),
        euler_offsets_deg(offset_quaternions(solution.delta)),
    )
    intervals, regions = {}, {}
    for level in LEVELS:
        tails = [(1.0 - level) / 2.0, (1.0 + level) / 2.0]
        intervals[level_label(level)] = np.quantile(angles, tails, axis=0).T
        regions[level_label(level)] = float(np.quantile(rise, level))
    sigma = np.sqrt(np.clip(np.diag(covariance), 0.0, None))
    bounds = np.quantile(delta, [0.025, 0.975], axis=0)
    laplace = solution.delta + np.outer([-_Z95, _Z95], sigma)
    laplace_ok = bool(np.all(np.abs(bounds - laplace) <= LAPLACE_TOLERANCE * _Z95 * sigma))
    return OffsetPosterior(
        intervals_deg=intervals,
        region_rise=regions,
        laplace_ok=laplace_ok,
        samples=len(delta),
        walkers=walkers,
        steps=sampler.iteration,
        burn_in=burn_in,
        acceptance=float(np.mean(sampler.acceptance_fraction)),
        autocorrelation_steps=tau,
    )


def _unwrapped_deg(angles: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """``angles`` (deg) shifted by whole turns to within ±180° of ``centre``."""
    return centre + (angles - centre + 180.0) % 360.0 - 180.0
