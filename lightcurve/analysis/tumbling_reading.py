"""Reading a tumbler's frequency pair as precession and rotation periods with a convex
facet model under torque-free motion.

The two-period series (:mod:`lightcurve.analysis.tumbling`) finds a lattice of
combination frequencies; several of its bases, in either mode, are torque-free readings
``(f_φ, f_ψ, mode)`` of the same light curve (:func:`reading_hypotheses`). Each reading
fixes the two periods, and the light curve of a convex body under the reading's motion is
fitted by non-negative facet areas over a fixed grid of normals (the extended Gaussian
image; Kaasalainen & Torppa 2001, Icarus 153, 24, eq. 1) ::

    F_e = Σ_n a_n ρ(n, s_e, o_e) max(0, n·s_e) max(0, n·o_e),   a_n ≥ 0,

with ``s_e``, ``o_e`` the Sun and observer directions in the body frame at epoch e and ρ
the convex-inversion scattering law, Lommel–Seeliger plus ``c = 0.1`` times Lambert, no
phase function (:mod:`brdf.lommel_seeliger`; Kaasalainen & Torppa 2001, sec. 2). A convex
body's brightness is reproduced exactly by such areas (closed: ``Σ a_n n = 0``), and
non-negativity makes the fit far more selective than a series truncated in degree. The
areas are the variable projection of the motion
(:func:`~lightcurve.analysis.egi.fit.egi_residuals`; Golub & Pereyra 1973, SIAM J. Numer.
Anal. 10, 413), so only the motion is searched.

The body's attitude is ``A(t) = M(f_ψ t + τ₀) R``: ``M`` the scale-free torque-free motion
in the frame of the angular momentum ``L`` (:func:`~filters.attitude.torque_free_motion.
attitude_about_momentum`), ``τ₀`` the origin of the rotation (in rotation periods) and
``R`` the constant inertial → ``L``-frame rotation (the direction of ``L`` and the initial
precession angle). The body-side rotation of the principal axes against the shape is
absorbed by the free areas. The scale-free motion has principal moments ``A ≤ B ≤ C = 1``
and ``d = L²/(2E)``, with ``d`` solved for the reading's ratio ``P_φ/P_ψ``
(:func:`motions_with_ratio`, over a lattice of moments), so a reading's free parameters are
the moments along that curve, ``τ₀`` and ``R``.

The search per reading (:func:`reading_chi2`): random trials (a motion of the lattice, τ₀
uniform, R uniform) scored on a grid of normals at thinned epochs; the best few refined in
``R``, ``τ₀`` and the moments (``d`` re-solved) by trust-region least squares on the same
grid, the periods held. Readings have the same parameter count, so their least χ²
compare directly (:func:`convex_reading`). The decision (:func:`decide_reading`): every
reading in a quick pass (:data:`QUICK_TRIALS` trials on :data:`QUICK_NORMALS` normals and
:data:`QUICK_EPOCHS` epochs, the best :data:`QUICK_REFINED` refined), the
:data:`FINALISTS` lowest refined again on :data:`SCREEN_NORMALS` normals and
:data:`SCREEN_EPOCHS` epochs; the two lowest are told apart when their Δχ², over the best's
χ² per epoch when above 1, reaches :data:`AMBIGUOUS_DELTA_CHI2`.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from scipy.optimize import brentq, least_squares

import brdf
from filters.attitude import (
    attitude_matrix,
    random_quaternion,
    rotation_vector_to_quaternion,
)
from filters.attitude.torque_free_motion import (
    ScaledMotion,
    attitude_about_momentum,
    period_ratio,
    scaled_motion,
)
from lightcurve.analysis.egi.profile import EGIProfile
from lightcurve.io.observations import Observations

__all__ = [
    "AMBIGUOUS_DELTA_CHI2",
    "CONVEX_LAW",
    "MAX_MOMENT_RATIO",
    "ConvexDecision",
    "Reading",
    "ReadingFit",
    "convex_reading",
    "decide_reading",
    "motions_with_ratio",
    "reading_chi2",
    "reading_hypotheses",
]

#: Largest ratio C/A of the principal moments of a reading (a LAM's ``f_ψ/f_φ`` bound).
MAX_MOMENT_RATIO = 8.0
#: The convex-inversion scattering law (Lommel–Seeliger + 0.1 Lambert, phase function 1).
CONVEX_LAW = brdf.get("lommel-seeliger", w=4 * math.pi, c=0.1, a=0.0, d=0.1, k=0.0)
#: Normals and epochs of the profile, random trials per reading and trials refined.
SCREEN_NORMALS = 150
SCREEN_EPOCHS = 300
SCREEN_TRIALS = 300
REFINED = 3
#: Evaluations of one refinement at most (besides its finite-difference Jacobians).
REFINE_STEPS = 15
#: The quick pass over every reading: normals, epochs, random trials; the lowest readings'
#: best fits then refined on the full profile, in at most ``FINAL_STEPS`` evaluations.
QUICK_NORMALS = 100
QUICK_EPOCHS = 150
QUICK_TRIALS = 100
QUICK_REFINED = 2
FINALISTS = 3
FINAL_STEPS = 20
#: Δχ² (over the reduced χ²) below which the two lowest readings are not told apart.
AMBIGUOUS_DELTA_CHI2 = 9.0
#: Moment lattice per axis and trial values of ``d`` across a mode's interval.
MOMENT_GRID = 6
_ENERGY_STEPS = 60


class Reading(NamedTuple):
    """A torque-free reading of a frequency pair ``(f₁, f₂)``.

    Attributes
    ----------
    f_phi, f_psi : float
        Precession and rotation frequencies (the pair's unit).
    mode : str
        ``"SAM"`` or ``"LAM"``.
    basis : (2, 2) int
        ``(f_φ, f_ψ) = basis @ (f₁, f₂)``.
    """

    f_phi: float
    f_psi: float
    mode: str
    basis: np.ndarray


def reading_hypotheses(
    pair: Sequence[float], max_moment_ratio: float = MAX_MOMENT_RATIO
) -> list[Reading]:
    """The torque-free readings of a frequency pair.

    Every basis ``T (f₁, f₂)`` of the pair's lattice (entries of T in {−1, 0, 1},
    ``|det T| = 1``, both frequencies positive) in SAM and in LAM, and the twin of each
    (the same spin about ``L`` — ``f_φ − f_ψ`` in a SAM, ``f_φ + f_ψ`` in a LAM — and the
    same other frequency read in the other mode), kept when the torque-free period ratio
    allows it: ``f_ψ/f_φ < 1/2`` in a SAM, ``< C/A − 1`` in a LAM with ``C/A ≤
    max_moment_ratio``.

    Parameters
    ----------
    pair : (2,) float
        Two frequencies (any unit).
    max_moment_ratio : float

    Returns
    -------
    list of Reading
        Distinct readings, in the enumeration's order.
    """
    pair = np.asarray(pair, float)
    # The twins of (f_φ, f_ψ): a LAM (f_ψ, f_φ − 2 f_ψ) and a SAM (2 f_φ + f_ψ, f_φ).
    to_lam, to_sam = np.array([[0, 1], [1, -2]]), np.array([[2, 1], [1, 0]])
    candidates = []
    for entries in itertools.product((0, 1, -1), repeat=4):
        basis = np.array(entries).reshape(2, 2)
        if abs(round(np.linalg.det(basis))) == 1:
            candidates += [
                (basis, "SAM"),
                (basis, "LAM"),
                (to_lam @ basis, "LAM"),
                (to_sam @ basis, "SAM"),
            ]
    readings: list[Reading] = []
    for basis, mode in candidates:
        f_phi, f_psi = basis @ pair
        bound = 0.5 if mode == "SAM" else max_moment_ratio - 1.0
        if (
            min(f_phi, f_psi) > 0
            and f_psi / f_phi < bound
            and not any(
                np.allclose((f_phi, f_psi), r[:2], rtol=1e-9) and mode == r.mode for r in readings
            )
        ):
            readings.append(Reading(float(f_phi), float(f_psi), mode, basis))
    return readings


def motions_with_ratio(
    ratio: float, mode: str, grid: int = MOMENT_GRID, max_moment_ratio: float = MAX_MOMENT_RATIO
) -> list[ScaledMotion]:
    """Scale-free motions in ``mode`` whose ``P_φ/P_ψ`` is ``ratio``: moments
    (:func:`_moments`) on a ``grid × grid`` lattice of ``(a, share)``, every root ``d``
    of the ratio.

    Parameters
    ----------
    ratio : float
        ``P_φ/P_ψ = f_ψ/f_φ``.
    mode : str
        ``"SAM"`` or ``"LAM"``.
    grid : int
    max_moment_ratio : float

    Returns
    -------
    list of ScaledMotion
        Empty when no body of the lattice has this ratio in this mode.
    """
    low, high = _lattice_bounds(max_moment_ratio)
    motions = []
    for a in np.linspace(low[0], high[0], grid):
        for share in np.linspace(low[1], high[1], grid):
            moments = _moments(a, share)
            if moments[0] + moments[1] >= 1.0:
                motions += [
                    scaled_motion(moments, d, mode) for d in _energy_roots(moments, ratio, mode)
                ]
    return motions


def _moments(a: float, share: float) -> np.ndarray:
    """Scale-free principal moments ``(A, B, 1)`` with ``A = a``, ``B = a + share (1 − a)``."""
    return np.array([a, a + share * (1.0 - a), 1.0])


def _lattice_bounds(max_moment_ratio: float) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of ``(a, share)``: ``A ≥ 1/max_moment_ratio`` and away from the symmetric
    tops."""
    return np.array([1.0 / max_moment_ratio + 0.02, 0.05]), np.array([0.97, 0.95])


def _energy_roots(moments: np.ndarray, ratio: float, mode: str) -> list[float]:
    """Every ``d = L²/(2E)`` of ``moments`` in ``mode`` whose period ratio is ``ratio``."""
    low, high = (moments[1], 1.0) if mode == "SAM" else (moments[0], moments[1])
    d = low + (high - low) * np.linspace(0.01, 0.99, _ENERGY_STEPS)
    excess = period_ratio(np.broadcast_to(moments, (len(d), 3)), d, mode) - ratio
    return [
        brentq(
            lambda x: float(period_ratio(moments, np.array(x), mode)) - ratio,
            d[i],
            d[i + 1],
            xtol=1e-14,
            rtol=1e-13,
        )
        for i in np.nonzero(np.diff(np.sign(excess)) != 0)[0]
    ]


def _moved(motion: ScaledMotion, a: float, share: float, ratio: float) -> ScaledMotion:
    """The motion of moments ``(a, share)`` with the same ratio whose ``d`` is nearest
    ``motion``'s (``motion`` itself when there is none)."""
    moments = _moments(a, share)
    if moments[0] + moments[1] < 1.0:
        return motion
    roots = _energy_roots(moments, ratio, motion.mode)
    if not roots:
        return motion
    d = min(roots, key=lambda root: abs(root - motion.d))
    return scaled_motion(moments, d, motion.mode)


@dataclass(frozen=True)
class ReadingFit:
    """The best convex fit of one reading.

    Attributes
    ----------
    reading : Reading
        Frequencies in Hz.
    chi2 : float
        Least profile χ² found.
    motion : ScaledMotion or None
        Its scale-free motion (None when no motion of the lattice has the ratio).
    origin : float
        ``τ₀`` (rotation periods).
    frame : (3, 3) float
        ``R``, inertial → ``L`` frame.
    """

    reading: Reading
    chi2: float
    motion: ScaledMotion | None
    origin: float
    frame: np.ndarray


def _attitudes(
    profile: EGIProfile, f_psi: float, motion: ScaledMotion, origin: float, frame: np.ndarray
) -> np.ndarray:
    """``A(t) = M(f_ψ t + τ₀) R`` at the profile's epochs (module docstring)."""
    return attitude_about_momentum(motion, f_psi * profile.seconds + origin) @ frame


def reading_chi2(
    profile: EGIProfile,
    reading: Reading,
    rng: np.random.Generator,
    *,
    trials: int = SCREEN_TRIALS,
    refined: int = REFINED,
    grid: int = MOMENT_GRID,
) -> ReadingFit:
    """The least profile χ² of one reading (module docstring).

    Parameters
    ----------
    profile : EGIProfile
    reading : Reading
        Frequencies in Hz.
    rng : numpy.random.Generator
        Draws the trials.
    trials, refined : int
        Random trials screened, and the best of them refined.
    grid : int
        Moment lattice per axis (:func:`motions_with_ratio`).

    Returns
    -------
    ReadingFit
        ``chi2`` is infinite when no motion of the lattice has the reading's ratio.
    """
    f_phi, f_psi, mode, _ = reading
    motions = motions_with_ratio(f_psi / f_phi, mode, grid)
    if not motions:
        return ReadingFit(reading, math.inf, None, 0.0, np.eye(3))
    which = rng.integers(len(motions), size=trials)
    origins = rng.uniform(0.0, 1.0, trials)
    frames = attitude_matrix(random_quaternion(trials, rng))
    scores = np.array(
        [
            profile.chi2(_attitudes(profile, f_psi, motions[k], o, r))
            for k, o, r in zip(which, origins, frames, strict=True)
        ]
    )
    best = None
    for i in np.argsort(scores)[:refined]:
        fit = _refined(profile, reading, motions[which[i]], origins[i], frames[i])
        if best is None or fit.chi2 < best.chi2:
            best = fit
    return best


def _refined(
    profile: EGIProfile,
    reading: Reading,
    motion: ScaledMotion,
    origin: float,
    frame: np.ndarray,
    steps: int = REFINE_STEPS,
) -> ReadingFit:
    """A trial refined in a small rotation of ``R``, in ``τ₀`` and in the moments along the
    reading's curve of constant period ratio (:func:`_moved`); the periods held."""
    f_psi = reading.f_psi
    ratio = f_psi / reading.f_phi
    a = motion.moments[0]
    start = np.array([0.0, 0.0, 0.0, 0.0, a, (motion.moments[1] - a) / (1.0 - a)])
    low, high = _lattice_bounds(MAX_MOMENT_RATIO)
    start[4:] = np.clip(start[4:], low, high)

    def unpack(x: np.ndarray) -> tuple[ScaledMotion, float, np.ndarray]:
        turned = frame @ attitude_matrix(rotation_vector_to_quaternion(x[:3])).T
        return _moved(motion, x[4], x[5], ratio), origin + x[3], turned

    def residuals(x: np.ndarray) -> np.ndarray:
        return profile.residuals(_attitudes(profile, f_psi, *unpack(x)))

    found = least_squares(
        residuals,
        start,
        x_scale=np.array([0.05, 0.05, 0.05, 0.01, 0.02, 0.02]),
        bounds=(
            np.concatenate([np.full(4, -np.inf), low]),
            np.concatenate([np.full(4, np.inf), high]),
        ),
        diff_step=1e-3,
        max_nfev=steps,
    )
    moved, tau0, turned = unpack(found.x)
    return ReadingFit(reading, 2.0 * float(found.cost), moved, tau0, turned)


def convex_reading(
    observations: Observations | Sequence[Observations],
    readings: Sequence[Reading],
    *,
    seed: int = 0,
    normals: int = SCREEN_NORMALS,
    epochs: int = SCREEN_EPOCHS,
    trials: int = SCREEN_TRIALS,
    refined: int = REFINED,
) -> list[ReadingFit]:
    """Each reading's best convex fit (module docstring), the lowest χ² first.

    Parameters
    ----------
    observations : Observations or sequence of them
    readings : sequence of Reading
        Frequencies in Hz.
    seed : int
        Seed of every reading's trials (each reading draws from ``default_rng([seed, k])``).
    normals, epochs, trials, refined : int
        The profile's normals and epochs, the random trials per reading and those refined.

    Returns
    -------
    list of ReadingFit
    """
    profile = EGIProfile(observations, CONVEX_LAW, normals=normals, epochs=epochs)
    fits = [
        reading_chi2(
            profile, reading, np.random.default_rng([seed, k]), trials=trials, refined=refined
        )
        for k, reading in enumerate(readings)
    ]
    return sorted(fits, key=lambda fit: fit.chi2)


@dataclass(frozen=True)
class ConvexDecision:
    """The convex model's choice among the readings of a fitted pair.

    Attributes
    ----------
    fits : list of ReadingFit
        The finalists' full fits, the lowest χ² first.
    delta_chi2 : float
        χ² of the runner-up minus the best, over the best's reduced χ² (when above 1).
    ambiguous : bool
        ``delta_chi2 < AMBIGUOUS_DELTA_CHI2``: the light curve does not tell the two apart.
    """

    fits: list[ReadingFit]
    delta_chi2: float
    ambiguous: bool

    @property
    def best(self) -> ReadingFit:
        """The reading of least χ²."""
        return self.fits[0]

    def periods(self, periods_h: Sequence[float], sigmas_h: Sequence[float]) -> dict:
        """The best reading's periods (h) with 1σ, and its mode.

        Parameters
        ----------
        periods_h, sigmas_h : (2,) float
            The fitted pair (h) in the order of the readings' bases, and its 1σ; the
            frequencies' ``σ_f² = Σ_j T_ij² σ_j²`` (their correlation ignored).
        """
        reading = self.best.reading
        frequencies = np.array([reading.f_phi, reading.f_psi])
        pair_sigma = np.asarray(sigmas_h, float) / np.asarray(periods_h, float) ** 2 / 3600.0
        sigma = np.sqrt(reading.basis**2 @ pair_sigma**2)
        periods = [
            {"period_h": float(1.0 / f / 3600.0), "sigma_h": float(s / f**2 / 3600.0)}
            for f, s in zip(frequencies, sigma, strict=True)
        ]
        return {
            "precession_period_h": periods[0],
            "rotation_period_h": periods[1],
            "mode": reading.mode,
        }


def decide_reading(
    observations: Observations | Sequence[Observations],
    pair: Sequence[float],
    *,
    seed: int = 0,
) -> ConvexDecision | None:
    """The convex model's reading of a fitted pair (module docstring, "The decision").

    ``delta_chi2`` is the runner-up's χ² minus the best's over the best's χ² per epoch
    when above 1: the misfit the law and the grid leave counts as noise.

    Parameters
    ----------
    observations : Observations or sequence of them
    pair : (2,) float
        The fitted frequencies (Hz).
    seed : int
        Seed of the trials.

    Returns
    -------
    ConvexDecision or None
        None when no reading has a motion (no two readings to compare).
    """
    quick = convex_reading(
        observations,
        reading_hypotheses(pair),
        seed=seed,
        normals=QUICK_NORMALS,
        epochs=QUICK_EPOCHS,
        trials=QUICK_TRIALS,
        refined=QUICK_REFINED,
    )
    finalists = [fit for fit in quick[:FINALISTS] if fit.motion is not None]
    if len(finalists) < 2:
        return None
    profile = EGIProfile(observations, CONVEX_LAW, normals=SCREEN_NORMALS, epochs=SCREEN_EPOCHS)
    fits = sorted(
        (
            _refined(profile, fit.reading, fit.motion, fit.origin, fit.frame, FINAL_STEPS)
            for fit in finalists
        ),
        key=lambda fit: fit.chi2,
    )
    reduced = max(fits[0].chi2 / len(profile.seconds), 1.0)
    delta = (fits[1].chi2 - fits[0].chi2) / reduced
    return ConvexDecision(fits, float(delta), bool(delta < AMBIGUOUS_DELTA_CHI2))
