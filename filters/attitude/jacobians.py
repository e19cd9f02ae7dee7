"""Analytic Jacobians of the attitude dynamics for extended Kalman filters.

The error state of the monocular EKF (Deng et al. 2024) is ``δx = [δq_v, δω, δl]``
(11 entries) with the multiplicative attitude error ``δq = q ⊗ q̂⁻¹`` (vector part, half the
small rotation angle), ``l = [Lxx, Lyy, Lxy, Lxz, Lyz]`` the free entries of ``L = J/Jzz``.
Its linearised dynamics are ``δẋ = C δx`` with (Deng et al. 2024, eqs. 27–31)

``C = [[−[ω×], ½ I₃, 0], [0, M, N], [0, 0, 0]]``,
``M = −∂(L⁻¹[ω×]Lω)/∂ω``, ``N = −∂(L⁻¹[ω×]Lω)/∂l``.

With ``g = L⁻¹ (ω × L ω)``: ``M = L⁻¹([Lω×] − [ω×]L)`` and the ``j``-th column of ``N`` is
``L⁻¹ (E_j g − ω × E_j ω)``, ``E_j = ∂L/∂l_j``. Every function here is checked against
torch autograd in ``tests/filters/attitude``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from filters.attitude.arrays import as_arrays, cross, matvec
from filters.attitude.inertia import inertia_from_normalized, inertia_from_tanh, ratios_from_tanh
from filters.attitude.kinematics import cross_matrix, omega_matrix, xi_matrix

__all__ = [
    "error_state_matrix",
    "euler_rate_jacobian",
    "euler_rate_jacobian_normalized",
    "euler_rate_jacobian_tanh",
    "state_jacobian",
    "transition_matrix",
]

# ∂L/∂l_j for l = [Lxx, Lyy, Lxy, Lxz, Lyz].
_BASIS = np.zeros((5, 3, 3))
_BASIS[0, 0, 0] = _BASIS[1, 1, 1] = 1.0
_BASIS[2, 0, 1] = _BASIS[2, 1, 0] = 1.0
_BASIS[3, 0, 2] = _BASIS[3, 2, 0] = 1.0
_BASIS[4, 1, 2] = _BASIS[4, 2, 1] = 1.0


def euler_rate_jacobian(omega: Any, inertia: Any) -> Any:
    """``∂ω̇/∂ω = J⁻¹([Jω×] − [ω×]J)`` of the torque-free Euler equations (Deng et al.'s ``M``).

    Parameters
    ----------
    omega : (..., 3) array
        Body rates (rad/s).
    inertia : (..., 3, 3) array
        Body-frame inertia (or ``L``).

    Returns
    -------
    (..., 3, 3) array
    """
    xp, (w, j) = as_arrays(omega, inertia)
    return xp.linalg.inv(j) @ (cross_matrix(matvec(j, w)) - cross_matrix(w) @ j)


def euler_rate_jacobian_normalized(omega: Any, l: Any) -> Any:
    """``N = ∂ω̇/∂l`` for ``l = [Lxx, Lyy, Lxy, Lxz, Lyz]`` (Deng et al. 2024, eq. 30).

    Parameters
    ----------
    omega : (..., 3) array
        Body rates (rad/s).
    l : (..., 5) array
        Free entries of ``L = J/Jzz``.

    Returns
    -------
    (..., 3, 5) array
    """
    xp, (w, l) = as_arrays(omega, l)
    big_l = inertia_from_normalized(l)
    l_inv = xp.linalg.inv(big_l)
    g = matvec(l_inv, cross(w, matvec(big_l, w)))
    basis = xp.asarray(_BASIS, dtype=w.dtype, device=getattr(w, "device", None))
    w_b = w[..., None, :]
    cols = matvec(basis, g[..., None, :]) - cross(w_b, matvec(basis, w_b))
    return xp.matrix_transpose(matvec(l_inv[..., None, :, :], cols))


def euler_rate_jacobian_tanh(omega: Any, k: Any) -> Any:
    """``∂ω̇/∂k`` for the principal-axis tanh inertia form (Feng et al.).

    With ``ω̇ = [px ωy ωz, py ωz ωx, pz ωx ωy]``, ``px = −tanh k2``, ``py = tanh k1``,
    ``pz = tanh(k2 − k1)``.

    Parameters
    ----------
    omega : (..., 3) array
        Body rates (rad/s).
    k : (..., 2) array

    Returns
    -------
    (..., 3, 2) array
    """
    xp, (w, k) = as_arrays(omega, k)
    x, y, z = w[..., 0], w[..., 1], w[..., 2]
    p = ratios_from_tanh(k)
    dpx = -(1 - p[..., 0] ** 2)  # ∂px/∂k2
    dpy = 1 - p[..., 1] ** 2  # ∂py/∂k1
    dpz = 1 - p[..., 2] ** 2  # ∂pz/∂k2 = −∂pz/∂k1
    zero = xp.zeros_like(x)
    return xp.stack(
        [
            xp.stack([zero, dpx * y * z], axis=-1),
            xp.stack([dpy * z * x, zero], axis=-1),
            xp.stack([-dpz * x * y, dpz * x * y], axis=-1),
        ],
        axis=-2,
    )


def error_state_matrix(omega: Any, params: Any, form: str = "L") -> Any:
    """The matrix ``C`` of the error-state dynamics ``δẋ = C δx`` (Deng et al. 2024, eqs. 27–33).

    ``C = [[−[ω×], ½ I₃, 0], [0, M, N], [0, 0, 0]]`` with ``M = ∂ω̇/∂ω`` and
    ``N = ∂ω̇/∂p`` for the inertia parameters ``p`` of the chosen form.

    Parameters
    ----------
    omega : (..., 3) array
        Estimated body rates (rad/s).
    params : (..., 5) or (..., 2) array
        ``[Lxx, Lyy, Lxy, Lxz, Lyz]`` (form ``"L"``, Deng et al. 2024) or ``[k1, k2]``
        (form ``"k"``, the principal-axis tanh form of Feng et al.).
    form : {"L", "k"}

    Returns
    -------
    (..., 6 + m, 6 + m) array
        Rows/columns ordered ``[δq_v (3), δω (3), δp (m)]``; 11×11 for ``"L"``, 8×8 for ``"k"``.
    """
    xp, (w, p) = as_arrays(omega, params)
    if form == "L":
        inertia, n_block = inertia_from_normalized(p), euler_rate_jacobian_normalized(w, p)
    elif form == "k":
        inertia, n_block = inertia_from_tanh(p), euler_rate_jacobian_tanh(w, p)
    else:
        raise ValueError(f"inertia form must be 'L' or 'k', got {form!r}")
    m = p.shape[-1]
    batch = np.broadcast_shapes(tuple(w.shape[:-1]), tuple(p.shape[:-1]))
    kwargs = {"dtype": w.dtype, "device": getattr(w, "device", None)}
    top = xp.concat(
        [
            xp.broadcast_to(-cross_matrix(w), (*batch, 3, 3)),
            xp.broadcast_to(0.5 * xp.eye(3, **kwargs), (*batch, 3, 3)),
            xp.zeros((*batch, 3, m), **kwargs),
        ],
        axis=-1,
    )
    middle = xp.concat(
        [
            xp.zeros((*batch, 3, 3), **kwargs),
            xp.broadcast_to(euler_rate_jacobian(w, inertia), (*batch, 3, 3)),
            xp.broadcast_to(n_block, (*batch, 3, m)),
        ],
        axis=-1,
    )
    bottom = xp.zeros((*batch, m, 6 + m), **kwargs)
    return xp.concat([top, middle, bottom], axis=-2)


def state_jacobian(state: Any, inertia: Any) -> Any:
    """``∂ẋ/∂x`` (7×7) of the full torque-free state ``x = [q, ω]``.

    ``∂q̇/∂q = ½ Ω(ω)``, ``∂q̇/∂ω = ½ Ξ(q)``, ``∂ω̇/∂q = 0``, ``∂ω̇/∂ω`` from
    :func:`euler_rate_jacobian`.

    Parameters
    ----------
    state : (..., 7) array
    inertia : (..., 3, 3) array

    Returns
    -------
    (..., 7, 7) array
    """
    xp, (x, j) = as_arrays(state, inertia)
    q, w = x[..., :4], x[..., 4:]
    batch = x.shape[:-1]
    top = xp.concat([0.5 * omega_matrix(w), 0.5 * xi_matrix(q)], axis=-1)
    bottom = xp.concat(
        [
            xp.zeros((*batch, 3, 4), dtype=x.dtype, device=getattr(x, "device", None)),
            xp.broadcast_to(euler_rate_jacobian(w, j), (*batch, 3, 3)),
        ],
        axis=-1,
    )
    return xp.concat([top, bottom], axis=-2)


def transition_matrix(matrix: Any, dt: float, terms: int = 12) -> Any:
    """Discrete state-transition matrix ``Φ = exp(C Δt)`` (Deng et al. 2024, eq. 32, exact form).

    numpy: scaling and squaring of the Taylor series, batched — the argument is halved until
    its 1-norm is at most ½, ``terms`` terms are summed (truncation ≈ 2⁻¹³/13! ≈ 1e-14
    relative with the default) and the result squared back. Orders of magnitude faster than
    ``scipy.linalg.expm`` on many small matrices and equal to it to rounding: 1e-13 relative,
    times ``‖C Δt‖₁`` where that exceeds 1 (both square their result back, which amplifies
    rounding in proportion; tested).
    torch: ``torch.linalg.matrix_exp`` (differentiable, any device).

    Parameters
    ----------
    matrix : (..., n, n) array
        Continuous-time system matrices ``C``.
    dt : float
        Time step (s).
    terms : int
        Taylor terms of the numpy path.

    Returns
    -------
    (..., n, n) array
    """
    _, (c,) = as_arrays(matrix)
    if not isinstance(c, np.ndarray):
        import torch

        return torch.linalg.matrix_exp(c * dt)
    a = c * dt
    norm = float(np.max(np.sum(np.abs(a), axis=-2))) if a.size else 0.0
    squarings = max(0, math.ceil(math.log2(norm / 0.5))) if norm > 0.5 else 0
    a = a / 2.0**squarings
    eye = np.broadcast_to(np.eye(a.shape[-1]), a.shape)
    result = eye.copy()
    term = eye
    for j in range(1, terms + 1):
        term = term @ a / j
        result = result + term
    for _ in range(squarings):
        result = result @ result
    return result
