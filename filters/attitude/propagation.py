"""Propagation of the attitude state ``x = [q1, q2, q3, q4, ωx, ωy, ωz]``.

* :func:`rk4_step` / :func:`propagate_rk4`: fixed-step classical Runge–Kutta with quaternion
  renormalisation, batched over any leading dimensions (particles × sigma points …), numpy
  or torch. This is what filters use.
* :func:`propagate`: adaptive integration with scipy's DOP853 for truth simulation.
* :func:`axisymmetric_solution`: the exact torque-free motion of an axisymmetric body, the
  reference the integrators are tested against.
"""

from __future__ import annotations

import math
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
    "propagate_torque_free",
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


def propagate_torque_free(
    q: Any,
    omega: Any,
    inertia: Any,
    dt: float,
    max_step: float = 1.0,
    inertia_inverse: Any = None,
) -> tuple[Any, Any]:
    """Torque-free RK4 propagation of a batch of attitudes and rates over ``dt``.

    The equations are the attitude core's (:func:`~filters.attitude.rk4_step` of
    :func:`~filters.attitude.torque_free_derivative`), written in :func:`_torch_rk4` as a
    handful of fused torch operations: the global search, the particle filter and the UKF
    banks call this thousands of times, and the core's array-API dispatch overhead
    dominated their run time (3–5× slower). The tests check it against the core to
    rounding. numpy inputs are wrapped as tensors (no copy) and returned as numpy.

    Parameters
    ----------
    q : (..., 4) array or tensor
        Attitudes (inertial → body).
    omega : (..., 3) array or tensor
        Body rates (rad/s).
    inertia : (3, 3) or (..., 3, 3) array
        Body-frame inertia (any scale).
    dt : float
        Time step (s), negative to go backwards.
    max_step : float
        Largest RK4 step (s); ``dt`` is cut into ``ceil(|dt|/max_step)`` equal steps.
    inertia_inverse : array, optional
        ``J⁻¹`` when the caller has it (torch path; saves one inverse per call).

    Returns
    -------
    q, omega : arrays of the input kind
    """
    if dt == 0.0:
        return q, omega
    steps = max(1, math.ceil(abs(dt) / max_step))
    h = dt / steps
    if not isinstance(q, np.ndarray):
        return _torch_rk4(q, omega, inertia, inertia_inverse, h, steps)
    import torch

    q_t, w_t = _torch_rk4(
        torch.from_numpy(np.ascontiguousarray(q, dtype=float)),
        torch.from_numpy(np.ascontiguousarray(omega, dtype=float)),
        np.asarray(inertia, dtype=float),
        inertia_inverse,
        h,
        steps,
    )
    return q_t.numpy(), w_t.numpy()


def _torch_rk4(
    q: Any, omega: Any, inertia: Any, inertia_inverse: Any, h: float, steps: int
) -> tuple[Any, Any]:
    """``steps`` RK4 steps of ``h`` of ``q̇ = ½ Ω(ω) q`` (the core's
    :func:`~filters.attitude.quaternion_rate`: ``q̇_v = ½ (q₄ ω − ω × q_v)``,
    ``q̇₄ = −½ ω·q_v``) and ``ω̇ = −J⁻¹ (ω × J ω)``, quaternions renormalised after each
    step as in :func:`~filters.attitude.rk4_step`."""
    import torch

    j = torch.as_tensor(inertia, dtype=q.dtype, device=q.device)
    j_inv = (
        torch.linalg.inv(j)
        if inertia_inverse is None
        else torch.as_tensor(inertia_inverse, dtype=q.dtype, device=q.device)
    )
    cross = torch.linalg.cross
    if j.ndim == 2:

        def euler(w: Any) -> Any:
            return -(cross(w, w @ j.T) @ j_inv.T)

    else:

        def euler(w: Any) -> Any:
            h_w = (j @ w.unsqueeze(-1)).squeeze(-1)
            return -(j_inv @ cross(w, h_w).unsqueeze(-1)).squeeze(-1)

    def derivative(qq: Any, w: Any) -> tuple[Any, Any]:
        qv, q4 = qq[..., :3], qq[..., 3:]
        vec = 0.5 * (q4 * w - cross(w, qv))
        scalar = -0.5 * (w * qv).sum(dim=-1, keepdim=True)
        return torch.cat([vec, scalar], dim=-1), euler(w)

    for _ in range(steps):
        dq1, dw1 = derivative(q, omega)
        dq2, dw2 = derivative(q + 0.5 * h * dq1, omega + 0.5 * h * dw1)
        dq3, dw3 = derivative(q + 0.5 * h * dq2, omega + 0.5 * h * dw2)
        dq4, dw4 = derivative(q + h * dq3, omega + h * dw3)
        q = q + (h / 6.0) * (dq1 + 2.0 * dq2 + 2.0 * dq3 + dq4)
        omega = omega + (h / 6.0) * (dw1 + 2.0 * dw2 + 2.0 * dw3 + dw4)
        q = q / torch.linalg.vector_norm(q, dim=-1, keepdim=True)
    return q, omega
