"""Closed-form torque-free motion of a rigid body, in a scale-free form.

The body rates in principal axes are Jacobi elliptic functions of ``u = s t``
(Landau & Lifshitz 1976, Mechanics, §37; Samarasinha & A'Hearn 1991, Icarus 93, 194): with
the reference axis r (C in a short-axis mode, SAM; A in a long-axis mode, LAM), the opposite
extreme axis o and the intermediate axis b, ::

    ω_o = √((2E I_r − L²) / (I_o (I_r − I_o))) cn u,
    ω_b = √((2E I_r − L²) / (I_b (I_r − I_b))) sn u,
    ω_r = √((L² − 2E I_o) / (I_r (I_r − I_o))) dn u,

    s² = (I_r − I_b)(L² − 2E I_o) / (I_o I_b I_r),
    k² = (I_b − I_o)(2E I_r − L²) / ((I_r − I_b)(L² − 2E I_o)).

The Euler angles (φ, θ, ψ) of the body about ``L`` (3-1-3 about the reference axis) follow
from the body components of ``L``: ``L_x = L sin θ sin ψ``, ``L_y = L sin θ cos ψ``,
``L_z = L cos θ``, and the precession rate ``φ̇ = L (I_x ω_x² + I_y ω_y²) / (I_x² ω_x² +
I_y² ω_y²)`` (Landau & Lifshitz §37; :mod:`filters.attitude.torque_free_periods`).

Scale-free form: the largest moment is 1, ``|L| = 1`` and ``d = L²/(2E)`` (``B < d < C``
in a SAM, ``A < d < B`` in a LAM). Time is in units of the rotation period ``P_ψ``, so a
motion of given moments and ``d`` is one function of ``τ = t/P_ψ``; its period ratio
``P_φ/P_ψ`` is :func:`period_ratio`. A real motion of those moments, energy and ``L`` is this
one with time scaled by ``P_ψ``, rotated by a constant rotation (the direction of ``L``
and the initial precession angle) and shifted in time.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.special import ellipj, ellipk

from filters.attitude.torque_free_periods import elliptic_parameters, elliptic_periods

__all__ = [
    "ScaledMotion",
    "attitude_about_momentum",
    "body_rates",
    "period_ratio",
    "scaled_motion",
]

#: Samples per rotation period of the table of the precession angle's periodic part.
_PHASE_SAMPLES = 512


def _elliptic(moments: np.ndarray, d: Any, mode: str) -> tuple[np.ndarray, ...]:
    """Scale s, parameter k², the amplitudes of (ω_o, ω_b, ω_r) (|L| = 1) and the moments
    (I_o, I_b, I_r), vectorised over the leading axes of ``moments`` (…, 3) and ``d`` (…)."""
    two_e = 1.0 / np.asarray(d, float)
    scale, k2 = elliptic_parameters(moments, 1.0, two_e, mode)
    a, b, c = np.moveaxis(np.asarray(moments, float), -1, 0)
    o, r = (a, c) if mode == "SAM" else (c, a)
    amp_o = np.sqrt((two_e * r - 1.0) / (o * (r - o)))
    amp_b = np.sqrt((two_e * r - 1.0) / (b * (r - b)))
    amp_r = np.sqrt((1.0 - two_e * o) / (r * (r - o)))
    return scale, k2, amp_o, amp_b, amp_r, o, b, r


def period_ratio(moments: np.ndarray, d: np.ndarray, mode: str) -> np.ndarray:
    """``P_φ/P_ψ = f_ψ/f_φ`` of the scale-free motions (module docstring), vectorised
    (:func:`~filters.attitude.torque_free_periods.elliptic_periods`).

    Parameters
    ----------
    moments : (…, 3) float
        ``A ≤ B ≤ C`` (any scale).
    d : (…) float
        ``L²/(2E)`` in the moments' units, inside the mode's interval.
    mode : str

    Returns
    -------
    (…) float
    """
    rotation, precession = elliptic_periods(moments, 1.0, 1.0 / np.asarray(d, float), mode)
    return precession / rotation


@dataclass(frozen=True)
class ScaledMotion:
    """One scale-free torque-free motion (module docstring).

    Attributes
    ----------
    mode : str
    moments : (3,) float
    d : float
        ``L²/(2E)``.
    ratio : float
        ``P_φ/P_ψ``.
    rotation_period : float
        ``P_ψ`` in the scale-free time unit (``|L| = 1`` in the moments' units).
    phase_table : (_PHASE_SAMPLES + 1,) float
        The periodic part of φ (rad) over one rotation period, ``τ ∈ [0, 1]``.
    """

    mode: str
    moments: np.ndarray
    d: float
    ratio: float
    rotation_period: float
    phase_table: np.ndarray


def scaled_motion(moments: np.ndarray, d: float, mode: str) -> ScaledMotion:
    """Tabulate the scale-free motion of ``moments`` and ``d`` in ``mode``.

    The periodic part of φ is the trapezoid-rule integral of ``φ̇ − ⟨φ̇⟩`` on
    ``_PHASE_SAMPLES`` steps of a rotation period (attitude within 1e-4 rad of the
    integrated motion: the tests).

    Parameters
    ----------
    moments : (3,) float
        ``A ≤ B ≤ C``.
    d : float
        ``L²/(2E)`` in the moments' units, inside the mode's interval.
    mode : str
        ``"SAM"`` or ``"LAM"``.

    Returns
    -------
    ScaledMotion
    """
    moments = np.asarray(moments, float)
    tau = np.linspace(0.0, 1.0, _PHASE_SAMPLES + 1)
    rates, _ = _rates(moments, d, mode, tau)
    s, k2, _, _, _, ix, iy, _ = _elliptic(moments, d, mode)
    period = 4.0 * float(ellipk(k2)) / float(s)
    wx, wy = rates[:, 0], rates[:, 1]
    phi_dot = (ix * wx**2 + iy * wy**2) / (ix**2 * wx**2 + iy**2 * wy**2) * period
    increments = 0.5 * (phi_dot[1:] + phi_dot[:-1]) * np.diff(tau)
    phi = np.concatenate([[0.0], np.cumsum(increments)])
    mean_rate = phi[-1]
    return ScaledMotion(
        mode, moments, float(d), float(2 * np.pi / mean_rate), period, phi - mean_rate * tau
    )


def body_rates(motion: ScaledMotion, tau: np.ndarray) -> np.ndarray:
    """Body rates (N, 3) (rad per scale-free time unit) in the motion's axes
    (:func:`attitude_about_momentum`) at scaled times τ (rotation periods)."""
    return _rates(motion.moments, motion.d, motion.mode, tau)[0]


def _rates(moments: np.ndarray, d: float, mode: str, tau: np.ndarray):
    """Body rates (…, 3) in the motion's axes at scaled times τ (rotation periods), and the
    body components of the unit angular momentum."""
    _, k2, amp_o, amp_b, amp_r, o, b, r = _elliptic(moments, d, mode)
    u = 4.0 * ellipk(k2) * np.asarray(tau, float)
    sn, cn, dn, _ = ellipj(u, k2)
    # (x, y, z) = (o, b, r) in a SAM, (o, −b, r) in a LAM: right-handed either way.
    sign = 1.0 if mode == "SAM" else -1.0
    rates = np.stack([amp_o * cn, sign * amp_b * sn, amp_r * dn], axis=-1)
    momentum = rates * np.array([o, b, r])
    return rates, momentum / np.linalg.norm(momentum, axis=-1, keepdims=True)


def attitude_about_momentum(motion: ScaledMotion, tau: np.ndarray) -> np.ndarray:
    """Attitude matrices (N, 3, 3) from a frame whose z axis is along ``L`` to the motion's
    body axes, ``v_B = M v_L``, at scaled times τ (rotation periods from the motion's
    origin, where φ = 0).

    The body axes are (opposite, intermediate, reference) in a SAM and (opposite,
    −intermediate, reference) in a LAM: right-handed, the reference axis z. ``M = R_z(ψ)
    R_x(θ) R_z(φ)`` (passive elementary rotations; R_x(θ) from ``cos θ``, ``sin θ``).

    Parameters
    ----------
    motion : ScaledMotion
    tau : (N,) float
        Time in rotation periods.

    Returns
    -------
    (N, 3, 3) float
    """
    tau = np.asarray(tau, float)
    _, unit = _rates(motion.moments, motion.d, motion.mode, tau)
    cos_theta = unit[:, 2]
    sin_theta = np.hypot(unit[:, 0], unit[:, 1])
    psi = np.arctan2(unit[:, 0], unit[:, 1])
    grid = np.linspace(0.0, 1.0, len(motion.phase_table))
    phi = 2 * np.pi * tau / motion.ratio + np.interp(np.mod(tau, 1.0), grid, motion.phase_table)
    return _rz(psi) @ _rx(cos_theta, sin_theta) @ _rz(phi)


def _rz(angle: np.ndarray) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    zero, one = np.zeros_like(c), np.ones_like(c)
    return np.stack([c, s, zero, -s, c, zero, zero, zero, one], axis=-1).reshape(-1, 3, 3)


def _rx(c: np.ndarray, s: np.ndarray) -> np.ndarray:
    zero, one = np.zeros_like(c), np.ones_like(c)
    return np.stack([one, zero, zero, zero, c, s, zero, -s, c], axis=-1).reshape(-1, 3, 3)
