"""Rotation and mean precession periods of torque-free motion (non-principal-axis rotation).

Euler angles (φ, θ, ψ) of the body about the angular momentum ``L`` (z-axis of the inertial
reference along ``L``, the 3-1-3 sequence about the body's *reference axis* a): φ is the
precession of the reference axis about ``L``, θ its tilt, ψ the rotation about it. With the
principal moments ``A < B < C`` and the rotational energy ``E``, the motion is

* a **short-axis mode** (SAM, ``L² > 2EB``): reference axis C, the body rates circulate
  about the axis of largest moment;
* a **long-axis mode** (LAM, ``L² < 2EB``): reference axis A;
* a principal-axis rotation (PA) when ω lies along a principal axis.

The body rates are periodic with the rotation period ``P_ψ`` (ψ advances by 2π, θ
oscillates); φ advances at the non-uniform rate (Samarasinha & A'Hearn 1991, Icarus 93, 194;
Kaasalainen 2001, A&A 376, 302, eq. 2) ::

    φ̇ = |L| (I_b ω_b² + I_c ω_c²) / (I_b² ω_b² + I_c² ω_c²)

with b, c the two other axes, and ``P_φ = 2π / ⟨φ̇⟩`` its mean over ``P_ψ``. A light curve
of the tumbler is a function of (φ, ψ) and of time only through them, so it is quasi-periodic
with the two frequencies ``1/P_φ`` and ``1/P_ψ``.

Two independent routes:

* :func:`euler_periods` — closed forms with complete elliptic integrals (Landau & Lifshitz
  1976, Mechanics, §37): ``P_ψ = 4 K(k) / s``, and, from ``φ̇ = (L/I_a)[1 + (I_a − I_c)/I_c
  · 1/(1 − n sn²)]`` over a quarter period, ``⟨φ̇⟩ = (L/I_a)[1 + (I_a − I_c)/I_c · Π(n, k)/
  K(k)]`` (a = reference axis, c = the opposite extreme axis, ``n = −I_a (I_b − I_c)/(I_c
  (I_a − I_b))``);
* :func:`euler_periods_numeric` — the rates integrated by the attitude core's adaptive
  propagator, ``P_ψ`` from the zero crossings of the intermediate-axis rate (∝ sn in either
  mode) and ``⟨φ̇⟩`` by quadrature of the formula above over that period.

A symmetric top (``A = B`` or ``B = C``) has ``k = 0``, ``n = 0`` and the textbook
``P_φ = 2π I_t / |L|`` with ``I_t`` the transverse moment.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.integrate import simpson
from scipy.interpolate import CubicSpline
from scipy.special import ellipk, elliprf, elliprj

from filters.attitude.inertia import validate_inertia
from filters.attitude.propagation import propagate

__all__ = [
    "EulerPeriods",
    "elliptic_parameters",
    "elliptic_periods",
    "euler_periods",
    "euler_periods_numeric",
    "principal_state",
]

#: Rates within this fraction of |ω| off a principal axis count as a principal-axis rotation.
PRINCIPAL_TOLERANCE = 1e-9


@dataclass(frozen=True)
class EulerPeriods:
    """Periods of a torque-free motion.

    Attributes
    ----------
    mode : str
        ``"SAM"``, ``"LAM"`` or ``"PA"`` (principal-axis rotation).
    rotation_period_s : float
        ``P_ψ`` (s): the period of the body rates (for PA: the spin period ``2π/|ω|``).
    precession_period_s : float
        ``P_φ = 2π/⟨φ̇⟩`` (s) (for PA: the spin period as well, ψ being undefined).
    """

    mode: str
    rotation_period_s: float
    precession_period_s: float


def principal_state(inertia: Any, omega: Any) -> tuple[np.ndarray, np.ndarray]:
    """Principal moments ``A ≤ B ≤ C`` and the body rates in those principal axes.

    Parameters
    ----------
    inertia : (3, 3) array_like
        Body-frame inertia (validated).
    omega : (3,) array_like
        Body rates (rad/s, body frame).

    Returns
    -------
    moments : (3,) numpy.ndarray
    omega : (3,) numpy.ndarray
    """
    moments, axes = np.linalg.eigh(validate_inertia(inertia))
    return moments, axes.T @ np.asarray(omega, float)


def _mode(moments: np.ndarray, w: np.ndarray) -> tuple[str, float, float]:
    """Mode and (|L|², 2E)."""
    l2 = float(np.sum((moments * w) ** 2))
    two_e = float(np.sum(moments * w * w))
    if l2 == 0.0:
        raise ValueError("the body does not rotate (ω = 0)")
    along = np.max(np.abs(w)) / np.linalg.norm(w)
    if along > 1.0 - PRINCIPAL_TOLERANCE:
        return "PA", l2, two_e
    if abs(l2 - two_e * moments[1]) <= PRINCIPAL_TOLERANCE * l2:
        raise ValueError("the state lies on the separatrix (L² = 2E·B): the periods are infinite")
    return ("SAM" if l2 > two_e * moments[1] else "LAM"), l2, two_e


def _principal_periods(w: np.ndarray) -> EulerPeriods:
    spin = 2 * math.pi / float(np.linalg.norm(w))
    return EulerPeriods("PA", spin, spin)


def elliptic_parameters(
    moments: Any, l2: Any, two_e: Any, mode: str
) -> tuple[np.ndarray, np.ndarray]:
    """Scale ``s`` and parameter ``k²`` of the body rates' Jacobi functions of ``u = s t``
    (Landau & Lifshitz 1976, §37), vectorised.

    With the reference axis r (C in a SAM, A in a LAM), the opposite extreme axis o and the
    intermediate b: ``s² = (I_r − I_b)(L² − 2E I_o)/(A B C)``, ``k² = (I_b − I_o)(2E I_r −
    L²)/((I_r − I_b)(L² − 2E I_o))``.

    Parameters
    ----------
    moments : (..., 3) array_like
        Principal moments ``A ≤ B ≤ C``.
    l2, two_e : array_like
        ``|L|²`` and twice the rotational energy (broadcast against the moments' batch).
    mode : str
        ``"SAM"`` or ``"LAM"``.

    Returns
    -------
    s, k2 : numpy.ndarray
    """
    if mode not in ("SAM", "LAM"):
        raise ValueError(f"unknown mode {mode!r}: expected 'SAM' or 'LAM'")
    a, b, c = np.moveaxis(np.asarray(moments, float), -1, 0)
    reference, opposite = (c, a) if mode == "SAM" else (a, c)
    scale = np.sqrt((reference - b) * (l2 - two_e * opposite) / (a * b * c))
    k2 = (b - opposite) * (two_e * reference - l2) / ((reference - b) * (l2 - two_e * opposite))
    return scale, k2


def elliptic_periods(moments: Any, l2: Any, two_e: Any, mode: str) -> tuple[np.ndarray, np.ndarray]:
    """Rotation and mean precession periods ``(P_ψ, P_φ)`` in closed form (module
    docstring), vectorised over the arguments of :func:`elliptic_parameters`."""
    scale, k2 = elliptic_parameters(moments, l2, two_e, mode)
    a, b, c = np.moveaxis(np.asarray(moments, float), -1, 0)
    reference, opposite = (c, a) if mode == "SAM" else (a, c)
    quarter = ellipk(k2)
    n = -reference * (b - opposite) / (opposite * (reference - b))
    # Π(n, k) = R_F(0, 1 − k², 1) + n/3 · R_J(0, 1 − k², 1, 1 − n) (Carlson 1995).
    third = elliprf(0.0, 1 - k2, 1.0) + n / 3.0 * elliprj(0.0, 1 - k2, 1.0, 1.0 - n)
    rate = np.sqrt(l2) / reference * (1.0 + (reference - opposite) / opposite * third / quarter)
    return 4.0 * quarter / scale, 2 * np.pi / rate


def euler_periods(inertia: Any, omega: Any) -> EulerPeriods:
    """Closed-form rotation and mean precession periods (module docstring).

    Parameters
    ----------
    inertia : (3, 3) array_like
        Body-frame inertia (any units).
    omega : (3,) array_like
        Body rates (rad/s, body frame) at any instant.

    Returns
    -------
    EulerPeriods

    Raises
    ------
    ValueError
        No rotation, or a state on the separatrix.
    """
    moments, w = principal_state(inertia, omega)
    mode, l2, two_e = _mode(moments, w)
    if mode == "PA":
        return _principal_periods(w)
    rotation, precession = elliptic_periods(moments, l2, two_e, mode)
    return EulerPeriods(mode, float(rotation), float(precession))


def euler_periods_numeric(
    inertia: Any, omega: Any, *, samples_per_period: int = 4000
) -> EulerPeriods:
    """Rotation and mean precession periods by integrating the motion (module docstring).

    The rates are propagated by :func:`filters.attitude.propagate` (DOP853, tolerances
    1e-12) over windows doubled until the intermediate-axis rate has crossed zero upwards
    twice; the crossings are located by cubic interpolation and ``φ̇`` is integrated between
    them by Simpson's rule.

    Parameters
    ----------
    inertia : (3, 3) array_like
        Body-frame inertia.
    omega : (3,) array_like
        Body rates (rad/s, body frame).
    samples_per_period : int
        Output samples per rotation period of the final window.

    Returns
    -------
    EulerPeriods
    """
    moments, w = principal_state(inertia, omega)
    mode, l2, _ = _mode(moments, w)
    if mode == "PA":
        return _principal_periods(w)
    state = np.concatenate([[0.0, 0.0, 0.0, 1.0], w])
    span = 4 * math.pi / float(np.linalg.norm(w))
    for _ in range(40):
        times = np.linspace(0.0, span, samples_per_period * 2 + 1)
        rates = propagate(state, times, np.diag(moments))[:, 4:]
        crossings = _upward_zeros(times, rates[:, 1])
        if len(crossings) >= 2:
            break
        span *= 2.0
    else:
        raise RuntimeError("the body rates did not return within 2⁴⁰ spin periods")
    start, stop = crossings[:2]
    if start > 0:
        state = propagate(state, [0.0, start], np.diag(moments))[-1]
    grid = np.linspace(0.0, stop - start, 2 * samples_per_period + 1)
    rw = propagate(state, grid, np.diag(moments))[:, 4:]
    b_axis, c_axis = (0, 1) if mode == "SAM" else (1, 2)
    ib, ic = moments[b_axis], moments[c_axis]
    wb, wc = rw[:, b_axis], rw[:, c_axis]
    phi_dot = math.sqrt(l2) * (ib * wb**2 + ic * wc**2) / (ib**2 * wb**2 + ic**2 * wc**2)
    advance = float(simpson(phi_dot, x=grid))
    period = stop - start
    return EulerPeriods(mode, float(period), float(2 * math.pi * period / advance))


def _upward_zeros(times: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Times where the cubic interpolant of ``values`` crosses zero upwards."""
    spline = CubicSpline(times, values)
    roots = spline.roots(extrapolate=False)
    return roots[spline(roots, 1) > 0]
