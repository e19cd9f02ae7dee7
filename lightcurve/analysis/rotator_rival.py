"""The one-period rival of the two-period analysis: the BIC of a single period whose light
curve changes with the geometry over the arc (:mod:`lightcurve.analysis.tumbling`).

Three forms compete by BIC, each with the per-curve trend polynomial of
:class:`~lightcurve.analysis.fourier_design.FourierDesign`: fixed Fourier coefficients;
coefficients changing within each curve as Legendre polynomials of degree
``MODULATION_DEGREE`` in the curve's scaled time (amplitude and shape follow the aspect and
the phase angle); and the latter with the phase ``2π f t − Λ_p(t)``, Λ_p the longitude of
the phase-angle bisector about a trial pole p
(:func:`~lightcurve.analysis.period.pab_longitude`): the synodic drift of a rotator's phase
as the geometry moves (Harris et al. 1984, Icarus 57, 251; Pravec et al. 2005, Icarus 173,
108, sec. 2). The poles are ``ROTATOR_POLES`` points of a Fibonacci lattice, screened at
order ``ROTATOR_SCREEN_ORDER``; the ``ROTATOR_CANDIDATES`` best are fitted at every order,
the pole counting two parameters.

Where the geometry changes fast (a low-orbit pass), a rotator's light curve changes its
amplitude and shape within the arc in ways neither form follows, and a pair of
frequencies near a low-order ratio then fits it better (:func:`geometry_explains_pair`,
the verdict's last test).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy.optimize import minimize_scalar

from lightcurve.analysis.fourier_design import FourierDesign
from lightcurve.analysis.period import StackedLightCurves, pab_longitude
from lightcurve.sky.geometry import phase_angle, phase_angle_bisector

__all__ = ["geometry_change_deg", "geometry_explains_pair", "rotator_bic", "search_penalty"]

#: Degree of the slow change of the one-period rival's coefficients within a light curve:
#: its amplitude and shape follow the aspect and phase angle over a night or a pass (the
#: rival is also judged with fixed coefficients; the BIC chooses).
MODULATION_DEGREE = 3
#: Trial poles of the one-period rival's PAB phase (a Fibonacci lattice on the sphere), the
#: order of their screening, and how many of the best are judged at every order.
ROTATOR_POLES = 48
ROTATOR_SCREEN_ORDER = 4
ROTATOR_CANDIDATES = 2
#: Harmonic orders of the one-period rival judged on all points (besides ``orders``).
SINGLE_HARMONICS = (2, 3, 4, 6, 8, 12, 16)
#: Change of the geometry (deg) over an arc above which a rotator's light curve changes
#: appreciably within it: the larger of the solar phase angle's range and the angle the
#: phase-angle bisector turns (the aspect of the spin axis changes by up to as much). The
#: amplitude grows as ``1 + m α`` with m ≈ 0.013–0.03 per degree of phase angle (Zappalà et
#: al. 1990, A&A 231, 548), i.e. by 40–90 % over 30°.
GEOMETRY_CHANGE_DEG = 30.0
#: Ratios p:q of the two frequencies (coprime, p, q ≤ 4) whose combinations are the
#: harmonics of one frequency, ``f2/q``, when the pair lies near them.
HARMONIC_RATIOS = tuple((p, q) for p in range(1, 5) for q in range(1, 5) if math.gcd(p, q) == 1)


def rotator_bic(
    data: StackedLightCurves,
    frequencies: Sequence[float],
    step: float,
    *,
    trend_degree: int,
    orders: Sequence[int] = (),
) -> float:
    """The lowest BIC of the one-period rival (module docstring) near any of
    ``frequencies``.

    Parameters
    ----------
    data : StackedLightCurves
        The light curves (with their Sun and observer vectors).
    frequencies : sequence of float
        Frequencies (Hz) around which the rival's χ² minimum is sought, within ``± step``.
    step : float
        Half-width (Hz) of each search.
    trend_degree : int
        Degree of each curve's trend polynomial.
    orders : sequence of int
        Harmonic orders tried besides ``SINGLE_HARMONICS``.

    Returns
    -------
    float
        ``χ² + p ln N`` of the best form, order and frequency.
    """
    designs = _rotator_designs(data, trend_degree, frequencies, step)
    forms = [(designs[0], 0)] + [(design, MODULATION_DEGREE) for design in designs]
    return min(
        _single_bic(design, f, order, step, modulation=modulation)
        for design, modulation in forms
        for f in frequencies
        for order in sorted({*orders, *SINGLE_HARMONICS})
    )


def geometry_change_deg(sun: np.ndarray, observer: np.ndarray) -> float:
    """How far the geometry moves over the points (deg): the larger of the solar phase
    angle's range and the largest angle between the phase-angle bisector at a point and at
    the first.

    Parameters
    ----------
    sun, observer : (n, 3) float
        Object → Sun and object → observer vectors (any common frame).
    """
    phase = phase_angle(sun, observer)
    bisector = phase_angle_bisector(sun, observer)
    turn = np.arccos(np.clip(bisector @ bisector[0], -1.0, 1.0))
    return float(np.degrees(max(np.ptp(phase), turn.max())))


def geometry_explains_pair(
    pair: Sequence[float],
    span_s: float,
    sun: np.ndarray,
    observer: np.ndarray,
    *,
    resolution_cycles: float,
) -> bool:
    """Whether one period whose light curve changes with the geometry explains a fitted pair.

    True when the geometry moves by more than ``GEOMETRY_CHANGE_DEG`` over the points
    (:func:`geometry_change_deg`) and the two frequencies lie within ``resolution_cycles``
    cycles per span of a ratio p:q of ``HARMONIC_RATIOS`` (``|q f2 − p f1| T <
    resolution_cycles``). Every combination ``j f1 + k f2`` is then a harmonic of ``f2/q``
    offset by a multiple of ``|q f2 − p f1|/q``: sidebands that beat by less than the
    frequency resolution over the arc (1.5 cycles: Loumos & Deeming 1978, Ap&SS 56, 285),
    which is how a changing amplitude and shape look in a two-frequency series. A tumbler's
    near-commensurate pair is told apart only where the geometry stands still.

    Parameters
    ----------
    pair : (f1, f2)
        The fitted frequencies (Hz).
    span_s : float
        Time span T (s) of the points.
    sun, observer : (n, 3) float
        Object → Sun and object → observer vectors of the points (any common frame).
    resolution_cycles : float
        Cycles per span that resolve two frequencies.

    Returns
    -------
    bool
    """
    f1, f2 = pair
    near_ratio = any(abs(q * f2 - p * f1) * span_s < resolution_cycles for p, q in HARMONIC_RATIOS)
    return near_ratio and geometry_change_deg(sun, observer) > GEOMETRY_CHANGE_DEG


def search_penalty(independent_trials: float) -> float:
    """The ΔBIC a second frequency must add for having been searched: ``2 ln M``.

    The BIC counts a frequency as one parameter (``ln N``), as if its value were known in
    advance; the largest of M independent periodogram peaks of pure noise grows as ``ln M``
    in ``Δχ²/2`` (false-alarm probability ``≈ M e^{−Δχ²/2}``: Scargle 1982, ApJ 263, 835;
    Horne & Baliunas 1986, ApJ 302, 757). The threshold of a searched frequency is
    therefore raised by ``2 ln M``.

    Parameters
    ----------
    independent_trials : float
        M, the independent trial frequencies: the searched band times the span T.

    Returns
    -------
    float
        ``2 ln M`` (0 for M ≤ 1).
    """
    return 2.0 * math.log(max(float(independent_trials), 1.0))


def _single_bic(
    design: FourierDesign, f0: float, order: int, step: float, *, modulation: int
) -> float:
    """BIC of the K-harmonic one-period series, its coefficients changing within each light
    curve as Legendre polynomials of degree ``modulation``, at its χ² minimum within
    ``f0 ± step`` (the pole of a PAB phase, when the design has one, counts two
    parameters)."""
    harmonics = np.arange(1, order + 1)[:, None]
    result = minimize_scalar(
        lambda f: float(_modulated_chi2(design, np.array([f]), harmonics, modulation)[0]),
        bounds=(f0 - step, f0 + step),
        method="bounded",
        options={"xatol": 1e-4 * step},
    )
    pole_parameters = 0 if np.isscalar(design.offset) else 2
    n_parameters = 2 * order * (modulation + 1) + design.n_nuisance + 1 + pole_parameters
    return float(result.fun) + n_parameters * math.log(len(design.t))


def _modulated_chi2(
    design: FourierDesign, frequencies: np.ndarray, harmonics: np.ndarray, modulation: int
) -> np.ndarray:
    return design.solve_combinations(frequencies[:, None], harmonics, modulation=modulation)[1]


def _fibonacci_poles(count: int) -> list[tuple[float, float]]:
    """``count`` nearly uniform directions (λ, β) (rad) on the sphere (Fibonacci lattice)."""
    index = np.arange(count) + 0.5
    latitude = np.arcsin(1 - 2 * index / count)
    longitude = np.mod(np.pi * (1 + 5**0.5) * index, 2 * np.pi)
    return [(float(a), float(b)) for a, b in zip(longitude, latitude, strict=True)]


def _rotator_designs(
    data: StackedLightCurves, trend_degree: int, frequencies: Sequence[float], step: float
) -> list[FourierDesign]:
    """Designs of the one-period rival: the plain phase ``2π f t`` and the PAB phases
    ``2π f t − Λ_p(t)`` (:func:`~lightcurve.analysis.period.pab_longitude`) of the
    ``ROTATOR_CANDIDATES`` poles p (of ``ROTATOR_POLES`` on the sphere) that fit best near
    ``frequencies`` at order ``ROTATOR_SCREEN_ORDER``."""

    def design(offset: np.ndarray | None) -> FourierDesign:
        return FourierDesign(
            data.times,
            data.magnitudes,
            data.sigma,
            data.curve,
            offset,
            trend_degree=trend_degree,
        )

    harmonics = np.arange(1, ROTATOR_SCREEN_ORDER + 1)[:, None]
    grid = np.concatenate([f + step * np.linspace(-1, 1, 9) for f in frequencies])
    screened = []
    for pole in _fibonacci_poles(ROTATOR_POLES):
        candidate = design(pab_longitude(data.sun, data.observer, pole))
        chi2 = _modulated_chi2(candidate, grid, harmonics, MODULATION_DEGREE)
        screened.append((float(chi2.min()), candidate))
    screened.sort(key=lambda item: item[0])
    return [design(None)] + [d for _, d in screened[:ROTATOR_CANDIDATES]]
