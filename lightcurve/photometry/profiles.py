"""Attitude profiles of stabilised satellites: the attitude a control system holds.

A profile gives the reference attitude ``q_ref(t)`` (inertial → body, scalar last,
``v_B = A(q) v_I``) from the object's geocentric position ``r``, velocity ``v`` and the
object → Sun vector ``s`` at each epoch; a fixed offset ``q_off`` (a small mis-pointing, or
any fixed rotation of the body relative to the profile's frame) composes on the body side:

``q = q_off ⊗ q_ref``, i.e. ``A(q) = A(q_off) A(q_ref)``.

Profiles
--------
``torque-free``
    Not a stabilised profile: the body tumbles freely
    (:func:`lightcurve.photometry.simulate.truth_states`).
``inertial``
    ``A(q_ref)`` constant (the identity unless a reference attitude is given): the body axes
    are fixed in the inertial frame.
``nadir``
    Local vertical / local horizontal (LVLH): body ``+z`` to nadir (``−r̂``), body ``+y``
    along the negative orbit normal ``−ĥ`` (``ĥ = r × v / |r × v|``), body ``+x = y × z``
    (along the velocity on a circular orbit). With **yaw steering** the body turns about
    ``+z`` so that the Sun lies in the body ``x–z`` half-plane of positive ``x``:
    ``y = ẑ × ŝ / |ẑ × ŝ|`` (the solar-array axis ``y`` stays perpendicular to the Sun, as
    GNSS satellites do; Bar-Sever 1996, "A new model for GPS yaw attitude", J. Geodesy 70).
    Where the Sun is on the nadir line (``|ẑ × ŝ| < 10⁻⁹``) the yaw is undefined and the
    LVLH axes are kept.
``sun-pointing``
    Body ``+z`` to the Sun (``ŝ``); secondary constraint: body ``+x`` along the component
    of the inertial (GCRS) pole ``Ẑ`` perpendicular to ``ŝ``, i.e. towards the north
    celestial pole, ``y = z × x``. The Sun's declination never exceeds 23.44°, so the
    constraint is never degenerate for Earth-orbiting objects.

Offsets are given as 3-2-1 Euler angles ``[roll φ, pitch θ, yaw ψ]`` about the body axes of
the profile frame (``A(q_off) = R1(φ) R2(θ) R3(ψ)``, see ``docs/conventions.md``).
"""

from __future__ import annotations

import numpy as np

from filters.attitude import (
    euler321_to_quaternion,
    quaternion_canonical,
    quaternion_conjugate,
    quaternion_from_matrix,
    quaternion_multiply,
    quaternion_normalize,
    quaternion_to_euler321,
    quaternion_to_rotation_vector,
)
from lightcurve.io.observations import OBJECT_COLUMNS, Observations

__all__ = [
    "PROFILES",
    "STABILISED_PROFILES",
    "body_rates",
    "euler_offsets_deg",
    "inertial_attitude",
    "nadir_attitude",
    "offset_quaternion",
    "profile_attitude",
    "profile_states",
    "sun_pointing_attitude",
]

#: Every attitude profile; ``torque-free`` is today's tumbling propagation.
PROFILES = ("torque-free", "inertial", "nadir", "sun-pointing")
#: The profiles a control system holds (everything but ``torque-free``).
STABILISED_PROFILES = ("inertial", "nadir", "sun-pointing")

_DEGENERATE = 1e-9


def _unit(v: np.ndarray, what: str) -> np.ndarray:
    norm = np.linalg.norm(v, axis=-1, keepdims=True)
    if not np.all(norm > 0) or not np.all(np.isfinite(norm)):
        raise ValueError(f"{what} must be finite and non-zero at every epoch")
    return v / norm


def _as_vectors(v: np.ndarray, what: str) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    if v.ndim != 2 or v.shape[1] != 3:
        raise ValueError(f"{what} must have shape (n, 3), got {v.shape}")
    return v


def _from_axes(x: np.ndarray, y: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Quaternions whose attitude matrices have the body axes ``x, y, z`` (inertial
    components) as rows, with the sign continuous in time."""
    matrix = np.stack([x, y, z], axis=-2)
    return _continuous(quaternion_from_matrix(matrix))


def _continuous(q: np.ndarray) -> np.ndarray:
    """Flip quaternion signs so that consecutive ones have a positive dot product."""
    q = np.array(q, dtype=float)
    if len(q) > 1:
        flips = np.cumsum(np.r_[0, np.sum(q[1:] * q[:-1], axis=-1) < 0]) % 2
        q[flips == 1] *= -1.0
    return q


def nadir_attitude(
    position: np.ndarray,
    velocity: np.ndarray | None,
    sun: np.ndarray | None = None,
    yaw_steering: bool = False,
) -> np.ndarray:
    """Nadir-pointing (LVLH) attitudes, optionally yaw-steered (see the module doc).

    Parameters
    ----------
    position, velocity : (n, 3) array
        Geocentric position and velocity of the object, inertial frame (any consistent units).
        A yaw-steered profile needs no velocity: where the Sun is on the nadir line (its yaw
        undefined) the ``y`` axis is then east, ``Ẑ × r̂`` (``Ẑ`` the inertial pole),
        instead of the negative orbit normal.
    sun : (n, 3) array, optional
        Object → Sun vectors, inertial frame (any unit); required with ``yaw_steering``.
    yaw_steering : bool
        Turn about the nadir axis to keep the Sun in the body ``x–z`` plane.

    Returns
    -------
    (n, 4) numpy.ndarray
        Quaternions inertial → body, sign continuous in time.
    """
    r = _unit(_as_vectors(position, "position"), "position")
    if velocity is None:
        if not yaw_steering:
            raise ValueError("the nadir profile needs the velocity unless it is yaw-steered")
        east = np.cross([0.0, 0.0, 1.0], r)
        y = east / np.maximum(np.linalg.norm(east, axis=-1, keepdims=True), _DEGENERATE)
    else:
        y = -_unit(np.cross(r, _as_vectors(velocity, "velocity")), "the orbit normal r × v")
    z = -r
    if yaw_steering:
        if sun is None:
            raise ValueError("yaw steering needs the object → Sun vectors")
        s = _unit(_as_vectors(sun, "sun"), "object → Sun vector")
        across = np.cross(z, s)
        norm = np.linalg.norm(across, axis=-1, keepdims=True)
        y = np.where(norm > _DEGENERATE, across / np.maximum(norm, _DEGENERATE), y)
    return _from_axes(np.cross(y, z), y, z)


def sun_pointing_attitude(sun: np.ndarray) -> np.ndarray:
    """Sun-pointing attitudes: body ``+z`` to the Sun, ``+x`` towards the inertial pole.

    Parameters
    ----------
    sun : (n, 3) array
        Object → Sun vectors, inertial frame (any unit).

    Returns
    -------
    (n, 4) numpy.ndarray
    """
    z = _unit(_as_vectors(sun, "sun"), "object → Sun vector")
    pole = np.array([0.0, 0.0, 1.0])
    x = pole - (z @ pole)[:, None] * z
    x = _unit(x, "the pole's component perpendicular to the Sun (Sun at a pole?)")
    return _from_axes(x, np.cross(z, x), z)


def inertial_attitude(n: int, reference: np.ndarray | None = None) -> np.ndarray:
    """``n`` copies of a fixed attitude (the identity by default), shape (n, 4)."""
    q = np.array([0.0, 0.0, 0.0, 1.0]) if reference is None else np.asarray(reference, float)
    if q.shape != (4,) or not np.all(np.isfinite(q)) or not np.linalg.norm(q) > 0:
        raise ValueError(f"reference attitude must be 4 finite numbers, got {q}")
    return np.tile(quaternion_normalize(q), (n, 1))


def offset_quaternion(offset_deg: np.ndarray | None) -> np.ndarray:
    """Offset quaternion of 3-2-1 Euler angles ``[roll, pitch, yaw]`` (deg)."""
    if offset_deg is None:
        return np.array([0.0, 0.0, 0.0, 1.0])
    roll, pitch, yaw = np.deg2rad(np.asarray(offset_deg, dtype=float))
    return euler321_to_quaternion(np.array([yaw, pitch, roll]))


def euler_offsets_deg(q_offset: np.ndarray) -> np.ndarray:
    """``[roll, pitch, yaw]`` (deg) of offset quaternions (inverse of
    :func:`offset_quaternion`), shape (..., 3)."""
    yaw_pitch_roll = np.rad2deg(quaternion_to_euler321(np.asarray(q_offset, float)))
    return yaw_pitch_roll[..., ::-1]


def profile_attitude(
    profile: str,
    *,
    position: np.ndarray | None = None,
    velocity: np.ndarray | None = None,
    sun: np.ndarray | None = None,
    n: int | None = None,
    reference: np.ndarray | None = None,
    yaw_steering: bool = False,
    offset: np.ndarray | None = None,
) -> np.ndarray:
    """Attitudes of a stabilised profile composed with an offset: ``q_off ⊗ q_ref``.

    Parameters
    ----------
    profile : {"inertial", "nadir", "sun-pointing"}
    position, velocity : (n, 3) array, optional
        Geocentric object position and velocity, inertial frame (``nadir``).
    sun : (n, 3) array, optional
        Object → Sun vectors (``sun-pointing``, and ``nadir`` with yaw steering).
    n : int, optional
        Number of epochs (``inertial``; else taken from the vectors).
    reference : (4,) array, optional
        Fixed attitude of the ``inertial`` profile (default the identity).
    yaw_steering : bool
        ``nadir`` only.
    offset : (4,) or (n, 4) array, optional
        Offset quaternion(s) ``q_off`` (see :func:`offset_quaternion`); default none.

    Returns
    -------
    (n, 4) numpy.ndarray
        Unit quaternions inertial → body, sign continuous in time.

    Raises
    ------
    ValueError
        Unknown profile, missing or malformed vectors, or options that do not apply.
    """
    if profile not in STABILISED_PROFILES:
        raise ValueError(
            f"profile must be one of {', '.join(STABILISED_PROFILES)}, got {profile!r}"
        )
    if yaw_steering and profile != "nadir":
        raise ValueError("yaw steering applies to the nadir profile only")
    if reference is not None and profile != "inertial":
        raise ValueError("a reference attitude applies to the inertial profile only")
    if profile == "nadir":
        if position is None or (velocity is None and not yaw_steering):
            raise ValueError(
                "the nadir profile needs the object's position and velocity (the position "
                "alone when yaw-steered)"
            )
        q_ref = nadir_attitude(position, velocity, sun, yaw_steering)
    elif profile == "sun-pointing":
        if sun is None:
            raise ValueError("the sun-pointing profile needs the object → Sun vectors")
        q_ref = sun_pointing_attitude(sun)
    else:
        count = n if n is not None else len(_as_vectors(sun if sun is not None else position, "v"))
        q_ref = inertial_attitude(count, reference)
    if offset is None:
        return q_ref
    q_off = quaternion_normalize(np.asarray(offset, dtype=float))
    return _continuous(quaternion_multiply(np.broadcast_to(q_off, q_ref.shape), q_ref))


def body_rates(times: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Body rates (rad/s, body frame) of an attitude sequence by central differences.

    ``δq_k = q_{k+1} ⊗ q_k⁻¹`` is the body-frame rotation between samples
    (``q̇ = ½ [ω, 0] ⊗ q``); its rotation vector over the time step is the mean rate. Each
    epoch gets the mean of its two neighbouring intervals (one-sided at the ends), an error
    of order ``ω̇ Δt / 2``.

    Parameters
    ----------
    times : (n,) array
        Seconds, strictly increasing.
    q : (n, 4) array
        Quaternions inertial → body.

    Returns
    -------
    (n, 3) numpy.ndarray
    """
    t = np.asarray(times, dtype=float)
    q = np.asarray(q, dtype=float)
    if len(t) < 2:
        return np.zeros((len(t), 3))
    step = quaternion_multiply(q[1:], quaternion_conjugate(q[:-1]))
    rates = quaternion_to_rotation_vector(quaternion_canonical(step)) / np.diff(t)[:, None]
    return np.concatenate([rates[:1], 0.5 * (rates[1:] + rates[:-1]), rates[-1:]])


def profile_states(
    observations: Observations,
    profile: str,
    *,
    reference: np.ndarray | None = None,
    yaw_steering: bool = False,
    offset: np.ndarray | None = None,
) -> np.ndarray:
    """States ``[q1..q4, ωx, ωy, ωz]`` of a stabilised profile at an observation set's epochs.

    The positions and velocities come from the ``obj_*`` columns (``nadir``), the Sun from
    ``sun_*``; the rates are :func:`body_rates` of the attitude sequence.

    Parameters
    ----------
    observations : Observations
    profile : {"inertial", "nadir", "sun-pointing"}
    reference, yaw_steering, offset
        As :func:`profile_attitude`.

    Returns
    -------
    (n, 7) numpy.ndarray

    Raises
    ------
    ValueError
        The file lacks the object-position columns a profile needs (naming the file).
    """
    position = velocity = None
    if profile == "nadir":
        needs_velocity = not yaw_steering
        if not observations.has_object_position or (
            needs_velocity and not observations.has_object_velocity
        ):
            where = observations.source or observations.name
            columns = OBJECT_COLUMNS if needs_velocity else OBJECT_COLUMNS[:3]
            raise ValueError(
                f"{where}: the nadir profile needs the object's "
                f"{'position and velocity' if needs_velocity else 'position'} "
                f"(columns {', '.join(columns)}): write the file with 'lightcurve geometry'"
                + ("" if needs_velocity else " or 'import'")
            )
        position = observations.object_positions
        velocity = observations.object_velocities if observations.has_object_velocity else None
    q = profile_attitude(
        profile,
        position=position,
        velocity=velocity,
        sun=observations.sun_vectors,
        n=len(observations),
        reference=reference,
        yaw_steering=yaw_steering,
        offset=offset,
    )
    return np.concatenate([q, body_rates(observations.times, q)], axis=1)
