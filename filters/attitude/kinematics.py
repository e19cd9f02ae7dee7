"""Attitude kinematics and torque-free rigid-body dynamics.

* Kinematics ``q̇ = ½ Ω(ω) q`` with ``ω`` the body rate in the body frame (rad/s) and
  ``Ω(ω) = [[−[ω×], ω], [−ωᵀ, 0]]`` (Deng et al. 2024, eq. 11).
* Euler's equations ``J ω̇ = τ − ω × J ω`` with ``J`` in the body frame (Deng et al. 2024,
  eq. 12); with the normalised tensor ``L = J / Jzz`` this is ``ω̇ = −L⁻¹ [ω×] L ω`` (eq. 14),
  and in principal axes with the ratios ``p`` (Feng et al.) ``ω̇ = [px ωy ωz, py ωz ωx, pz ωx ωy]``.

The full state used for propagation is ``x = [q1, q2, q3, q4, ωx, ωy, ωz]``.
"""

from __future__ import annotations

from typing import Any

from filters.attitude.arrays import as_arrays, cross, matvec

__all__ = [
    "cross_matrix",
    "euler_rate",
    "euler_rate_principal",
    "omega_matrix",
    "quaternion_rate",
    "state_derivative",
    "xi_matrix",
]


def cross_matrix(v: Any) -> Any:
    """Skew-symmetric cross-product matrix ``[v×]`` with ``[v×] u = v × u``.

    Parameters
    ----------
    v : (..., 3) array

    Returns
    -------
    (..., 3, 3) array
    """
    xp, (v,) = as_arrays(v)
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    zero = xp.zeros_like(x)
    return xp.stack(
        [
            xp.stack([zero, -z, y], axis=-1),
            xp.stack([z, zero, -x], axis=-1),
            xp.stack([-y, x, zero], axis=-1),
        ],
        axis=-2,
    )


def omega_matrix(omega: Any) -> Any:
    """The 4×4 matrix ``Ω(ω)`` of ``q̇ = ½ Ω(ω) q`` (Deng et al. 2024, eq. 11).

    Parameters
    ----------
    omega : (..., 3) array
        Body rates in the body frame (rad/s).

    Returns
    -------
    (..., 4, 4) array
    """
    xp, (w,) = as_arrays(omega)
    x, y, z = w[..., 0], w[..., 1], w[..., 2]
    zero = xp.zeros_like(x)
    return xp.stack(
        [
            xp.stack([zero, z, -y, x], axis=-1),
            xp.stack([-z, zero, x, y], axis=-1),
            xp.stack([y, -x, zero, z], axis=-1),
            xp.stack([-x, -y, -z, zero], axis=-1),
        ],
        axis=-2,
    )


def xi_matrix(q: Any) -> Any:
    """The 4×3 matrix ``Ξ(q)`` with ``Ω(ω) q = Ξ(q) ω``: ``[[q4 I + [q_v×]], [−q_vᵀ]]``.

    Parameters
    ----------
    q : (..., 4) array

    Returns
    -------
    (..., 4, 3) array
    """
    xp, (q,) = as_arrays(q)
    q1, q2, q3, q4 = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return xp.stack(
        [
            xp.stack([q4, -q3, q2], axis=-1),
            xp.stack([q3, q4, -q1], axis=-1),
            xp.stack([-q2, q1, q4], axis=-1),
            xp.stack([-q1, -q2, -q3], axis=-1),
        ],
        axis=-2,
    )


def quaternion_rate(q: Any, omega: Any) -> Any:
    """Quaternion derivative ``q̇ = ½ Ω(ω) q``.

    Parameters
    ----------
    q : (..., 4) array
        Attitude quaternions (inertial → body).
    omega : (..., 3) array
        Body rates (rad/s, body frame).

    Returns
    -------
    (..., 4) array
    """
    xp, (q, w) = as_arrays(q, omega)
    qv, q4 = q[..., :3], q[..., 3:]
    vec = 0.5 * (q4 * w - cross(w, qv))
    scalar = -0.5 * xp.sum(w * qv, axis=-1, keepdims=True)
    return xp.concat([vec, scalar], axis=-1)


def euler_rate(omega: Any, inertia: Any, torque: Any = None) -> Any:
    """Angular acceleration from Euler's equations ``ω̇ = J⁻¹ (τ − ω × J ω)``.

    Parameters
    ----------
    omega : (..., 3) array
        Body rates (rad/s).
    inertia : (..., 3, 3) array
        Inertia tensor in the body frame (any consistent unit; only ratios matter without
        torque). A normalised tensor ``L = J/Jzz`` gives Deng et al. 2024, eq. 14.
    torque : (..., 3) array, optional
        External torque in the body frame, in the units of ``inertia`` times rad/s².

    Returns
    -------
    (..., 3) array
        ``ω̇`` in rad/s².
    """
    xp, (w, j, tau) = as_arrays(omega, inertia, 0.0 if torque is None else torque)
    rhs = tau - cross(w, matvec(j, w))
    return matvec(xp.linalg.inv(j), rhs)


def euler_rate_principal(omega: Any, ratios: Any) -> Any:
    """Torque-free ``ω̇`` in principal axes from the inertia ratios (Feng et al.).

    ``ω̇ = [px ωy ωz, py ωz ωx, pz ωx ωy]`` with ``px = (Jyy − Jzz)/Jxx``,
    ``py = (Jzz − Jxx)/Jyy``, ``pz = (Jxx − Jyy)/Jzz``.

    Parameters
    ----------
    omega : (..., 3) array
        Body rates (rad/s).
    ratios : (..., 3) array
        ``[px, py, pz]`` (see :func:`filters.attitude.inertia.inertia_ratios`).

    Returns
    -------
    (..., 3) array
    """
    xp, (w, p) = as_arrays(omega, ratios)
    x, y, z = w[..., 0], w[..., 1], w[..., 2]
    return p * xp.stack([y * z, z * x, x * y], axis=-1)


def state_derivative(state: Any, inertia: Any, torque: Any = None) -> Any:
    """Time derivative of the full attitude state ``x = [q, ω]`` (7 components).

    Parameters
    ----------
    state : (..., 7) array
        ``[q1, q2, q3, q4, ωx, ωy, ωz]`` (rad/s).
    inertia : (..., 3, 3) array
        Body-frame inertia tensor.
    torque : (..., 3) array, optional
        Body-frame external torque.

    Returns
    -------
    (..., 7) array
    """
    xp, (x, j) = as_arrays(state, inertia)
    q, w = x[..., :4], x[..., 4:]
    return xp.concat([quaternion_rate(q, w), euler_rate(w, j, torque)], axis=-1)
