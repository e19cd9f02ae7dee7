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
from typing import Any, NamedTuple

import numpy as np
from scipy.integrate import solve_ivp

from filters.attitude.arrays import as_arrays, cross, matvec
from filters.attitude.inertia import moment_ratios, ratios_from_tanh, validate_inertia
from filters.attitude.kinematics import quaternion_rate
from filters.attitude.quaternion import (
    attitude_matrix,
    axis_angle_to_quaternion,
    quaternion_from_matrix,
    quaternion_multiply,
    quaternion_normalize,
)

__all__ = [
    "PrincipalInertia",
    "axisymmetric_solution",
    "propagate",
    "propagate_rk4",
    "propagate_torque_free",
    "rk4",
    "rk4_step",
    "torque_free_derivative",
    "torque_free_trajectory",
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
    *,
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


class PrincipalInertia(NamedTuple):
    """Torque-free dynamics of one or many bodies, in their principal axes.

    In principal axes Euler's equations need no matrix: ``ω̇_P = p ⊙ (ω₂ω₃, ω₃ω₁, ω₁ω₂)``
    with the inertia ratios ``p = [(J₂ − J₃)/J₁, (J₃ − J₁)/J₂, (J₁ − J₂)/J₃]``
    (:func:`~filters.attitude.inertia_ratios`, Feng et al.). The propagators below turn
    body-frame states into the principal frame once (``v_P = Pᵀ v_B``, ``q_P = r ⊗ q``
    with ``A(r) = Pᵀ``), integrate there and turn them back. RK4 commutes with a constant
    linear change of variables and the renormalisation with a rotation of ``q``, so this is
    the body-frame RK4 of the attitude core to rounding, in a fraction of the operations.

    Build it with :meth:`from_inertia` or :meth:`from_tanh`.

    Attributes
    ----------
    axes : (..., 3, 3) numpy.ndarray
        Columns: the principal axes in the body frame, right-handed (``J = P diag J_P Pᵀ``).
    ratios : (..., 3) numpy.ndarray
        Inertia ratios of the principal moments, in the order of ``axes``.
    rotation : (..., 4) numpy.ndarray
        ``r``, the quaternion of ``Pᵀ`` (body → principal frame).
    """

    axes: np.ndarray
    ratios: np.ndarray
    rotation: np.ndarray

    @classmethod
    def from_inertia(cls, inertia: Any) -> PrincipalInertia:
        """Principal axes and ratios of body-frame inertia tensors ``(..., 3, 3)`` (any
        scale; tensors are copied to numpy)."""
        j = _numpy(inertia)
        moments, axes = np.linalg.eigh(0.5 * (j + np.swapaxes(j, -1, -2)))
        # Right-handed: flip the third axis of the reflections.
        flip = np.where(np.linalg.det(axes) < 0, -1.0, 1.0)[..., None]
        axes = np.concatenate([axes[..., :2], axes[..., 2:] * flip[..., None]], axis=-1)
        return cls._of(axes, moment_ratios(moments))

    @classmethod
    def from_tanh(cls, k: Any, axes: Any = None) -> PrincipalInertia:
        """The tanh inertia parameters ``k (..., 2)`` (Feng et al.) about principal axes
        ``axes`` (identity by default): ratios ``[−tanh k₂, tanh k₁, tanh(k₂ − k₁)]``
        (:func:`~filters.attitude.ratios_from_tanh`)."""
        axes = np.eye(3) if axes is None else _numpy(axes)
        return cls._of(axes, ratios_from_tanh(_numpy(k)))

    @classmethod
    def _of(cls, axes: np.ndarray, ratios: np.ndarray) -> PrincipalInertia:
        batch = np.broadcast_shapes(axes.shape[:-2], ratios.shape[:-1])
        axes = np.broadcast_to(axes, (*batch, 3, 3)).copy()
        ratios = np.broadcast_to(ratios, (*batch, 3)).copy()
        return cls(axes, ratios, quaternion_from_matrix(np.swapaxes(axes, -1, -2)))

    def select(self, index: Any) -> PrincipalInertia:
        """The bodies ``index`` of a stack of them (leading dimension)."""
        return PrincipalInertia(self.axes[index], self.ratios[index], self.rotation[index])


def propagate_torque_free(
    q: Any,
    omega: Any,
    inertia: Any,
    dt: float,
    max_step: float = 1.0,
) -> tuple[Any, Any]:
    """Torque-free RK4 propagation of a batch of attitudes and rates over ``dt``.

    The equations are the attitude core's (:func:`~filters.attitude.rk4_step` of
    :func:`~filters.attitude.torque_free_derivative`), integrated in principal axes
    (:class:`PrincipalInertia`): the global search, the particle filter and the UKF banks
    call this thousands of times, and the core's array-API dispatch overhead dominated
    their run time. Numpy arrays and CPU tensors without gradients run every state's chain
    of steps in one compiled loop (:mod:`filters.attitude.principal_rk4`); other tensors
    (autograd, GPU) take the same arithmetic as element-wise torch operations. The tests
    check both against the core to rounding.

    Parameters
    ----------
    q : (..., 4) array or tensor
        Attitudes (inertial → body).
    omega : (..., 3) array or tensor
        Body rates (rad/s).
    inertia : (3, 3) or (..., 3, 3) array, or PrincipalInertia
        Body-frame inertia (any scale), one or one per state.
    dt : float
        Time step (s), negative to go backwards.
    max_step : float
        Largest RK4 step (s); ``dt`` is cut into ``ceil(|dt|/max_step)`` equal steps.

    Returns
    -------
    q, omega : arrays of the input kind
    """
    if dt == 0.0:
        return q, omega
    q_out, w_out = torque_free_trajectory(q, omega, [dt], inertia, max_step)
    return q_out[..., 0, :], w_out[..., 0, :]


def torque_free_trajectory(
    q: Any,
    omega: Any,
    offsets: Any,
    inertia: Any,
    max_step: float = 1.0,
) -> tuple[Any, Any]:
    """Torque-free RK4 states at many times: one chain forwards, one backwards.

    The states at the non-negative ``offsets`` are reached by one chain forwards in time
    (in increasing order), those at the negative ones by one chain backwards; the interval
    to each next offset is cut into ``ceil(|Δt|/max_step)`` equal RK4 steps, as a chain of
    :func:`propagate_torque_free` calls would do. The whole chain runs in one kernel
    (:class:`PrincipalInertia`); the frame changes are done once.

    Parameters
    ----------
    q : (..., 4) array or tensor
        Attitudes (inertial → body) at offset 0.
    omega : (..., 3) array or tensor
        Body rates (rad/s).
    offsets : (E,) array_like
        Times (s) relative to the given states, in any order and of either sign.
    inertia : (3, 3) or (..., 3, 3) array, or PrincipalInertia
        Body-frame inertia, one or one per state (broadcast against the batch shape).
    max_step : float
        Largest RK4 step (s).

    Returns
    -------
    q : (..., E, 4), omega : (..., E, 3)
        Of the input kind.
    """
    offsets = np.asarray(offsets, dtype=float).reshape(-1)
    if not isinstance(inertia, PrincipalInertia):
        inertia = PrincipalInertia.from_inertia(inertia)
    if isinstance(q, np.ndarray) or not hasattr(q, "requires_grad"):
        q, omega = np.asarray(q, dtype=float), np.asarray(omega, dtype=float)
    elif q.requires_grad or omega.requires_grad or q.device.type != "cpu":
        return _trajectory(q, omega, offsets, inertia, max_step)
    else:
        import torch

        q_np, w_np = torque_free_trajectory(
            q.numpy().astype(float, copy=False),
            omega.numpy().astype(float, copy=False),
            offsets,
            inertia,
            max_step,
        )
        return torch.from_numpy(q_np).to(q.dtype), torch.from_numpy(w_np).to(q.dtype)
    # Runaway states (a trial step of a least-squares fit) overflow to NaN, as in torch.
    with np.errstate(over="ignore", invalid="ignore"):
        return _trajectory(q, omega, offsets, inertia, max_step)


def _numpy(array: Any) -> np.ndarray:
    """A float numpy array of an array or (CPU or GPU) tensor."""
    if hasattr(array, "detach"):
        return array.detach().cpu().numpy().astype(float)
    return np.asarray(array, dtype=float)


def _trajectory(
    q: Any, omega: Any, offsets: np.ndarray, inertia: PrincipalInertia, max_step: float
) -> tuple[Any, Any]:
    """:func:`torque_free_trajectory` on arrays of one kind (numpy or torch)."""
    xp, (q, omega, axes, ratios, rotation) = as_arrays(q, omega, *inertia)
    batch = tuple(
        np.broadcast_shapes(tuple(q.shape[:-1]), tuple(omega.shape[:-1]), ratios.shape[:-1])
    )
    # Components first, (c, M): every operation of the kernel is element-wise. Per-body
    # constants are (c, M), shared ones (c, 1).
    per_body = ratios.ndim > 1
    constants = batch if per_body else ()
    r = _components(rotation, constants, xp)
    p = _components(ratios, constants, xp)
    frame = _components(xp.reshape(axes, (*axes.shape[:-2], 9)), constants, xp)
    # Body → principal frame: q_P = r ⊗ q, ω_P = Pᵀ ω.
    q_c = _left_multiply(r, _components(q, batch, xp))
    w_c = _components(omega, batch, xp)
    w_c = _mat_vec(frame[[0, 3, 6, 1, 4, 7, 2, 5, 8]], w_c)
    back = xp.concat([-r[:3], r[3:]])
    if xp is _NUMPY_NAMESPACE:  # the compiled chains write body-frame (c, E, M) states
        from filters.attitude.principal_rk4 import body_chains

        q_out, w_out = body_chains(q_c, w_c, p, back, frame, offsets, max_step=max_step)
    else:  # torch (autograd, GPU): one block, stacked
        states = _chains(q_c, w_c, p, offsets, max_step)
        q_p = xp.stack([s[0] for s in states], axis=1)
        w_p = xp.stack([s[1] for s in states], axis=1)
        # (c, E, M), back in the body frame (q = r⁻¹ ⊗ q_P, ω = P ω_P).
        q_out = _left_multiply(back, q_p)
        w_out = _mat_vec(frame, w_p)
    # (..., E, c): a transposed view of the component-first arrays
    return _from_components(q_out, batch, xp), _from_components(w_out, batch, xp)


_NUMPY_NAMESPACE = as_arrays(np.zeros(1))[0]


def _chains(q: Any, w: Any, p: Any, offsets: np.ndarray, max_step: float) -> list[tuple]:
    """Principal-frame component states ``(q (4, M), ω (3, M))`` at every offset: one RK4
    chain through the non-negative offsets in increasing order, one backwards through the
    negative ones, each interval in ``ceil(|Δt|/max_step)`` equal steps."""
    order = np.argsort(offsets, kind="stable")
    states: list[Any] = [None] * len(offsets)
    for chain in (order[offsets[order] >= 0], order[offsets[order] < 0][::-1]):
        qq, ww, t = q, w, 0.0
        for i in chain:
            dt = float(offsets[i]) - t
            steps = math.ceil(abs(dt) / max_step)
            for _ in range(steps):
                qq, ww = _rk4_principal(qq, ww, p, dt / steps)
            t = float(offsets[i])
            states[i] = (qq, ww)
    return states


def _components(x: Any, batch: tuple[int, ...], xp: Any) -> Any:
    """``(..., c)`` broadcast to ``batch`` → contiguous ``(c, M)`` (``(c, 1)`` for an
    empty batch)."""
    c = x.shape[-1]
    flat = xp.reshape(xp.broadcast_to(x, (*batch, c)), (-1, c))
    return np.ascontiguousarray(flat.T) if isinstance(flat, np.ndarray) else flat.T.contiguous()


def _from_components(x: Any, batch: tuple[int, ...], xp: Any) -> Any:
    """``(c, E, M)`` → ``(*batch, E, c)``."""
    c, e = x.shape[0], x.shape[1]
    return xp.reshape(xp.permute_dims(x, (2, 1, 0)), (*batch, e, c))


def _left_multiply(r: Any, q: Any) -> Any:
    """``r ⊗ q`` on component arrays ``r (4, M or 1)`` and ``q (4, ...)`` (``q`` may carry
    further axes between the components and ``M``, to which ``r`` is broadcast)."""
    r = r.reshape(4, *([1] * (q.ndim - 2)), r.shape[-1])
    r1, r2, r3, r4 = r[0], r[1], r[2], r[3]
    q1, q2, q3, q4 = q[0], q[1], q[2], q[3]
    parts = [
        r4 * q1 + r1 * q4 - r2 * q3 + r3 * q2,
        r4 * q2 + r2 * q4 - r3 * q1 + r1 * q3,
        r4 * q3 + r3 * q4 - r1 * q2 + r2 * q1,
        r4 * q4 - r1 * q1 - r2 * q2 - r3 * q3,
    ]
    return _stack(parts)


def _stack(parts: list[Any]) -> Any:
    """Stack arrays of one kind along a new first axis."""
    if isinstance(parts[0], np.ndarray):
        return np.stack(parts)
    import torch

    return torch.stack(parts)


def _mat_vec(matrix: Any, v: Any) -> Any:
    """``M v`` on components: ``matrix (9, M or 1)`` row-major, ``v (3, ...)``."""
    m = matrix.reshape(9, *([1] * (v.ndim - 2)), matrix.shape[-1])
    return _stack([m[3 * i] * v[0] + m[3 * i + 1] * v[1] + m[3 * i + 2] * v[2] for i in range(3)])


_NEXT = [1, 2, 0]
_LAST = [2, 0, 1]


def _rk4_principal(q: Any, w: Any, p: Any, h: float) -> tuple[Any, Any]:
    """One RK4 step ``h`` of ``q̇ = ½ Ω(ω) q``, ``ω̇ = p ⊙ (ω₂ω₃, ω₃ω₁, ω₁ω₂)`` on
    component tensors ``q (4, M)``, ``ω (3, M)``, ``p (3, M or 1)``, then the
    renormalisation of ``q``. The ½ of the kinematics is folded into the step weights.
    Numpy arrays take the compiled twin of this step
    (:mod:`filters.attitude.principal_rk4`)."""
    import torch

    join, total, sqrt = torch.cat, torch.sum, torch.sqrt

    def rates(qq: Any, ww: Any) -> tuple[Any, Any]:
        # 2 q̇ = [q₄ ω − ω × q_v, −ω·q_v]; ω × q_v and ω̇ share the cyclic shifts of ω.
        w1, w2 = ww[_NEXT], ww[_LAST]
        qv = qq[:3]
        vector = qq[3:] * ww - (w1 * qv[_LAST] - w2 * qv[_NEXT])
        return join([vector, -total(ww * qv, 0)[None]]), p * (w1 * w2)

    a_q1, a_w1 = rates(q, w)
    a_q2, a_w2 = rates(q + (0.25 * h) * a_q1, w + (0.5 * h) * a_w1)
    a_q3, a_w3 = rates(q + (0.25 * h) * a_q2, w + (0.5 * h) * a_w2)
    a_q4, a_w4 = rates(q + (0.5 * h) * a_q3, w + h * a_w3)
    q = q + (h / 12.0) * (a_q1 + 2.0 * (a_q2 + a_q3) + a_q4)
    w = w + (h / 6.0) * (a_w1 + 2.0 * (a_w2 + a_w3) + a_w4)
    return q / sqrt(total(q * q, 0))[None], w
