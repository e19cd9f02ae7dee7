"""Principal-axis spin states of asteroids and tumbling-free bodies, in the DAMIT convention.

A body rotating uniformly about its body z axis is described by the spin state
``(λ, β, P, φ0, t0)``: the ecliptic longitude λ and latitude β of the spin axis (ecliptic
J2000), the sidereal rotation period P, and the rotation angle φ0 at the epoch t0.

Convention (Kaasalainen, Torppa & Muinonen 2001; Ďurech, Sidorin & Kaasalainen 2010, the
DAMIT database, eq. 1). A vector ``v_ecl`` in the ecliptic J2000 frame has body-frame
coordinates ::

    v_B = R_z(φ(t)) · R_y(90° − β) · R_z(λ) · v_ecl,      φ(t) = φ0 + 2π (t − t0) / P,

with the *passive* elementary rotations ``R_z(φ) = [[cos φ, sin φ, 0], [−sin φ, cos φ, 0],
[0, 0, 1]]`` and ``R_y(θ) = [[cos θ, 0, −sin θ], [0, 1, 0], [sin θ, 0, cos θ]]``. The body z
axis is the spin axis ``(cos β cos λ, cos β sin λ, sin β)``; the rotation is positive
(counter-clockwise) about it, so a retrograde rotator has β < 0. t is the (light-time
corrected) epoch; times enter as MJD and are converted to seconds once.

In the toolkit's quaternion convention (``v_B = A(q) v_I``, ``A(p ⊗ q) = A(p) A(q)``) every
passive elementary rotation ``R_e(θ)`` is ``A(axis_angle_to_quaternion(e, θ))``, so ::

    q(t) = q_z(φ(t)) ⊗ q_y(90° − β) ⊗ q_z(λ),      ω_B = (0, 0, 2π/P).

All quaternion algebra is done by the attitude core (:mod:`filters.attitude`); the
functions here accept numpy arrays or torch tensors (with autograd), like the core.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

# The attitude core (filters.attitude, which loads its integrators) and the simulator are
# imported by the functions that use them: spin states and pole matrices, all a convex fit
# needs, load with numpy alone.
if TYPE_CHECKING:  # the simulator (renderer, shapes, pandas) loads when simulate_rotator runs
    from lightcurve.io.observations import Observations
    from lightcurve.photometry.simulate import NoiseModel
    from shapes import FacetModel

__all__ = [
    "SpinState",
    "pole_distance",
    "pole_matrix",
    "pole_quaternion",
    "pole_vector",
    "rotation_angle",
    "simulate_rotator",
    "spin_attitude",
    "spin_from_attitude",
]

SECONDS_PER_DAY = 86400.0
_X, _Y, _Z = np.eye(3)


@dataclass(frozen=True)
class SpinState:
    """Principal-axis spin state (DAMIT convention, see the module docstring).

    Parameters
    ----------
    lambda_rad, beta_rad : float
        Ecliptic longitude and latitude of the spin axis (rad, ecliptic J2000).
    period_s : float
        Sidereal rotation period (s, > 0).
    phi0_rad : float
        Rotation angle at ``epoch_mjd`` (rad).
    epoch_mjd : float
        Reference epoch t0 (MJD).
    """

    lambda_rad: float
    beta_rad: float
    period_s: float
    phi0_rad: float = 0.0
    epoch_mjd: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.period_s) and self.period_s > 0):
            raise ValueError(f"spin period must be positive, got {self.period_s} s")
        if not abs(self.beta_rad) <= math.pi / 2 + 1e-12:
            raise ValueError(
                f"pole latitude must be within ±90°, got {math.degrees(self.beta_rad)}"
            )

    @classmethod
    def from_degrees(
        cls,
        lambda_deg: float,
        beta_deg: float,
        period_h: float,
        phi0_deg: float = 0.0,
        epoch_mjd: float = 0.0,
    ) -> SpinState:
        """Spin state from degrees and hours (the units of DAMIT and of the CLI)."""
        return cls(
            math.radians(lambda_deg),
            math.radians(beta_deg),
            period_h * 3600.0,
            math.radians(phi0_deg),
            epoch_mjd,
        )

    @property
    def rate(self) -> float:
        """Rotation rate ω = 2π/P (rad/s)."""
        return 2.0 * math.pi / self.period_s

    @property
    def period_h(self) -> float:
        """Sidereal period (h)."""
        return self.period_s / 3600.0

    @property
    def pole(self) -> np.ndarray:
        """Unit spin axis in the ecliptic frame, shape (3,)."""
        return pole_vector(self.lambda_rad, self.beta_rad)

    def at_epoch(self, mjd: float) -> SpinState:
        """The same rotation with its reference epoch moved to ``mjd``.

        ``φ0' = φ(mjd) mod 2π``; the attitude at every epoch is unchanged.
        """
        phi = float(rotation_angle(self, np.array(mjd, float))) % (2 * math.pi)
        return SpinState(self.lambda_rad, self.beta_rad, self.period_s, phi, float(mjd))

    def attitude(self, mjd: Any) -> Any:
        """Attitude quaternions (ecliptic → body) at epochs ``mjd``, shape (n, 4)."""
        return spin_attitude(
            self.lambda_rad, self.beta_rad, rotation_angle(self, np.asarray(mjd, float))
        )

    def body_rate(self) -> np.ndarray:
        """Angular velocity in the body frame, ``(0, 0, 2π/P)`` rad/s."""
        return np.array([0.0, 0.0, self.rate])

    def initial_state(self, mjd: float) -> tuple[np.ndarray, np.ndarray]:
        """``(q0, ω0)`` at epoch ``mjd`` for :func:`lightcurve.photometry.simulate.simulate`.

        With an axisymmetric inertia about z (e.g. ``diag(1, 1, 2)``) the torque-free motion
        from this state is the uniform rotation of this spin state.
        """
        return np.asarray(self.attitude([mjd]))[0], self.body_rate()


def pole_vector(lambda_rad: Any, beta_rad: Any) -> Any:
    """Unit vector ``(cos β cos λ, cos β sin λ, sin β)`` (ecliptic frame).

    Parameters
    ----------
    lambda_rad, beta_rad : array
        Longitude and latitude (rad), broadcastable.

    Returns
    -------
    (..., 3) array
    """
    from filters.attitude.arrays import as_arrays

    xp, (lam, beta) = as_arrays(lambda_rad, beta_rad)
    cb = xp.cos(beta)
    return xp.stack([cb * xp.cos(lam), cb * xp.sin(lam), xp.sin(beta) + 0 * lam], axis=-1)


def pole_quaternion(lambda_rad: Any, beta_rad: Any) -> Any:
    """Quaternion of ``R_y(90° − β) R_z(λ)``: ecliptic → frame with z along the pole.

    Parameters
    ----------
    lambda_rad, beta_rad : array
        Pole longitude and latitude (rad), broadcastable.

    Returns
    -------
    (..., 4) array
    """
    from filters.attitude import axis_angle_to_quaternion, quaternion_multiply
    from filters.attitude.arrays import as_arrays

    xp, (lam, beta) = as_arrays(lambda_rad, beta_rad)
    q_lambda = axis_angle_to_quaternion(xp.asarray(_Z, dtype=lam.dtype), lam)
    q_beta = axis_angle_to_quaternion(xp.asarray(_Y, dtype=lam.dtype), math.pi / 2 - beta)
    return quaternion_multiply(q_beta, q_lambda)


def pole_matrix(
    lambda_rad: np.ndarray, beta_rad: np.ndarray, derivatives: bool = False
) -> np.ndarray | tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Matrix ``R_y(90° − β) R_z(λ)`` of :func:`pole_quaternion` in closed form (numpy).

    ::

        [[ sin β cos λ,  sin β sin λ,  −cos β],
         [      −sin λ,        cos λ,       0],
         [ cos β cos λ,  cos β sin λ,   sin β]]

    (its last row is the pole). With ``derivatives`` also ``∂/∂λ`` and ``∂/∂β``.

    Parameters
    ----------
    lambda_rad, beta_rad : (...) array
        Pole longitude and latitude (rad), broadcastable.

    Returns
    -------
    (..., 3, 3) numpy.ndarray, or three of them with ``derivatives``
    """
    lam, beta = np.broadcast_arrays(np.asarray(lambda_rad, float), np.asarray(beta_rad, float))
    cl, sl, cb, sb = np.cos(lam), np.sin(lam), np.cos(beta), np.sin(beta)
    zero = np.zeros_like(lam)

    def matrix(*rows):
        return np.stack([np.stack(row, axis=-1) for row in rows], axis=-2)

    value = matrix((sb * cl, sb * sl, -cb), (-sl, cl, zero), (cb * cl, cb * sl, sb))
    if not derivatives:
        return value
    d_lambda = matrix((-sb * sl, sb * cl, zero), (-cl, -sl, zero), (-cb * sl, cb * cl, zero))
    d_beta = matrix((cb * cl, cb * sl, sb), (zero, zero, zero), (-sb * cl, -sb * sl, cb))
    return value, d_lambda, d_beta


def rotation_angle(state: SpinState, mjd: np.ndarray) -> np.ndarray:
    """Rotation angle ``φ(t) = φ0 + 2π (t − t0)/P`` (rad) at epochs ``mjd``."""
    return (
        state.phi0_rad + state.rate * (np.asarray(mjd, float) - state.epoch_mjd) * SECONDS_PER_DAY
    )


def spin_attitude(lambda_rad: Any, beta_rad: Any, phi: Any) -> Any:
    """Attitude quaternions ``q_z(φ) ⊗ q_y(90° − β) ⊗ q_z(λ)`` (ecliptic → body).

    Parameters
    ----------
    lambda_rad, beta_rad : array
        Pole longitude and latitude (rad), broadcastable against ``phi``.
    phi : array
        Rotation angles (rad).

    Returns
    -------
    (..., 4) array
    """
    from filters.attitude import axis_angle_to_quaternion, quaternion_multiply
    from filters.attitude.arrays import as_arrays

    xp, (lam, beta, phi) = as_arrays(lambda_rad, beta_rad, phi)
    q_phi = axis_angle_to_quaternion(xp.asarray(_Z, dtype=phi.dtype), phi)
    return quaternion_multiply(q_phi, pole_quaternion(lam, beta))


def spin_from_attitude(q: Any, omega_body: Any, mjd: float, atol: float = 1e-6) -> SpinState:
    """Spin state of a body rotating uniformly about its z axis, from one attitude.

    Parameters
    ----------
    q : (4,) array
        Attitude (ecliptic → body) at ``mjd``.
    omega_body : (3,) array
        Body rates (rad/s); must be along ±z.
    mjd : float
        Epoch of ``q``; it becomes the spin state's t0.
    atol : float
        Tolerated transverse rate relative to |ω|.

    Returns
    -------
    SpinState
        With ``φ0`` the rotation angle at ``mjd`` (in ``[0, 2π)``). A negative ``ωz`` is a
        positive rotation about the −z axis: the pole is then the body's −z axis, and the
        body frame of the returned state is turned 180° about x relative to ``q``'s.

    Raises
    ------
    ValueError
        If ω is not along the body z axis.
    """
    from filters.attitude import (
        attitude_angle,
        axis_angle_to_quaternion,
        quaternion_conjugate,
        quaternion_multiply,
        rotate,
    )

    q = np.asarray(q, float)
    w = np.asarray(omega_body, float)
    rate = float(np.linalg.norm(w))
    if rate == 0 or np.linalg.norm(w[:2]) > atol * rate:
        raise ValueError(f"body rate {w.tolist()} rad/s is not along the body z axis")
    if w[2] < 0:
        # Same motion seen in a body frame turned 180° about x: z → −z, ω_z → −ω_z.
        q = np.asarray(quaternion_multiply(axis_angle_to_quaternion(_X, math.pi), q))
    pole = np.asarray(rotate(quaternion_conjugate(q), _Z))
    lam = math.atan2(pole[1], pole[0]) % (2 * math.pi)
    beta = math.asin(float(np.clip(pole[2], -1.0, 1.0)))
    # φ from the rest, R_z(φ) = A(q) A(q_pole)ᵀ, whose x column is (cos φ, −sin φ, 0).
    x_pole = rotate(quaternion_conjugate(pole_quaternion(lam, beta)), _X)
    residual = np.asarray(rotate(q, x_pole))
    phi = math.atan2(-residual[1], residual[0]) % (2 * math.pi)
    state = SpinState(lam, beta, 2 * math.pi / rate, phi, float(mjd))
    if float(attitude_angle(state.attitude([mjd])[0], q)) > 1e-6:
        raise ValueError("attitude is not a rotation about the pole (internal check failed)")
    return state


def pole_distance(lambda1: Any, beta1: Any, lambda2: Any, beta2: Any) -> Any:
    """Great-circle angle between two poles (rad), ``atan2(|p1 × p2|, p1 · p2)``.

    Parameters
    ----------
    lambda1, beta1, lambda2, beta2 : array
        Longitudes and latitudes (rad), broadcastable.

    Returns
    -------
    array
        In ``[0, π]``.
    """
    p1 = np.asarray(pole_vector(lambda1, beta1))
    p2 = np.asarray(pole_vector(lambda2, beta2))
    return np.arctan2(np.linalg.norm(np.cross(p1, p2), axis=-1), np.sum(p1 * p2, axis=-1))


def simulate_rotator(
    geometry: Observations,
    shape: FacetModel,
    spin: SpinState,
    *,
    noise: NoiseModel | None = None,
    seed: int | np.random.Generator | None = None,
    relative: bool | None = True,
    shadows: str = "auto",
) -> Observations:
    """Light curves of a body in uniform rotation about its z axis, one curve at a time.

    Each light curve of ``geometry`` (``lightcurve_id``) is simulated by
    :func:`lightcurve.photometry.simulate.simulate` from the spin state's attitude at its first
    epoch, ``ω0 = (0, 0, 2π/P)`` and the axisymmetric inertia ``diag(1, 1, 2)``, for which the
    torque-free motion is exactly the uniform rotation of ``spin``. Simulating night by
    night keeps the integration short over data spanning decades. Repeated epochs within a
    curve are dropped (the integrator needs increasing times).

    Parameters
    ----------
    geometry : Observations
        Epochs and Sun/observer vectors (e.g. a DAMIT file's).
    shape : FacetModel
        The body (its z axis is the spin axis).
    spin : SpinState
    noise : NoiseModel, optional
    seed : int or numpy.random.Generator, optional
    relative : bool or None
        True: flag every light curve relative (as most asteroid photometry is); False:
        calibrated (the simulated magnitudes are absolute); None: keep the geometry's flags.
    shadows : str
        Renderer shadow mode.

    Returns
    -------
    Observations
        With ``mag``, ``mag_err``, truth columns, ``lightcurve_id`` and ``relative``.
    """
    import pandas as pd

    from lightcurve.io.observations import Observations, validate_table
    from lightcurve.photometry.simulate import simulate

    rng = np.random.default_rng(seed)
    inertia = np.diag([1.0, 1.0, 2.0])
    tables = []
    ids = geometry.lightcurve_ids
    for label in np.unique(ids):
        table = geometry.table.loc[ids == label].drop_duplicates("mjd").reset_index(drop=True)
        night = Observations(table, {"target": geometry.meta.get("target", "satellite")})
        q0, omega0 = spin.initial_state(float(table["mjd"].iloc[0]))
        result = simulate(
            night,
            shape,
            q0=q0,
            omega0=omega0,
            inertia=inertia,
            noise=noise,
            shadows=shadows,
            seed=rng,
        )
        out = result.table.copy()
        out["lightcurve_id"] = int(label)
        out["relative"] = (
            bool(geometry.relative[ids == label][0]) if relative is None else bool(relative)
        )
        tables.append(out)
    meta = {
        key: value for key, value in geometry.meta.items() if key not in ("source_format", "notes")
    }
    meta.update(
        {
            "simulated": "true",
            "shape": shape.name,
            "spin": f"lambda={math.degrees(spin.lambda_rad):.6f} deg, "
            f"beta={math.degrees(spin.beta_rad):.6f} deg, period={spin.period_h:.9f} h",
            "noise": noise.describe() if noise is not None else "none",
        }
    )
    combined = validate_table(pd.concat(tables, ignore_index=True), geometry.source, meta)
    return Observations(combined, meta, geometry.source)
