"""Monocular attitude, rate and inertia estimation of a tumbling non-cooperative target.

The extended Kalman filter of Deng et al. 2024 (eqs. 24–36). The only measurement
is the attitude of the target relative to the first camera frame, a quaternion obtained from
image sequences (``filters.navigation.epipolar``); the filter estimates that attitude, the
body rates and the normalised inertia tensor.

State and error state
---------------------
Nominal state ``x = [q (4), ω (3), p]`` with ``q`` the attitude relative to the first frame
(passive, ``v_B = A(q) v_ref``, truth starts at the identity), ``ω`` the body rate in the
body frame (rad/s) and ``p`` the inertia parameters:

* form ``"L"``: ``p = l = [Lxx, Lyy, Lxy, Lxz, Lyz]``, the free entries of ``L = J/Jzz``
  (Deng et al. 2024, eq. 15; 11 error states);
* form ``"k"``: ``p = k = [k1, k2]``, the tanh principal-axis form of Feng et al. (8 error
  states), for a reference frame aligned with the principal axes.

The error state is ``δx = [δq_v, δω, δp]`` with the multiplicative attitude error
``δq = q ⊗ q̂⁻¹ ≈ [δq_v, 1]`` (half the small rotation vector). It obeys ``δẋ = C δx`` with
``C = [[−[ω×], ½ I₃, 0], [0, M, N], [0, 0, 0]]`` (eqs. 24–33), ``M = ∂ω̇/∂ω`` and
``N = ∂ω̇/∂p`` from the attitude core.

Filter cycle (eq. 36, with two deliberate refinements)
------------------------------------------------------
* predict: the nominal state is propagated with RK4 (the paper uses one Euler step),
  ``Φ = exp(C ΔT)`` by scaling and squaring of its Taylor series, ``P ← Φ P Φᵀ + Q ΔT``
  (``Q`` a spectral density per second, so ``Q ΔT`` is the paper's ``Q_k`` at ``ΔT = 1 s``);
* update with a measured quaternion ``z``: innovation ``ν = vec(z ⊗ q̂⁻¹)`` (sign-canonical),
  ``H = [I₃ 0 0]`` (eq. 35), ``K = P Hᵀ (H P Hᵀ + R)⁻¹``, Joseph-form covariance, and the
  multiplicative reset ``q̂ ← normalise([δq_v, 1] ⊗ q̂)``.

Every array may carry leading batch dimensions (Monte Carlo runs are filtered together).

Example
-------
>>> ekf = MonocularEKF(x0, p0, q=1e-3 * np.eye(11), r=1e-3 * np.eye(3))  # doctest: +SKIP
>>> history = ekf.batch_filter(times, quaternions)  # doctest: +SKIP
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from filters.attitude import (
    attitude_matrix,
    error_state_matrix,
    euler_rate,
    euler_rate_jacobian_normalized,
    euler_rate_jacobian_tanh,
    inertia_from_normalized,
    inertia_from_tanh,
    normalized_from_inertia,
    quaternion_canonical,
    quaternion_conjugate,
    quaternion_multiply,
    quaternion_normalize,
    quaternion_rate,
    rk4_step,
    rotation_vector_to_quaternion,
    tanh_from_inertia,
    torque_free_derivative,
    transition_matrix,
)
from filters.attitude.arrays import as_arrays
from filters.gaussian import joseph_update, mahalanobis_squared
from filters.planning.observability import (
    Chart,
    RankTest,
    observability_gramian,
    observability_rank,
)

__all__ = [
    "FORMS",
    "FilterHistory",
    "InertiaForm",
    "MonocularEKF",
    "inertia_form",
    "observability_at",
    "perturb_attitudes",
    "reference_frame_truth",
    "state_derivative",
    "trajectory_information",
]


@dataclass(frozen=True)
class InertiaForm:
    """An inertia parameterisation usable by the monocular EKF.

    Attributes
    ----------
    name : str
        ``"L"`` or ``"k"``.
    parameter_names : tuple of str
        Names of the entries of ``p``.
    tensor : callable
        ``p (..., m) → (..., 3, 3)`` body-frame inertia (any scale).
    rate_jacobian : callable
        ``(ω, p) → ∂ω̇/∂p`` of shape ``(..., 3, m)``.
    from_inertia : callable
        ``J (3, 3) → p`` (numpy), the truth in this form.
    """

    name: str
    parameter_names: tuple[str, ...]
    tensor: Callable[[Any], Any]
    rate_jacobian: Callable[[Any, Any], Any]
    from_inertia: Callable[[Any], Any]

    @property
    def size(self) -> int:
        """Number of inertia parameters."""
        return len(self.parameter_names)

    @property
    def state_names(self) -> tuple[str, ...]:
        """Names of the error-state entries ``[δq_v, δω, δp]``."""
        return ("q1", "q2", "q3", "wx", "wy", "wz", *self.parameter_names)


FORMS: dict[str, InertiaForm] = {
    "L": InertiaForm(
        "L",
        ("Lxx", "Lyy", "Lxy", "Lxz", "Lyz"),
        inertia_from_normalized,
        euler_rate_jacobian_normalized,
        normalized_from_inertia,
    ),
    "k": InertiaForm(
        "k", ("k1", "k2"), inertia_from_tanh, euler_rate_jacobian_tanh, tanh_from_inertia
    ),
}


def inertia_form(name: str | InertiaForm) -> InertiaForm:
    """Look up an inertia form by name (``"L"`` or ``"k"``).

    Raises
    ------
    ValueError
        For an unknown name.
    """
    if isinstance(name, InertiaForm):
        return name
    try:
        return FORMS[name]
    except KeyError:
        raise ValueError(f"unknown inertia form {name!r}; use one of {sorted(FORMS)}") from None


def state_derivative(form: str | InertiaForm = "L") -> Callable[[Any], Any]:
    """``f(x)`` of the nominal state ``x = [q, ω, p]`` (Deng et al. 2024, eq. 17).

    ``q̇ = ½ Ω(ω) q``, ``ω̇ = −L⁻¹ [ω×] L ω``, ``ṗ = 0``. Works on numpy arrays and torch
    tensors with leading batch dimensions, so the same function drives the EKF, the truth
    checks and the autograd observability analysis.

    Parameters
    ----------
    form : str or InertiaForm

    Returns
    -------
    callable
        ``x (..., 7 + m) → ẋ (..., 7 + m)``.
    """
    spec = inertia_form(form)

    def derivative(x: Any) -> Any:
        xp, (x,) = as_arrays(x)
        q, w, p = x[..., :4], x[..., 4:7], x[..., 7:]
        w_dot = euler_rate(w, spec.tensor(p))
        return xp.concat([quaternion_rate(q, w), w_dot, xp.zeros_like(p)], axis=-1)

    return derivative


@dataclass
class FilterHistory:
    """Output of :meth:`MonocularEKF.batch_filter`.

    Attributes
    ----------
    times : (K,) numpy.ndarray
        Measurement times (s).
    states : (K, ..., 7 + m) numpy.ndarray
        Posterior nominal states ``[q, ω, p]``.
    covariances : (K, ..., n, n) numpy.ndarray
        Posterior error covariances.
    innovations : (K, ..., 3) numpy.ndarray
        ``vec(z ⊗ q̂⁻¹)`` before each update.
    nis : (K, ...) numpy.ndarray
        Normalised innovation squared ``νᵀ S⁻¹ ν`` (χ²(3) when consistent).
    """

    times: np.ndarray
    states: np.ndarray
    covariances: np.ndarray
    innovations: np.ndarray
    nis: np.ndarray

    @property
    def sigmas(self) -> np.ndarray:
        """One-sigma error-state uncertainties ``√diag(P)``, shape ``(K, ..., n)``."""
        return np.sqrt(np.diagonal(self.covariances, axis1=-2, axis2=-1))


class MonocularEKF:
    """Multiplicative EKF on ``[q, ω, inertia]`` with quaternion measurements (Deng et al. 2024).

    Parameters
    ----------
    x : (..., 7 + m) array_like
        Initial nominal state ``[q (4), ω (3, rad/s), p (m)]``; leading dimensions are
        independent filters (e.g. Monte Carlo runs).
    p : (..., n, n) array_like
        Initial error covariance, ``n = 6 + m``.
    q : (n, n) array_like
        Process-noise spectral density (per second); the step covariance is ``q ΔT``.
    r : (3, 3) array_like
        Covariance of the measurement error ``δq_v`` (half-angle units, rad²/4).
    form : {"L", "k"}
        Inertia parameterisation.

    Attributes
    ----------
    x, P : numpy.ndarray
        Current state and covariance (posterior after :meth:`update`, prior after
        :meth:`predict`).
    """

    def __init__(self, x: Any, p: Any, q: Any, r: Any, form: str | InertiaForm = "L") -> None:
        self.form = inertia_form(form)
        n = 6 + self.form.size
        self.x = np.array(x, dtype=float)
        if self.x.shape[-1] != 7 + self.form.size:
            raise ValueError(
                f"state must have {7 + self.form.size} entries [q, omega, "
                f"{', '.join(self.form.parameter_names)}], got {self.x.shape[-1]}"
            )
        self.x[..., :4] = quaternion_normalize(self.x[..., :4])
        self.P = np.broadcast_to(np.asarray(p, dtype=float), (*self.x.shape[:-1], n, n)).copy()
        self.Q = np.asarray(q, dtype=float)
        self.R = np.asarray(r, dtype=float)
        if self.Q.shape != (n, n) or self.R.shape != (3, 3):
            raise ValueError(f"process noise must be {n}x{n} and measurement noise 3x3")
        self.H = np.concatenate([np.eye(3), np.zeros((3, n - 3))], axis=1)

    @property
    def dim(self) -> int:
        """Error-state dimension ``n``."""
        return 6 + self.form.size

    def predict(self, dt: float, substeps: int = 1) -> None:
        """Propagate the state (RK4) and the covariance over ``dt`` seconds.

        Parameters
        ----------
        dt : float
            Step (s), positive.
        substeps : int
            RK4 steps per interval.
        """
        if dt <= 0:
            raise ValueError(f"time step must be positive, got {dt}")
        c = error_state_matrix(self.x[..., 4:7], self.x[..., 7:], self.form.name)
        phi = transition_matrix(c, dt)
        # ṗ = 0, so the inertia is fixed over the step: propagate [q, ω] with J⁻¹ computed once.
        f = torque_free_derivative(self.form.tensor(self.x[..., 7:]))
        x = self.x[..., :7]
        for _ in range(substeps):
            x = rk4_step(f, x, dt / substeps)
        self.x = np.concatenate([x, self.x[..., 7:]], axis=-1)
        p = phi @ self.P @ np.swapaxes(phi, -1, -2) + self.Q * dt
        self.P = 0.5 * (p + np.swapaxes(p, -1, -2))

    def innovation(self, z: Any) -> np.ndarray:
        """Measurement residual ``ν = vec(z ⊗ q̂⁻¹)`` with ``z`` made sign-canonical.

        Parameters
        ----------
        z : (..., 4) array_like
            Measured attitude quaternions.

        Returns
        -------
        (..., 3) numpy.ndarray
        """
        dq = quaternion_canonical(quaternion_multiply(z, quaternion_conjugate(self.x[..., :4])))
        return np.asarray(dq[..., :3])

    def update(self, z: Any, r: Any = None) -> tuple[np.ndarray, np.ndarray]:
        """Update with a measured quaternion (eqs. 35–36, Joseph form).

        Parameters
        ----------
        z : (..., 4) array_like
            Measured attitude relative to the first frame; NaN rows are missing
            measurements (no update for that filter).
        r : (..., 3, 3) array_like, optional
            Measurement noise covariance of this update (default: the filter's ``R``), e.g.
            from the epipolar pipeline's per-pair estimate.

        Returns
        -------
        innovation : (..., 3) numpy.ndarray
        nis : (...) numpy.ndarray
            Normalised innovation squared.
        """
        z = np.asarray(z, dtype=float)
        valid = np.all(np.isfinite(z), axis=-1)
        nu = self.innovation(np.where(valid[..., None], z, self.x[..., :4]))
        r = self.R if r is None else np.asarray(r, dtype=float)
        s = self.P[..., :3, :3] + r
        nis = mahalanobis_squared(nu, s)
        # K = P Hᵀ S⁻¹ with H = [I 0]: P Hᵀ is the first three columns of P.
        gain = np.swapaxes(np.linalg.solve(s, np.swapaxes(self.P[..., :, :3], -1, -2)), -1, -2)
        dx = (gain @ nu[..., None])[..., 0]
        p = joseph_update(self.P, gain, self.H, r)
        dq = np.concatenate([dx[..., :3], np.ones_like(dx[..., :1])], axis=-1)
        q = quaternion_normalize(quaternion_multiply(dq, self.x[..., :4]))
        x = np.concatenate([q, self.x[..., 4:] + dx[..., 3:]], axis=-1)
        # A missing measurement (NaN) leaves that filter at its prior.
        self.x = np.where(valid[..., None], x, self.x)
        self.P = np.where(valid[..., None, None], p, self.P)
        return np.where(valid[..., None], nu, np.nan), np.where(valid, nis, np.nan)

    def batch_filter(self, times: Any, measurements: Any) -> FilterHistory:
        """Run the filter over a measurement sequence.

        The current state is taken to be at ``times[0]``; the first measurement updates it
        without a prediction.

        Parameters
        ----------
        times : (K,) array_like
            Strictly increasing measurement times (s).
        measurements : (K, ..., 4) array_like
            Measured quaternions (batch dimensions after the time axis).

        Returns
        -------
        FilterHistory
        """
        t = np.asarray(times, dtype=float)
        z = np.asarray(measurements, dtype=float)
        if t.ndim != 1 or z.shape[0] != t.size or np.any(np.diff(t) <= 0):
            raise ValueError("times must be strictly increasing, one per measurement")
        states, covs, innovations, nis = [], [], [], []
        for k in range(t.size):
            if k:
                self.predict(t[k] - t[k - 1])
            nu, e = self.update(z[k])
            states.append(self.x.copy())
            covs.append(self.P.copy())
            innovations.append(nu)
            nis.append(e)
        return FilterHistory(
            t, np.stack(states), np.stack(covs), np.stack(innovations), np.stack(nis)
        )


def reference_frame_truth(
    inertia: Any, q0: Any, states: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Express a simulated truth in the frame the monocular filter estimates.

    The filter's body frame ``B'`` is the body-fixed frame that coincides with the camera
    (reference) frame at the first epoch (Deng et al. 2024, sec. 1: ``R₁ = I``). With the truth body
    frame ``B`` and ``v_B = A(q0) v_B'``: ``q'(t) = q0⁻¹ ⊗ q(t)``, ``ω' = A(q0)ᵀ ω`` and
    ``J' = A(q0)ᵀ J A(q0)``. With ``q0 = [0, 0, 0, 1]`` nothing changes.

    Parameters
    ----------
    inertia : (3, 3) array_like
        Truth inertia in the body frame ``B``.
    q0 : (4,) array_like
        Truth attitude (camera → body) at the first epoch.
    states : (K, 7) numpy.ndarray
        Truth states ``[q, ω]`` in ``B`` (camera → body, body rates).

    Returns
    -------
    q : (K, 4) numpy.ndarray
        Attitude relative to the first frame (sign-canonical).
    omega : (K, 3) numpy.ndarray
        Body rates in ``B'`` (rad/s).
    inertia : (3, 3) numpy.ndarray
        ``J'``.
    """
    a0 = np.asarray(attitude_matrix(np.asarray(q0, dtype=float)))
    q = quaternion_multiply(quaternion_conjugate(np.asarray(q0, dtype=float)), states[:, :4])
    omega = states[:, 4:7] @ a0
    return quaternion_canonical(q), omega, a0.T @ np.asarray(inertia, dtype=float) @ a0


def perturb_attitudes(q: Any, sigma: float, rng: np.random.Generator) -> np.ndarray:
    """Noisy attitude measurements ``exp(δθ) ⊗ q`` with ``δθ ~ N(0, σ² I₃)`` (rad).

    Parameters
    ----------
    q : (..., 4) array_like
        True attitudes.
    sigma : float
        Per-axis rotation noise (rad).
    rng : numpy.random.Generator

    Returns
    -------
    (..., 4) numpy.ndarray
        Sign-canonical noisy quaternions.
    """
    q = np.asarray(q, dtype=float)
    noise = rotation_vector_to_quaternion(sigma * rng.standard_normal((*q.shape[:-1], 3)))
    return quaternion_canonical(quaternion_multiply(noise, q))


def _torch_state(x: Any) -> torch.Tensor:
    return torch.as_tensor(np.asarray(x, dtype=float), dtype=torch.float64)


def _measurement(x: Any) -> Any:
    """The attitude measurement as the full quaternion (its information equals ``δq_v``'s)."""
    return x[..., :4]


def error_chart(x: Any, form: str | InertiaForm = "L") -> Chart:
    """Local coordinates ``δx = [δq_v, δω, δp]`` around the nominal state ``x`` (torch).

    ``embed(δ) = [[δq_v, √(1 − |δq_v|²)] ⊗ q, ω + δω, p + δp]``: the filter's multiplicative
    error, so ranks and information are counted in the ``6 + m`` error states.

    Parameters
    ----------
    x : (7 + m,) array_like
        Nominal state ``[q, ω, p]``.
    form : str or InertiaForm

    Returns
    -------
    Chart
    """
    spec = inertia_form(form)
    x0 = _torch_state(x)

    def embed(delta: torch.Tensor) -> torch.Tensor:
        dq = torch.cat([delta[:3], torch.sqrt(1 - delta[:3] @ delta[:3])[None]])
        return torch.cat(
            [quaternion_multiply(dq, x0[:4]), x0[4:7] + delta[3:6], x0[7:] + delta[6:]]
        )

    return Chart(6 + spec.size, embed)


def observability_at(
    x: Any,
    form: str | InertiaForm = "L",
    max_order: int | None = None,
    rtol: float = 1e-9,
    patience: int = 2,
) -> RankTest:
    """Lie-derivative rank test of the monocular system at a state (Deng et al. 2024, eqs. 19–23).

    Columns are scaled by ``[1, 1, 1, |ω|, |ω|, |ω|, 1, …]`` (half-angle, rad/s and
    dimensionless inertia parameters compared on the scale of the motion).

    Parameters
    ----------
    x : (7 + m,) array_like
        State ``[q, ω, p]``.
    form : str or InertiaForm
    max_order : int, optional
        Highest Lie-derivative order (default ``n − 1``; the search stops earlier when the
        rank is full or stalls for two orders).
    rtol : float
        Relative singular-value tolerance of the rank decision.
    patience : int
        Orders without rank growth before the search stops.

    Returns
    -------
    RankTest
    """
    spec = inertia_form(form)
    x = np.asarray(x, dtype=float)
    w = float(np.linalg.norm(x[4:7])) or 1.0
    scales = [1.0] * 3 + [w] * 3 + [1.0] * spec.size
    return observability_rank(
        state_derivative(spec),
        _measurement,
        _torch_state(x),
        max_order=max_order,
        chart=error_chart(x, spec),
        scales=scales,
        rtol=rtol,
        patience=patience,
    )


def trajectory_information(
    states: Any, times: Any, sigma_qv: float, form: str | InertiaForm = "L"
) -> np.ndarray:
    """Fisher information about the initial error state from attitude measurements.

    Parameters
    ----------
    states : (K, 7 + m) array_like
        Trajectory ``[q, ω, p]`` at the measurement times (truth or estimate).
    times : (K,) array_like
        Measurement times (s).
    sigma_qv : float
        One-sigma noise of each component of ``δq_v`` (half-angle, rad).
    form : str or InertiaForm

    Returns
    -------
    (n, n) numpy.ndarray
        Information matrix in the error coordinates ``[δq_v, δω, δp]`` at ``times[0]``.
    """
    spec = inertia_form(form)
    f = state_derivative(spec)
    x = _torch_state(states)

    def step(state: torch.Tensor, dt: torch.Tensor) -> torch.Tensor:
        return rk4_step(f, state, dt)

    return observability_gramian(
        step, _measurement, x, _torch_state(times), sigma_qv**2 * np.eye(4), error_chart(x[0], spec)
    )
