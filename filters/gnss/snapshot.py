"""One epoch of relative GNSS: single point positioning, double-difference geometry and the
epoch's normal equations of baseline and ambiguities.

The snapshot pieces of the relative solver (:mod:`filters.gnss.relative`, where the model is
stated): each function uses one epoch's measurements only. Frame: the week-start inertial
frame of :mod:`filters.gnss.constellation`; units m, m/s.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from filters.gnss.differencing import double_differences
from filters.gnss.measurements import transmit_positions

__all__ = ["double_difference_geometry", "epoch_normal_equations", "single_point_position"]


def single_point_position(
    positions: Any,
    velocities: Any,
    code: Any,
    initial: Any = None,
    iterations: int = 10,
) -> tuple[np.ndarray, float]:
    """Absolute position and clock offset of a receiver from its pseudoranges (Gauss–Newton).

    Parameters
    ----------
    positions, velocities : (m, 3) array_like
        Satellite states at the reception time (m, m/s, inertial), ``m ≥ 4``.
    code : (m,) array_like
        Pseudoranges corrected for the broadcast satellite clocks (m).
    initial : (3,) array_like, optional
        Starting position (m); the geocentre by default.
    iterations : int
        Maximum iterations (stops when the update is below 1 mm).

    Returns
    -------
    position : (3,) numpy.ndarray
        Receiver position (m, week-start inertial frame).
    clock : float
        Receiver clock offset times ``c`` (m).
    """
    p = np.asarray(code, dtype=float)
    if len(p) < 4:
        raise ValueError(f"single point positioning needs 4 satellites, got {len(p)}")
    x = np.zeros(4) if initial is None else np.append(np.asarray(initial, dtype=float), 0.0)
    for _ in range(iterations):
        sat, rho = transmit_positions(positions, velocities, x[:3])
        g = np.hstack([-(sat - x[:3]) / rho[:, None], np.ones((len(p), 1))])
        dx = np.linalg.lstsq(g, p - rho - x[3], rcond=None)[0]
        x = x + dx
        if np.linalg.norm(dx[:3]) < 1e-3:
            break
    return x[:3], float(x[3])


def double_difference_geometry(
    positions: Any,
    velocities: Any,
    reference: int,
    base: Any,
    baseline: Any,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Single-difference geometric ranges and their derivatives with respect to the baseline.

    Parameters
    ----------
    positions, velocities : (m, 3) array_like
        Satellite states at the reception time (m, m/s, inertial).
    reference : int
        Index of the reference satellite.
    base : (3,) array_like
        Base receiver position (m).
    baseline : (3,) array_like
        Linearisation point ``b₀`` of the baseline (m).

    Returns
    -------
    single : (m,) numpy.ndarray
        ``ρ_rover − ρ_base`` at ``b₀`` (m), with light time for each receiver.
    jacobian : (m, 3) numpy.ndarray
        ``∂ single / ∂ b``: the rover's negative unit lines of sight.
    design : (m − 1, 3) numpy.ndarray
        ``A = ∂ DD ρ / ∂ b``, the double differences of ``jacobian``.
    """
    base = np.asarray(base, dtype=float)
    rover = base + np.asarray(baseline, dtype=float)
    _, rho_b = transmit_positions(positions, velocities, base)
    sat_r, rho_r = transmit_positions(positions, velocities, rover)
    jacobian = -(sat_r - rover) / rho_r[:, None]
    return rho_r - rho_b, jacobian, double_differences(jacobian.T, reference).T


def epoch_normal_equations(
    design: Any, y_code: Any, y_phase: Any, q_code: Any, q_phase: Any, wavelength: float
) -> dict[str, np.ndarray]:
    """One epoch's normal equations of ``[δb, a]`` and the ambiguity block with ``δb`` reduced.

    Parameters
    ----------
    design : (n, 3) array_like
        ``A``.
    y_code, y_phase : (n,) array_like
        Observed-minus-computed code and phase double differences (m).
    q_code, q_phase : (n, n) array_like
        Their covariances (m²).
    wavelength : float
        ``λ`` (m): the phase model is ``y_Φ = A δb + λ a``.

    Returns
    -------
    dict
        ``N_bb`` (3, 3), ``N_ba`` (3, n), ``N_aa`` (n, n), ``n_b`` (3,), ``n_a`` (n,),
        ``reduced_normal`` (n, n) and ``reduced_rhs`` (n,).
    """
    a = np.asarray(design, dtype=float)
    w_c = np.linalg.inv(np.asarray(q_code, dtype=float))
    w_p = np.linalg.inv(np.asarray(q_phase, dtype=float))
    y_c = np.asarray(y_code, dtype=float)
    y_p = np.asarray(y_phase, dtype=float)
    lam = float(wavelength)
    n_bb = a.T @ (w_c + w_p) @ a
    n_ba = lam * a.T @ w_p
    n_aa = lam * lam * w_p
    n_b = a.T @ (w_c @ y_c + w_p @ y_p)
    n_a = lam * w_p @ y_p
    reduce = np.linalg.solve(n_bb, np.column_stack([n_ba, n_b]))
    return {
        "N_bb": n_bb,
        "N_ba": n_ba,
        "N_aa": n_aa,
        "n_b": n_b,
        "n_a": n_a,
        "reduced_normal": n_aa - n_ba.T @ reduce[:, :-1],
        "reduced_rhs": n_a - n_ba.T @ reduce[:, -1],
    }
