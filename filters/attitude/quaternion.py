"""Quaternion algebra and attitude parameterisations (scalar-last, passive).

Conventions (``docs/conventions.md``):

* ``q = [q1, q2, q3, q4]`` with ``q4`` the scalar part, unit norm.
* The attitude matrix maps inertial vectors into the body frame, ``v_B = A(q) v_I``, with
  ``A(q) = (q4² − |q_v|²) I + 2 q_v q_vᵀ − 2 q4 [q_v×]`` (Deng et al. 2024, eq. 10; Shuster 1993).
* The product ``⊗`` composes like the matrices: ``A(p ⊗ q) = A(p) A(q)`` (Markley &
  Crassidis 2014, eq. 2.82).
* ``scipy.spatial.transform.Rotation.from_quat(q).as_matrix()`` equals ``A(q).T``.

All functions broadcast over leading dimensions and accept numpy arrays or torch tensors
(returning the same kind). Angles are in radians.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from filters.attitude.arrays import as_arrays, cross

__all__ = [
    "attitude_angle",
    "attitude_matrix",
    "axis_angle_to_quaternion",
    "euler321_to_quaternion",
    "grp_to_quaternion",
    "mrp_to_quaternion",
    "quaternion_canonical",
    "quaternion_conjugate",
    "quaternion_from_matrix",
    "quaternion_inverse",
    "quaternion_mean",
    "quaternion_multiply",
    "quaternion_normalize",
    "quaternion_to_euler321",
    "quaternion_to_grp",
    "quaternion_to_mrp",
    "quaternion_to_rotation_vector",
    "random_quaternion",
    "rotate",
    "rotation_vector_to_quaternion",
]

# Below this rotation angle (rad) the small-angle series replace sin(x)/x forms.
_SMALL_ANGLE = 1e-4
# Below this cos(pitch) the 3-2-1 angles are treated as gimbal-locked (roll set to zero).
_GIMBAL_LOCK = 1e-10


def quaternion_multiply(p: Any, q: Any) -> Any:
    """Quaternion product ``p ⊗ q`` such that ``A(p ⊗ q) = A(p) A(q)``.

    ``p ⊗ q = [p4 q_v + q4 p_v − p_v × q_v,  p4 q4 − p_v · q_v]``.

    Parameters
    ----------
    p, q : (..., 4) array
        Scalar-last quaternions (broadcastable).

    Returns
    -------
    (..., 4) array
    """
    xp, (p, q) = as_arrays(p, q)
    pv, p4 = p[..., :3], p[..., 3:]
    qv, q4 = q[..., :3], q[..., 3:]
    vec = p4 * qv + q4 * pv - cross(pv, qv)
    scalar = p4 * q4 - xp.sum(pv * qv, axis=-1, keepdims=True)
    return xp.concat([vec, scalar], axis=-1)


def quaternion_conjugate(q: Any) -> Any:
    """Conjugate ``[−q_v, q4]``; the inverse of a unit quaternion.

    Parameters
    ----------
    q : (..., 4) array
        Quaternions of any norm.

    Returns
    -------
    (..., 4) array
        Of the same norm; for unit ``q`` the opposite rotation.
    """
    xp, (q,) = as_arrays(q)
    return xp.concat([-q[..., :3], q[..., 3:]], axis=-1)


def quaternion_inverse(q: Any) -> Any:
    """Inverse ``q* / |q|²`` (equal to the conjugate for unit quaternions).

    Parameters
    ----------
    q : (..., 4) array
        Non-zero quaternions.

    Returns
    -------
    (..., 4) array
        ``q⁻¹`` with ``q ⊗ q⁻¹ = [0, 0, 0, 1]``.
    """
    xp, (q,) = as_arrays(q)
    return quaternion_conjugate(q) / xp.sum(q * q, axis=-1, keepdims=True)


def quaternion_normalize(q: Any) -> Any:
    """Scale quaternions to unit norm.

    Parameters
    ----------
    q : (..., 4) array
        Non-zero quaternions.

    Returns
    -------
    (..., 4) array
        ``q / |q|``.

    Raises
    ------
    ValueError
        If a quaternion has zero or non-finite norm (numpy input only; torch input is left
        unchecked so it stays differentiable and traceable).
    """
    xp, (q,) = as_arrays(q)
    norm = xp.linalg.vector_norm(q, axis=-1, keepdims=True)
    if isinstance(norm, np.ndarray) and not np.all(np.isfinite(norm) & (norm > 0)):
        raise ValueError("quaternion has zero or non-finite norm")
    return q / norm


def quaternion_canonical(q: Any) -> Any:
    """Sign-canonical form with ``q4 ≥ 0`` (``q`` and ``−q`` are the same attitude).

    Parameters
    ----------
    q : (..., 4) array
        Quaternions.

    Returns
    -------
    (..., 4) array
        ``q`` where ``q4 ≥ 0``, else ``−q``.
    """
    xp, (q,) = as_arrays(q)
    return xp.where(q[..., 3:] < 0, -q, q)


def attitude_matrix(q: Any) -> Any:
    """Attitude matrix ``A(q)`` mapping inertial vectors into the body frame.

    ``A(q) = (q4² − |q_v|²) I + 2 q_v q_vᵀ − 2 q4 [q_v×]`` (Deng et al. 2024, eq. 10). The input
    need not be normalised exactly; it is used as given.

    Parameters
    ----------
    q : (..., 4) array
        Unit quaternions, scalar last.

    Returns
    -------
    (..., 3, 3) array
        ``v_B = A v_I``.
    """
    xp, (q,) = as_arrays(q)
    q1, q2, q3, q4 = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    rows = [
        [q1 * q1 - q2 * q2 - q3 * q3 + q4 * q4, 2 * (q1 * q2 + q3 * q4), 2 * (q1 * q3 - q2 * q4)],
        [2 * (q1 * q2 - q3 * q4), -q1 * q1 + q2 * q2 - q3 * q3 + q4 * q4, 2 * (q2 * q3 + q1 * q4)],
        [2 * (q1 * q3 + q2 * q4), 2 * (q2 * q3 - q1 * q4), -q1 * q1 - q2 * q2 + q3 * q3 + q4 * q4],
    ]
    return xp.stack([xp.stack(row, axis=-1) for row in rows], axis=-2)


def rotate(q: Any, v: Any) -> Any:
    """Express inertial vectors in the body frame: ``A(q) v``.

    Parameters
    ----------
    q : (..., 4) array
        Unit quaternions.
    v : (..., 3) array
        Vectors in the inertial frame (broadcastable against ``q[..., :3]``).

    Returns
    -------
    (..., 3) array
        The vectors in the body frame.
    """
    xp, (q, v) = as_arrays(q, v)
    qv, q4 = q[..., :3], q[..., 3:]
    return (
        (q4 * q4 - xp.sum(qv * qv, axis=-1, keepdims=True)) * v
        + 2 * qv * xp.sum(qv * v, axis=-1, keepdims=True)
        - 2 * q4 * cross(qv, v)
    )


def quaternion_from_matrix(matrix: Any) -> Any:
    """Quaternion of an attitude matrix, robust for every rotation.

    Uses the four-candidate method of Shepperd (1978) / Markley (2008): the candidate built
    from the largest of ``tr A`` and the diagonal entries is always well conditioned.

    Parameters
    ----------
    matrix : (..., 3, 3) array
        Proper orthogonal matrices (``v_B = A v_I``).

    Returns
    -------
    (..., 4) array
        Unit quaternions with ``q4 ≥ 0``.
    """
    xp, (a,) = as_arrays(matrix)
    a11, a12, a13 = a[..., 0, 0], a[..., 0, 1], a[..., 0, 2]
    a21, a22, a23 = a[..., 1, 0], a[..., 1, 1], a[..., 1, 2]
    a31, a32, a33 = a[..., 2, 0], a[..., 2, 1], a[..., 2, 2]
    trace = a11 + a22 + a33
    # Each row is 4·q_k·q (unnormalised) for the pivot k = 1, 2, 3, 4 (Markley 2008, eq. 7).
    candidates = xp.stack(
        [
            xp.stack([1 + 2 * a11 - trace, a12 + a21, a13 + a31, a23 - a32], axis=-1),
            xp.stack([a21 + a12, 1 + 2 * a22 - trace, a23 + a32, a31 - a13], axis=-1),
            xp.stack([a31 + a13, a32 + a23, 1 + 2 * a33 - trace, a12 - a21], axis=-1),
            xp.stack([a23 - a32, a31 - a13, a12 - a21, 1 + trace], axis=-1),
        ],
        axis=-2,
    )
    pivots = xp.stack([a11, a22, a33, trace], axis=-1)
    best = xp.argmax(pivots, axis=-1)
    mask = xp.astype(best[..., None] == xp.arange(4, device=_device(a)), a.dtype)
    q = xp.sum(mask[..., :, None] * candidates, axis=-2)
    return quaternion_canonical(quaternion_normalize(q))


def _device(array: Any) -> Any:
    return getattr(array, "device", None) if not isinstance(array, np.ndarray) else None


def _half_angle_sinc(angle: Any, xp: Any) -> Any:
    """``sin(θ/2)/θ`` with its series below ``_SMALL_ANGLE`` (autograd-safe)."""
    small = angle < _SMALL_ANGLE
    safe = xp.where(small, xp.ones_like(angle), angle)
    return xp.where(small, 0.5 - angle * angle / 48.0, xp.sin(safe / 2) / safe)


def rotation_vector_to_quaternion(rotvec: Any) -> Any:
    """Quaternion of a rotation vector ``θ e`` (rad): ``[e sin(θ/2), cos(θ/2)]``.

    Parameters
    ----------
    rotvec : (..., 3) array
        Rotation vectors (rad); the rotation is passive like ``A(q)``.

    Returns
    -------
    (..., 4) array
    """
    xp, (rv,) = as_arrays(rotvec)
    angle = xp.linalg.vector_norm(rv, axis=-1, keepdims=True)
    return xp.concat([rv * _half_angle_sinc(angle, xp), xp.cos(angle / 2)], axis=-1)


def axis_angle_to_quaternion(axis: Any, angle: Any) -> Any:
    """Quaternion of a rotation by ``angle`` (rad) about the unit vector ``axis``.

    Parameters
    ----------
    axis : (..., 3) array
        Rotation axes (normalised here).
    angle : (...) array
        Rotation angles in radians.

    Returns
    -------
    (..., 4) array
    """
    xp, (axis, angle) = as_arrays(axis, angle)
    axis = axis / xp.linalg.vector_norm(axis, axis=-1, keepdims=True)
    half = angle[..., None] / 2
    return xp.concat([axis * xp.sin(half), xp.cos(half) * xp.ones_like(axis[..., :1])], axis=-1)


def quaternion_to_rotation_vector(q: Any) -> Any:
    """Rotation vector ``θ e`` (rad) of a quaternion, with ``θ ∈ [0, π]``.

    Parameters
    ----------
    q : (..., 4) array
        Unit quaternions.

    Returns
    -------
    (..., 3) array
    """
    xp, (q,) = as_arrays(q)
    q = quaternion_canonical(q)
    vnorm = xp.linalg.vector_norm(q[..., :3], axis=-1, keepdims=True)
    angle = 2 * xp.atan2(vnorm, q[..., 3:])
    small = vnorm < _SMALL_ANGLE / 2
    safe = xp.where(small, xp.ones_like(vnorm), vnorm)
    # θ/|q_v| = 2 atan(|q_v|/q4)/|q_v| → 2/q4 · (1 − |q_v|²/(3 q4²)) as |q_v| → 0.
    q4 = xp.where(small, q[..., 3:], xp.ones_like(vnorm))
    scale = xp.where(small, 2 / q4 * (1 - vnorm * vnorm / (3 * q4 * q4)), angle / safe)
    return q[..., :3] * scale


def grp_to_quaternion(p: Any, a: float = 1.0, f: float | None = None) -> Any:
    """Quaternion of generalized Rodrigues parameters (Crassidis & Markley 2003, eq. 17).

    ``δq4 = (−a|p|² + f √(f² + (1 − a²)|p|²)) / (f² + |p|²)``,
    ``δq_v = (a + δq4) p / f``.

    Parameters
    ----------
    p : (..., 3) array
        Generalized Rodrigues parameters.
    a : float
        ``a ∈ [0, 1]``; ``a = 0, f = 1`` gives the Gibbs vector, ``a = f = 1`` the modified
        Rodrigues parameters.
    f : float, optional
        Scale; defaults to ``2 (a + 1)``, for which ``|p|`` ≈ the rotation angle in radians
        when small (the USQUE choice).

    Returns
    -------
    (..., 4) array
    """
    f = 2.0 * (a + 1.0) if f is None else f
    xp, (p,) = as_arrays(p)
    p2 = xp.sum(p * p, axis=-1, keepdims=True)
    q4 = (-a * p2 + f * xp.sqrt(f * f + (1 - a * a) * p2)) / (f * f + p2)
    return xp.concat([(a + q4) * p / f, q4], axis=-1)


def quaternion_to_grp(q: Any, a: float = 1.0, f: float | None = None) -> Any:
    """Generalized Rodrigues parameters ``p = f q_v / (a + q4)`` (Crassidis & Markley 2003).

    The quaternion is taken sign-canonical first, so ``p`` describes the shorter rotation.

    Parameters
    ----------
    q : (..., 4) array
        Unit quaternions.
    a, f : float
        See :func:`grp_to_quaternion`.

    Returns
    -------
    (..., 3) array
    """
    f = 2.0 * (a + 1.0) if f is None else f
    _xp, (q,) = as_arrays(q)
    q = quaternion_canonical(q)
    return f * q[..., :3] / (a + q[..., 3:])


def mrp_to_quaternion(p: Any) -> Any:
    """Quaternion of modified Rodrigues parameters ``p = q_v / (1 + q4)``.

    Parameters
    ----------
    p : (..., 3) array
        Modified Rodrigues parameters (``|p| > 1`` describes the longer rotation).

    Returns
    -------
    (..., 4) array
        Unit quaternions, with ``q4 < 0`` where ``|p| > 1``.
    """
    return grp_to_quaternion(p, a=1.0, f=1.0)


def quaternion_to_mrp(q: Any) -> Any:
    """Modified Rodrigues parameters of the shorter rotation (``|p| ≤ 1``).

    Parameters
    ----------
    q : (..., 4) array
        Unit quaternions (``q`` and ``−q`` give the same parameters).

    Returns
    -------
    (..., 3) array
        ``p = f q_v / (a + q4)`` of :func:`quaternion_to_grp` with ``a = f = 1``.
    """
    return quaternion_to_grp(q, a=1.0, f=1.0)


def euler321_to_quaternion(angles: Any) -> Any:
    """Quaternion of 3-2-1 (yaw, pitch, roll) Euler angles (Gou et al. 2016, eq. 2).

    ``A = R1(φ) R2(θ) R3(ψ)``: first yaw ``ψ`` about z, then pitch ``θ`` about the new y,
    then roll ``φ`` about the new x.

    Parameters
    ----------
    angles : (..., 3) array
        ``[ψ, θ, φ]`` in radians.

    Returns
    -------
    (..., 4) array
    """
    xp, (angles,) = as_arrays(angles)
    zeros = xp.zeros_like(angles[..., :1])
    half = angles / 2
    s, c = xp.sin(half), xp.cos(half)
    qz = xp.concat([zeros, zeros, s[..., 0:1], c[..., 0:1]], axis=-1)
    qy = xp.concat([zeros, s[..., 1:2], zeros, c[..., 1:2]], axis=-1)
    qx = xp.concat([s[..., 2:3], zeros, zeros, c[..., 2:3]], axis=-1)
    return quaternion_multiply(quaternion_multiply(qx, qy), qz)


def quaternion_to_euler321(q: Any) -> Any:
    """3-2-1 Euler angles ``[ψ, θ, φ]`` (rad) of a quaternion, ``θ ∈ [−π/2, π/2]``.

    Parameters
    ----------
    q : (..., 4) array

    Returns
    -------
    (..., 3) array
        At the gimbal lock ``θ = ±π/2`` only ``ψ ∓ φ`` is defined; then ``φ`` is returned 0.
    """
    xp, (q,) = as_arrays(q)
    a = attitude_matrix(q)
    sin_theta = xp.clip(-a[..., 0, 2], -1.0, 1.0)
    # cos θ from the first row is accurate near the lock, where asin(sin θ) is not.
    cos_theta = xp.sqrt(a[..., 0, 0] ** 2 + a[..., 0, 1] ** 2)
    theta = xp.atan2(sin_theta, cos_theta)
    locked = cos_theta < _GIMBAL_LOCK
    psi = xp.where(
        locked, xp.atan2(-a[..., 1, 0], a[..., 1, 1]), xp.atan2(a[..., 0, 1], a[..., 0, 0])
    )
    phi = xp.where(locked, xp.zeros_like(psi), xp.atan2(a[..., 1, 2], a[..., 2, 2]))
    return xp.stack([psi, theta, phi], axis=-1)


def attitude_angle(p: Any, q: Any) -> Any:
    """Rotation angle (rad, in ``[0, π]``) between two attitudes.

    ``2 atan2(|δq_v|, |δq4|)`` with ``δq = p ⊗ q⁻¹``; insensitive to the sign of either
    quaternion.

    Parameters
    ----------
    p, q : (..., 4) array
        Unit quaternions.

    Returns
    -------
    (...) array
    """
    xp, (p, q) = as_arrays(p, q)
    dq = quaternion_multiply(p, quaternion_conjugate(q))
    return 2 * xp.atan2(xp.linalg.vector_norm(dq[..., :3], axis=-1), xp.abs(dq[..., 3]))


def random_quaternion(
    size: int | tuple[int, ...] = (), rng: np.random.Generator | int | None = None
) -> np.ndarray:
    """Attitudes uniformly distributed on SO(3) (normalised 4-D Gaussians).

    Parameters
    ----------
    size : int or tuple of int
        Leading shape of the output.
    rng : numpy.random.Generator or int, optional
        Random generator or seed.

    Returns
    -------
    (*size, 4) numpy.ndarray
        Sign-canonical unit quaternions.
    """
    rng = np.random.default_rng(rng)
    shape = (size,) if isinstance(size, int) else tuple(size)
    q = rng.standard_normal((*shape, 4))
    return quaternion_canonical(q / np.linalg.norm(q, axis=-1, keepdims=True))


def quaternion_mean(q: Any, weights: Any = None) -> Any:
    """Weighted average attitude (Markley, Cheng, Crassidis & Oshman 2007).

    The maximiser of ``Σ w_i (qᵀ q_i)²`` on the unit sphere: the eigenvector of
    ``M = Σ w_i q_i q_iᵀ`` for its largest eigenvalue. Insensitive to the signs of the
    ``q_i``, unlike a linear blend.

    Parameters
    ----------
    q : (..., n, 4) array
        Unit quaternions to average over axis ``-2``.
    weights : (..., n) array, optional
        Non-negative weights (equal when omitted).

    Returns
    -------
    (..., 4) array
        Sign-canonical mean quaternion.
    """
    if weights is None:
        xp, (q,) = as_arrays(q)
        weights = xp.ones_like(q[..., 0])
    xp, (q, weights) = as_arrays(q, weights)
    m = xp.sum(weights[..., :, None, None] * (q[..., :, None] * q[..., None, :]), axis=-3)
    _, vectors = xp.linalg.eigh(m)
    return quaternion_canonical(vectors[..., :, -1])
