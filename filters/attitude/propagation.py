"""Propagation of the attitude state ``x = [q1, q2, q3, q4, ωx, ωy, ωz]``.

* :func:`rk4_step` / :func:`propagate_rk4`: fixed-step classical Runge–Kutta with quaternion
  renormalisation, batched over any leading dimensions (particles × sigma points …), numpy
  or torch. This is what filters use.
* :func:`propagate`: adaptive integration with scipy's DOP853 for truth simulation.
* :func:`axisymmetric_solution`: the exact torque-free motion of an axisymmetric body, the
  reference the integrators are tested against.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp

from filters.attitude._array import as_arrays, cross, matvec
from filters.attitude.inertia import validate_inertia
from filters.attitude.kinematics import quaternion_rate
from filters.attitude.quaternion import (
    attitude_matrix,
    axis_angle_to_quaternion,
    quaternion_multiply,
    quaternion_normalize,
)

__all__ = [
    "axisymmetric_solution",
    "propagate",
    "propagate_rk4",
    "rk4",
    "rk4_step",
    "torque_free_derivative",
]

Derivative = Callable[[Any], Any]


def torque_free_derivative(inertia: Any) -> Derivative:
    """Return ``f(x) = ẋ`` for torque-free motion with a fixed inertia tensor.

    ``J⁻¹`` is computed once, so evaluating ``f`` on a large batch costs two small batched
    matrix products.

    Parameters
    ----------
    inertia : (..., 3, 3) array
        Body-frame inertia (broadcastable against the state's batch shape).

    Returns
    -------
    callable
        ``f(x)`` for ``x`` of shape ``(..., 7)``.
    """
    xp, (j,) = as_arrays(inertia)
    j_inv = xp.linalg.inv(j)

    def derivative(x: Any) -> Any:
        _, (x, jj, jinv) = as_arrays(x, j, j_inv)
        q, w = x[..., :4], x[..., 4:]
        h = matvec(jj, w)
        w_dot = -matvec(jinv, cross(w, h))
        return xp.concat([quaternion_rate(q, w), w_dot], axis=-1)

    return derivative


def rk4(derivative: Callable[[float, Any], Any], t: float, x: Any, dt: float) -> Any:
    """One classical Runge–Kutta step of ``ẋ = f(t, x)`` for any state (no normalisation).

    Parameters
    ----------
    derivative : callable
        ``f(t, x) → ẋ`` (scipy's argument order), batched over leading dimensions of ``x``.
    t : float
        Time at the start of the step (s).
    x : (..., n) array
        States (numpy or torch).
    dt : float
        Step (s).

    Returns
    -------
    (..., n) array
    """
    k1 = derivative(t, x)
    k2 = derivative(t + 0.5 * dt, x + 0.5 * dt * k1)
    k3 = derivative(t + 0.5 * dt, x + 0.5 * dt * k2)
    k4 = derivative(t + dt, x + dt * k3)
    return x + (dt / 6.0) * (k1 + 2 * k2 + 2 * k3 + k4)


def rk4_step(derivative: Derivative, x: Any, dt: float) -> Any:
    """One RK4 step of an autonomous attitude state, then quaternion renormalisation.

    Parameters
    ----------
    derivative : callable
        ``f(x) → ẋ`` for states ``(..., n)`` whose first four entries are a quaternion
        (e.g. from :func:`torque_free_derivative`); further entries (rates, parameters) are
        integrated as they are.
    x : (..., n) array
        States at the start of the step.
    dt : float
        Step (s).

    Returns
    -------
    (..., n) array
    """
    xp, (x,) = as_arrays(x)
    out = rk4(lambda _t, y: derivative(y), 0.0, x, dt)
    return xp.concat([quaternion_normalize(out[..., :4]), out[..., 4:]], axis=-1)


def propagate_rk4(x0: Any, inertia: Any, dt: float, n_steps: int, substeps: int = 1) -> Any:
    """Propagate a batch of torque-free states with fixed-step RK4.

    Parameters
    ----------
    x0 : (..., 7) array
        Initial states ``[q, ω]`` (rad/s).
    inertia : (..., 3, 3) array
        Body-frame inertia.
    dt : float
        Output interval (s).
    n_steps : int
        Number of output intervals.
    substeps : int
        RK4 steps per output interval.

    Returns
    -------
    (n_steps + 1, ..., 7) array
        States at ``0, dt, …, n_steps·dt``.
    """
    xp, (x,) = as_arrays(x0)
    f = torque_free_derivative(inertia)
    h = dt / substeps
    out = [x]
    for _ in range(n_steps):
        for _ in range(substeps):
            x = rk4_step(f, x, h)
        out.append(x)
    return xp.stack(out, axis=0)


def propagate(
    x0: Any,
    times: Any,
    inertia: Any,
    torque: Callable[[float, np.ndarray], np.ndarray] | None = None,
    rtol: float = 1e-12,
    atol: float = 1e-12,
    method: str = "DOP853",
    normalize: bool = True,
) -> np.ndarray:
    """Propagate states with an adaptive scipy integrator (truth simulation).

    A batch of initial states is integrated as one system, which amortises the integrator's
    per-step overhead over Monte Carlo runs (the step size follows the most demanding run).

    Parameters
    ----------
    x0 : (7,) or (B, 7) array_like
        Initial states ``[q, ω]`` at ``times[0]`` (rad/s).
    times : (n,) array_like
        Strictly increasing output times (s).
    inertia : (3, 3) array_like
        Body-frame inertia, validated with
        :func:`~filters.attitude.inertia.validate_inertia`.
    torque : callable, optional
        ``torque(t, x) → (3,)`` or ``(B, 3)`` body-frame torque in inertia units × rad/s².
    rtol, atol : float
        Integrator tolerances.
    method : str
        Any :func:`scipy.integrate.solve_ivp` method.
    normalize : bool
        Renormalise the output quaternions (their raw drift is ~1e-11 over 10⁴ s at the
        default tolerances).

    Returns
    -------
    (n, 7) or (n, B, 7) numpy.ndarray
        States at ``times``.
    """
    j = validate_inertia(inertia)
    j_inv = np.linalg.inv(j)
    t = np.asarray(times, dtype=float)
    if t.ndim != 1 or t.size == 0 or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise ValueError("times must be a non-empty, finite, strictly increasing 1-D sequence")
    x0 = np.array(x0, dtype=float)
    if x0.shape[-1] != 7 or x0.ndim > 2 or not np.all(np.isfinite(x0)):
        raise ValueError(f"initial state must be finite with shape (7,) or (B, 7), got {x0.shape}")
    x0[..., :4] = quaternion_normalize(x0[..., :4])
    shape = x0.shape
    torque_free = torque_free_derivative(j)

    def rhs(tt: float, y: np.ndarray) -> np.ndarray:
        x = y.reshape(shape)
        x_dot = torque_free(x)
        if torque is not None:
            x_dot[..., 4:] += matvec(j_inv, np.asarray(torque(tt, x), dtype=float))
        return x_dot.reshape(-1)

    if t.size == 1:
        return x0[None]
    sol = solve_ivp(
        rhs, (t[0], t[-1]), x0.reshape(-1), method=method, t_eval=t, rtol=rtol, atol=atol
    )
    if not sol.success:
        raise RuntimeError(f"attitude propagation failed: {sol.message}")
    states = sol.y.T.reshape((t.size, *shape))
    if normalize:
        states[..., :4] = quaternion_normalize(states[..., :4])
    return states


def axisymmetric_solution(
    q0: Any, omega0: Any, transverse: float, axial: float, times: Any
) -> tuple[np.ndarray, np.ndarray]:
    """Exact torque-free motion of a body with ``J = diag(It, It, Ia)`` (symmetry axis z).

    With ``λ = (Ia − It)/It · ωz`` and the angular momentum ``H`` (fixed in inertial space,
    ``ω_p = |H|/It``), ``ω = ω_p ĥ_B − λ ẑ``: the transverse rate turns about z at ``λ``
    and ``A(t) = R(ẑ, −λt) A(0) R(ĥ_I, ω_p t)`` (a body-cone rolling on a space cone).

    Parameters
    ----------
    q0 : (4,) array_like
        Initial attitude (inertial → body).
    omega0 : (3,) array_like
        Initial body rates (rad/s).
    transverse, axial : float
        Moments ``It`` (about x and y) and ``Ia`` (about z).
    times : (n,) array_like
        Times since the initial state (s).

    Returns
    -------
    q : (n, 4) numpy.ndarray
    omega : (n, 3) numpy.ndarray
    """
    q0 = np.asarray(q0, dtype=float)
    w0 = np.asarray(omega0, dtype=float)
    t = np.asarray(times, dtype=float)
    lam = (axial - transverse) / transverse * w0[2]
    h_body = np.array([transverse * w0[0], transverse * w0[1], axial * w0[2]])
    h_norm = np.linalg.norm(h_body)
    omega_p = h_norm / transverse
    h_inertial = attitude_matrix(q0).T @ (h_body / h_norm)
    c, s = np.cos(lam * t), np.sin(lam * t)
    omega = np.stack([c * w0[0] - s * w0[1], s * w0[0] + c * w0[1], np.full_like(t, w0[2])], -1)
    q_spin = axis_angle_to_quaternion(np.array([0.0, 0.0, 1.0]), -lam * t)
    q_prec = axis_angle_to_quaternion(h_inertial, omega_p * t)
    q = quaternion_multiply(quaternion_multiply(q_spin, q0), q_prec)
    return q, omega
