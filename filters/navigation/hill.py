"""Clohessy–Wiltshire (Hill) relative translational dynamics about a circular orbit.

Frame (the Hill or LVLH frame of the reference orbit, origin at the reference body):
``x`` radial (away from the Earth), ``y`` along-track (direction of motion), ``z`` along the
orbit normal (angular momentum). The state is ``[x, y, z, ẋ, ẏ, ż]`` (m, m/s) and the
linearised relative motion under a non-gravitational acceleration ``a`` is (the translation
model of the stereo relative-state filter, ``docs/stereo.md``; Shi et al.'s relative navigation
eq. 2)

``ẍ − 2 n ẏ − 3 n² x = a_x``,  ``ÿ + 2 n ẋ = a_y``,  ``z̈ + n² z = a_z``

with ``n`` the mean motion of the circular reference orbit (rad/s). The transition matrix and
the zero-order-hold input matrix are the closed-form solutions of these equations (Vallado,
*Fundamentals of Astrodynamics*, sec. 6.8); the process noise of white acceleration noise
is discretised exactly with :func:`filters.gaussian.discrete_process_noise`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from filters.gaussian import discrete_process_noise

__all__ = [
    "EARTH_MU",
    "EARTH_RADIUS",
    "circular_orbit",
    "cw_input_matrix",
    "cw_matrix",
    "cw_process_noise",
    "cw_transition",
    "hill_rotation",
    "mean_motion",
]

EARTH_MU = 3.986004418e14
"""Earth's gravitational parameter (m³/s², WGS-84 / EGM-96)."""

EARTH_RADIUS = 6378.137e3
"""Earth's equatorial radius (m, WGS-84), for orbit radii from altitudes."""


def mean_motion(semi_major_axis: float, mu: float = EARTH_MU) -> float:
    """Mean motion ``n = √(μ / a³)`` (rad/s) of a circular orbit.

    Parameters
    ----------
    semi_major_axis : float
        Orbit radius (m).
    mu : float
        Gravitational parameter (m³/s²).

    Returns
    -------
    float
    """
    if not semi_major_axis > 0:
        raise ValueError(f"orbit radius must be positive, got {semi_major_axis} m")
    return math.sqrt(mu / semi_major_axis**3)


def _check_n(n: float) -> float:
    n = float(n)
    if not (math.isfinite(n) and n > 0):
        raise ValueError(f"mean motion must be a positive number of rad/s, got {n}")
    return n


def cw_matrix(n: float) -> np.ndarray:
    """Continuous system matrix ``A`` of ``ṡ = A s + [0; I] a`` for ``s = [r, v]``.

    Parameters
    ----------
    n : float
        Mean motion (rad/s).

    Returns
    -------
    (6, 6) numpy.ndarray
    """
    n = _check_n(n)
    a = np.zeros((6, 6))
    a[:3, 3:] = np.eye(3)
    a[3, 0] = 3 * n * n
    a[3, 4] = 2 * n
    a[4, 3] = -2 * n
    a[5, 2] = -n * n
    return a


def cw_transition(n: float, dt: Any) -> np.ndarray:
    """Exact state-transition matrix ``Φ(Δt) = exp(A Δt)`` of the CW equations.

    Parameters
    ----------
    n : float
        Mean motion (rad/s).
    dt : float or (...) array_like
        Time steps (s); negative steps propagate backwards.

    Returns
    -------
    (..., 6, 6) numpy.ndarray
    """
    n = _check_n(n)
    t = np.asarray(dt, dtype=float)
    nt = n * t
    s, c = np.sin(nt), np.cos(nt)
    one_c = 2 * np.sin(0.5 * nt) ** 2  # 1 − cos(nt) without cancellation
    phi = np.zeros((*t.shape, 6, 6))
    phi[..., 0, 0] = 4 - 3 * c
    phi[..., 1, 0] = 6 * (s - nt)
    phi[..., 1, 1] = 1.0
    phi[..., 2, 2] = c
    phi[..., 0, 3] = s / n
    phi[..., 0, 4] = 2 * one_c / n
    phi[..., 1, 3] = -2 * one_c / n
    phi[..., 1, 4] = (4 * s - 3 * nt) / n
    phi[..., 2, 5] = s / n
    phi[..., 3, 0] = 3 * n * s
    phi[..., 4, 0] = -6 * n * one_c
    phi[..., 5, 2] = -n * s
    phi[..., 3, 3] = c
    phi[..., 3, 4] = 2 * s
    phi[..., 4, 3] = -2 * s
    phi[..., 4, 4] = 4 * c - 3
    phi[..., 5, 5] = c
    return phi


def cw_input_matrix(n: float, dt: Any) -> np.ndarray:
    """Zero-order-hold input matrix ``Γ(Δt) = ∫₀^Δt Φ(s) ds [0; I]``.

    A constant acceleration ``a`` (m/s², Hill frame) applied over the step adds ``Γ a`` to
    the state: ``s(t + Δt) = Φ(Δt) s(t) + Γ(Δt) a`` (Shi et al.'s eq. 2, ``B_k u_k``).

    Parameters
    ----------
    n : float
        Mean motion (rad/s).
    dt : float or (...) array_like
        Time steps (s).

    Returns
    -------
    (..., 6, 3) numpy.ndarray
    """
    n = _check_n(n)
    t = np.asarray(dt, dtype=float)
    nt = n * t
    s = np.sin(nt)
    one_c = 2 * np.sin(0.5 * nt) ** 2
    n2 = n * n
    gam = np.zeros((*t.shape, 6, 3))
    gam[..., 0, 0] = one_c / n2
    gam[..., 0, 1] = 2 * (nt - s) / n2
    gam[..., 1, 0] = -2 * (nt - s) / n2
    gam[..., 1, 1] = 4 * one_c / n2 - 1.5 * t * t
    gam[..., 2, 2] = one_c / n2
    gam[..., 3, 0] = s / n
    gam[..., 3, 1] = 2 * one_c / n
    gam[..., 4, 0] = -2 * one_c / n
    gam[..., 4, 1] = 4 * s / n - 3 * t
    gam[..., 5, 2] = s / n
    return gam


def cw_process_noise(n: float, dt: float, psd: float) -> np.ndarray:
    """Discrete covariance of white acceleration noise over one step.

    ``Q_d = ∫₀^Δt Φ(s) G q Gᵀ Φ(s)ᵀ ds`` with ``G = [0; I]`` and the same spectral density
    on the three axes, computed exactly by Van Loan's method.

    Parameters
    ----------
    n : float
        Mean motion (rad/s).
    dt : float
        Step (s).
    psd : float
        Acceleration noise spectral density ``q`` (m²/s³); ``√q`` is in m/s^(3/2).

    Returns
    -------
    (6, 6) numpy.ndarray
    """
    if not psd >= 0:
        raise ValueError(f"acceleration noise density must be >= 0, got {psd}")
    q = np.zeros((6, 6))
    q[3:, 3:] = psd * np.eye(3)
    return discrete_process_noise(cw_matrix(n), q, dt)[1]


def circular_orbit(
    radius: float,
    inclination: float,
    raan: float,
    latitude_argument: float,
    t: Any,
    mu: float = EARTH_MU,
) -> tuple[np.ndarray, np.ndarray]:
    """Position and velocity on a circular orbit (inertial frame of the elements).

    Parameters
    ----------
    radius : float
        Orbit radius (m).
    inclination, raan : float
        Inclination and right ascension of the ascending node (rad).
    latitude_argument : float
        Argument of latitude at ``t = 0`` (rad).
    t : (...) array_like
        Times (s).
    mu : float
        Gravitational parameter (m³/s²).

    Returns
    -------
    position, velocity : (..., 3) numpy.ndarray
        (m, m/s).
    """
    n = mean_motion(radius, mu)
    u = latitude_argument + n * np.asarray(t, dtype=float)
    cu, su = np.cos(u), np.sin(u)
    cn, sn = math.cos(raan), math.sin(raan)
    ci, si = math.cos(inclination), math.sin(inclination)
    radial = np.stack([cu * cn - su * ci * sn, cu * sn + su * ci * cn, su * si], axis=-1)
    along = np.stack([-su * cn - cu * ci * sn, -su * sn + cu * ci * cn, cu * si], axis=-1)
    return radius * radial, radius * n * along


def hill_rotation(position: Any, velocity: Any) -> np.ndarray:
    """Rotation matrix from the inertial frame to the Hill frame of an orbiting body.

    Rows are the Hill axes in inertial coordinates: ``x`` radial (``r̂``), ``z`` along the
    angular momentum (``ĥ = r × v / |r × v|``), ``y = z × x`` (along-track).

    Parameters
    ----------
    position, velocity : (..., 3) array_like
        Inertial state of the reference body (m, m/s).

    Returns
    -------
    (..., 3, 3) numpy.ndarray
        ``R`` with ``v_Hill = R v_inertial``.
    """
    r = np.asarray(position, dtype=float)
    v = np.asarray(velocity, dtype=float)
    x = r / np.linalg.norm(r, axis=-1, keepdims=True)
    h = np.cross(r, v)
    z = h / np.linalg.norm(h, axis=-1, keepdims=True)
    y = np.cross(z, x)
    return np.stack([x, y, z], axis=-2)
