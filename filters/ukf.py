"""Attitude unscented Kalman filter: USQUE with generalized Rodrigues parameters.

The unscented quaternion estimator of Crassidis & Markley (2003) keeps the attitude
quaternion ``q̂`` *outside* the filter and estimates a three-parameter attitude error, the
generalized Rodrigues parameters (GRPs) ``δp = f δq_v / (a + δq4)`` of
``δq = q ⊗ q̂⁻¹`` (``a = 1``, ``f = 2(a + 1) = 4``: ``|δp|`` ≈ the error angle in rad).
The filter state is

``x = [δp (3), ω (3), θ (m)]``

with ``ω`` the body rates (rad/s, body frame) and ``θ`` optional parameters that the
dynamics or the measurement function read (the two tanh inertia parameters ``k`` of Feng
et al., a magnitude offset for the albedo–area scale, BRDF weights ...).

One cycle (Crassidis & Markley 2003, sec. III):

1. **Sigma points** ``χ_0 = x̂``, ``χ_{±i} = x̂ ± (√((n + λ) P))_i`` with the scaled
   weights of Wan & van der Merwe (2000); the attitude of each is
   ``q_i = δq(δp_i) ⊗ q̂`` (:func:`~filters.attitude.grp_to_quaternion`).
2. **Predict**: propagate ``(q_i, ω_i)`` with the dynamics ``fx``; re-express every
   propagated attitude as GRPs about the propagated central point,
   ``δp_i' = GRP(q_i' ⊗ q_0'⁻¹)``; the unscented transform of these plus the process
   noise ``Q(Δt)`` gives the predicted mean and covariance; the mean attitude error is
   folded into ``q̂ ← δq(δp̄) ⊗ q_0'`` and reset to zero.
3. **Update** with a scalar measurement ``z`` of variance ``R``: sigma points are drawn
   again from the predicted ``(x̂, P)`` (as filterpy's ``UKF.update`` does), mapped through
   ``hx``; ``ẑ = Σ W_m Z_i``, ``S = Σ W_c (Z_i − ẑ)² + R``,
   ``P_xz = Σ W_c (χ_i − x̂)(Z_i − ẑ)``, ``K = P_xz/S``, ``x̂ ← x̂ + K ν``,
   ``P ← P − K S Kᵀ``, ``q̂ ← δq(δp̂) ⊗ q̂``, ``δp̂ ← 0``.

**A bank in one call.** The filter holds ``B`` independent members (leading batch
dimension): Monte Carlo runs, or hypotheses of a multiple-hypothesis / MMAE bank that
share a measurement model. The sigma points of all members go through the dynamics and the
measurement function in one batched call, which is what makes banks cheap: the cost of a
photometric update is dominated by the per-call overhead of rendering, not by the number
of sigma points. This is why the sigma points and the unscented transform are written here
as batched array expressions instead of calling filterpy's per-filter
``MerweScaledSigmaPoints.sigma_points`` and ``unscented_transform`` ``B`` times; the
weights are filterpy's (:class:`~filterpy.kalman.MerweScaledSigmaPoints`), and the tests
check the batched points and transform against filterpy's functions. No custom mean or
residual function is needed: the attitude part of every sigma point is expressed in the
chart of GRPs about one reference attitude before the transform, where averaging and
differencing are plain vector operations (the point of USQUE); quaternions never enter it.

**Underweighting** (Lear; Zanetti, Crassidis & Markley 2009): with a wide prior, the
curvature of a light curve makes a full update over-confident. With ``γ > 0`` the gain
uses ``S_γ = S + γ (S − R)`` and the covariance is the exact one for that gain,
``P ← P − P_xz P_xzᵀ (2 S_γ − S)/S_γ²``; the effect fades as ``S − R`` (the state part)
falls below ``R``.

**Divergence.** A member whose propagated or updated state or covariance is not finite
(a sigma point's rate so large that the fixed-step integration overflows, a covariance
blown up by a lost track) has *diverged*: its last finite state is kept, frozen, its
reason is recorded in :attr:`AttitudeUKF.divergence`, and from then on every
measurement is gated for it with log-likelihood ``−inf``, so a bank drops it instead of
propagating NaN. Covariances that lose positive definiteness but stay finite are repaired
(symmetrised, eigenvalues floored) before their Cholesky factor is taken.

**Gating**: a measurement whose normalised innovation squared ``ν²/S`` exceeds ``gate`` is
rejected for that member (its state is left unchanged) and reported; a NaN measurement (a
member without data at this epoch) is treated the same way. Dark predictions are
the measurement function's business (it must return finite values, see
:class:`lightcurve.photometry.measurement.PhotometricModel`); gaps are longer predictions.

References
----------
Crassidis, J. L. & Markley, F. L. (2003). Unscented filtering for spacecraft attitude
estimation. *J. Guidance, Control, and Dynamics* 26(4), 536–542.
Wan, E. A. & van der Merwe, R. (2000). The unscented Kalman filter for nonlinear
estimation. *IEEE AS-SPCC*.
Zanetti, R., DeMars, K. J. & Bishop, R. H. (2010). Underweighting nonlinear measurements.
*J. Guidance, Control, and Dynamics* 33(5), 1670–1675.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from filterpy.kalman import MerweScaledSigmaPoints
from scipy import stats

from filters.attitude import (
    grp_to_quaternion,
    quaternion_conjugate,
    quaternion_multiply,
    quaternion_normalize,
    quaternion_to_grp,
)
from filters.ukf_models import (
    Dynamics,
    Measurement,
    ProcessNoise,
    TorqueFreeDynamics,
    stack_dynamics,
    torque_free_dynamics,
)

__all__ = [
    "AttitudeUKF",
    "Dynamics",
    "Measurement",
    "ProcessNoise",
    "TorqueFreeDynamics",
    "UpdateResult",
    "default_gate",
    "sigma_points",
    "stack_dynamics",
    "torque_free_dynamics",
    "unscented_moments",
]

#: Every member (an index over a filter's members).
_ALL = slice(None)


def default_gate(probability: float = 1e-4) -> float:
    """NIS threshold rejecting a consistent scalar innovation with this probability."""
    return float(stats.chi2.isf(probability, 1))


def sigma_points(points: MerweScaledSigmaPoints, x: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Scaled sigma points of a batch of means and covariances.

    Parameters
    ----------
    points : filterpy.kalman.MerweScaledSigmaPoints
        Supplies ``n``, ``α``, ``κ`` (the weights are its ``Wm``, ``Wc``).
    x : (B, n) array
    p : (B, n, n) array
        Symmetric positive definite.

    Returns
    -------
    (B, 2n + 1, n) numpy.ndarray
        ``[x, x + L_1 … x + L_n, x − L_1 … x − L_n]`` with ``L Lᵀ = (n + λ) P`` (the
        order of filterpy's ``sigma_points``).
    """
    return _sigma_points_of(points, x, np.linalg.cholesky(p))


def _sigma_points_of(points: MerweScaledSigmaPoints, x: np.ndarray, root: np.ndarray) -> np.ndarray:
    """:func:`sigma_points` from the Cholesky factors ``root`` of ``P``."""
    n = points.n
    scale = math.sqrt(points.alpha**2 * (n + points.kappa))  # √(n + λ)
    offsets = scale * np.swapaxes(root, -1, -2)
    return np.concatenate([x[:, None], x[:, None] + offsets, x[:, None] - offsets], axis=1)


def unscented_moments(
    points: MerweScaledSigmaPoints, sigmas: np.ndarray, noise: Any = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """Weighted mean and covariance of a batch of transformed sigma points.

    Parameters
    ----------
    points : filterpy.kalman.MerweScaledSigmaPoints
        Supplies the weights ``Wm``, ``Wc``.
    sigmas : (B, 2n + 1, d) array
    noise : (d, d) array or float
        Added to the covariance.

    Returns
    -------
    mean : (B, d) numpy.ndarray
    covariance : (B, d, d) numpy.ndarray
    """
    mean = np.einsum("s,bsd->bd", points.Wm, sigmas)
    deviation = sigmas - mean[:, None]
    covariance = np.einsum("s,bsi,bsj->bij", points.Wc, deviation, deviation) + noise
    return mean, covariance


@dataclass(frozen=True)
class UpdateResult:
    """Outcome of one scalar measurement update, per bank member.

    Attributes
    ----------
    predicted : (B,) numpy.ndarray
        Predicted measurement ``ẑ`` (before the update).
    innovation : (B,) numpy.ndarray
        ``ν = z − ẑ``.
    variance : (B,) numpy.ndarray
        Innovation variance ``S`` (includes ``R``).
    nis : (B,) numpy.ndarray
        Normalised innovation squared ``ν²/S``.
    log_likelihood : (B,) numpy.ndarray
        ``−½ (ln 2πS + ν²/S)``.
    gated : (B,) bool numpy.ndarray
        The measurement was rejected by the innovation gate.
    """

    predicted: np.ndarray
    innovation: np.ndarray
    variance: np.ndarray
    nis: np.ndarray
    log_likelihood: np.ndarray
    gated: np.ndarray


class AttitudeUKF:
    """Unscented quaternion estimator (USQUE) for a bank of ``B`` members.

    Parameters
    ----------
    q : (4,) or (B, 4) array
        Initial attitude estimates (inertial → body).
    omega : (3,) or (B, 3) array
        Initial body-rate estimates (rad/s).
    covariance : (n, n) or (B, n, n) array
        Initial covariance of ``[δp, ω, θ]`` (rad² for GRPs with ``f = 4``).
    fx : callable
        Dynamics ``fx(q, ω, θ, Δt)`` on ``(..., 4)``, ``(..., 3)``, ``(..., m)`` arrays,
        e.g. :func:`torque_free_dynamics`.
    hx : callable, optional
        Default measurement function ``hx(q (B, S, 4), θ (B, S, m)) → (B, S)``.
    params : (m,) or (B, m) array, optional
        Initial parameter estimates ``θ``.
    process_noise : callable, optional
        ``Q(Δt, n) → (n, n)``; :class:`ProcessNoise` by default.
    alpha, beta, kappa : float
        Scaled sigma-point parameters (Wan & van der Merwe 2000). ``α = 1, β = 2, κ = 0``
        spreads the points ``√n σ`` from the mean.
    gate : float, optional
        NIS threshold of the innovation gate (``inf`` disables it); default
        :func:`default_gate`.
    underweighting : float
        ``γ`` of the underweighted gain (0: the standard update).

    Attributes
    ----------
    q : (B, 4) numpy.ndarray
        Attitude estimates (the reference of each member's GRP chart).
    x : (B, n) numpy.ndarray
        ``[δp, ω, θ]``; ``δp`` is zero between cycles.
    P : (B, n, n) numpy.ndarray
        Covariances of ``x``.
    divergence : (B,) object numpy.ndarray
        ``None`` for a live member; for a diverged one (see the module notes), the reason.

    Examples
    --------
    >>> import numpy as np
    >>> from filters.ukf import AttitudeUKF, torque_free_dynamics
    >>> ukf = AttitudeUKF([0, 0, 0, 1], [0.01, 0, 0], np.eye(6) * 1e-2,
    ...                   torque_free_dynamics(np.diag([1.0, 2.0, 3.0])))
    >>> ukf.predict(1.0)
    >>> result = ukf.update(0.1, 0.01, lambda q, p: q[..., 0])
    """

    def __init__(
        self,
        q: Any,
        omega: Any,
        covariance: Any,
        fx: Dynamics,
        *,
        hx: Measurement | None = None,
        params: Any = None,
        process_noise: Callable[[float, int], np.ndarray] | None = None,
        alpha: float = 1.0,
        beta: float = 2.0,
        kappa: float = 0.0,
        gate: float | None = None,
        underweighting: float = 0.0,
    ) -> None:
        q = np.atleast_2d(np.asarray(q, dtype=float))
        omega = np.atleast_2d(np.asarray(omega, dtype=float))
        b = max(len(q), len(omega))
        params = np.zeros((b, 0)) if params is None else np.atleast_2d(np.asarray(params, float))
        q, omega, params = (np.broadcast_to(v, (b, v.shape[-1])) for v in (q, omega, params))
        self.q = quaternion_normalize(np.array(q))
        self.x = np.concatenate([np.zeros((b, 3)), omega, params], axis=1)
        self.n = self.x.shape[1]
        p = np.asarray(covariance, dtype=float)
        if p.shape[-2:] != (self.n, self.n):
            raise ValueError(f"covariance must be {self.n}×{self.n}, got {p.shape}")
        self.P = np.array(np.broadcast_to(p, (b, self.n, self.n)))
        self.divergence = np.full(b, None, dtype=object)
        self.fx = fx
        self.hx = hx
        self.process_noise = process_noise or ProcessNoise(params=(0.0,) * params.shape[1])
        self.points = MerweScaledSigmaPoints(self.n, alpha=alpha, beta=beta, kappa=kappa)
        self.gate = default_gate() if gate is None else float(gate)
        self.underweighting = float(underweighting)
        self._noise_cache: tuple[float, Any] = (math.nan, None)

    @classmethod
    def stack(cls, filters: Sequence[AttitudeUKF]) -> AttitudeUKF:
        """One filter holding the members of several (in order), each member keeping its
        own dynamics (:func:`stack_dynamics`): a bank of models then runs every cycle's
        sigma points, propagation and unscented transforms in one batched call.

        Raises
        ------
        ValueError
            If the filters differ in state dimension, sigma-point parameters, process
            noise, gate or underweighting.
        """
        first = filters[0]
        settings = [
            (
                f.n,
                f.points.alpha,
                f.points.beta,
                f.points.kappa,
                f.process_noise,
                f.gate,
                f.underweighting,
            )
            for f in filters
        ]
        if any(s != settings[0] for s in settings):
            raise ValueError(
                "filters stacked into one must share the state dimension, sigma-point "
                "parameters, process noise, gate and underweighting"
            )
        out = cls.__new__(cls)
        out.__dict__.update(first.__dict__)
        out.q = np.concatenate([f.q for f in filters])
        out.x = np.concatenate([f.x for f in filters])
        out.P = np.concatenate([f.P for f in filters])
        out.divergence = np.concatenate([f.divergence for f in filters])
        out.fx = stack_dynamics([f.fx for f in filters], [len(f) for f in filters])
        out.hx = None
        out._noise_cache = (math.nan, None)
        return out

    def __len__(self) -> int:
        return len(self.x)

    # ------------------------------------------------------------------ accessors
    @property
    def omega(self) -> np.ndarray:
        """(B, 3) body-rate estimates (rad/s)."""
        return self.x[:, 3:6]

    @property
    def params(self) -> np.ndarray:
        """(B, m) parameter estimates ``θ``."""
        return self.x[:, 6:]

    @property
    def diverged(self) -> np.ndarray:
        """(B,) bool: the members that have diverged (see :attr:`divergence`)."""
        return np.array([d is not None for d in self.divergence], dtype=bool)

    def select(self, members: Any) -> None:
        """Keep only some members (an index or boolean mask over the bank)."""
        self.q, self.x, self.P = self.q[members], self.x[members], self.P[members]
        self.divergence = self.divergence[members]

    def _commit(
        self, q: np.ndarray, x: np.ndarray, p: np.ndarray, reason: Callable[[int], str]
    ) -> None:
        """Take the new ``(q̂, x̂, P)`` (``δp̂`` folded into ``q̂``) of the live members whose
        values are all finite; the others keep their last state, and those newly failing
        are marked diverged with the reason ``reason(member)``."""
        ok = (
            np.isfinite(q).all(axis=-1)
            & np.isfinite(x).all(axis=-1)
            & np.isfinite(p).all(axis=(-2, -1))
            & ~self.diverged
        )
        failed = ~ok & ~self.diverged
        for i in np.flatnonzero(failed):
            self.divergence[i] = reason(int(i))
        self.q = np.where(ok[:, None], q, self.q)
        self.q[ok] = quaternion_normalize(self.q[ok])
        self.x = np.where(ok[:, None], x, self.x)
        self.x[:, :3] = 0.0
        self.P = np.where(ok[:, None, None], 0.5 * (p + np.swapaxes(p, -1, -2)), self.P)

    # ------------------------------------------------------------------ cycle
    def _sigma_points(self, members: Any = _ALL) -> tuple[np.ndarray, np.ndarray]:
        """Sigma points of ``(x, P)`` of some members and their attitudes
        ``δq(δp_i) ⊗ q̂``."""
        p = self.P[members]
        fixed, root = _cholesky(p)
        if fixed is not p:
            self.P[members] = fixed
        sigmas = _sigma_points_of(self.points, self.x[members], root)
        q = quaternion_multiply(grp_to_quaternion(sigmas[..., :3]), self.q[members][:, None])
        return sigmas, q

    def _noise(self, dt: float) -> np.ndarray:
        """``Q(Δt)``, kept for the last step size (filters mostly step at one cadence)."""
        if self._noise_cache[0] != dt:
            self._noise_cache = (dt, self.process_noise(dt, self.n))
        return self._noise_cache[1]

    def predict(self, dt: float) -> None:
        """Propagate the estimates and covariances over ``dt`` seconds (USQUE step 2).

        A member whose propagated sigma points or moments are not finite diverges (see
        :attr:`divergence`) and keeps its last state.
        """
        if dt == 0.0:
            return
        sigmas, q = self._sigma_points()
        with np.errstate(over="ignore", invalid="ignore"):
            q_new, w_new = self.fx(q, sigmas[..., 3:6], sigmas[..., 6:], dt)
            q_new, w_new = np.asarray(q_new), np.asarray(w_new)
            norm = np.linalg.norm(q_new, axis=-1)
            finite = (
                np.isfinite(w_new).all(axis=(1, 2)) & np.isfinite(norm).all(1) & (norm > 0).all(1)
            )
            # Members that failed are carried through on their unpropagated sigma points
            # (finite), then kept at their last state by _commit.
            q_new = np.where(finite[:, None, None], q_new, q)
            w_new = np.where(finite[:, None, None], w_new, sigmas[..., 3:6])
            reference = q_new[:, :1]
            dp = quaternion_to_grp(quaternion_multiply(q_new, quaternion_conjugate(reference)))
            propagated = np.concatenate([dp, w_new, sigmas[..., 6:]], axis=-1)
            x, p = unscented_moments(self.points, propagated, self._noise(dt))
            q_mean = quaternion_multiply(grp_to_quaternion(x[:, :3]), reference[:, 0])
        q_mean[~finite] = np.nan
        rate = np.linalg.norm(sigmas[..., 3:6], axis=-1).max(axis=1)
        self._commit(
            q_mean,
            x,
            p,
            lambda i: (
                f"non-finite prediction over {dt:g} s (sigma-point rates up to {rate[i]:.3g} rad/s)"
            ),
        )

    def _measurement_moments(
        self, hx: Measurement | None, members: Any = _ALL
    ) -> tuple[np.ndarray, ...]:
        """``ẑ``, the state part of ``S`` and ``P_xz`` of a measurement, for some members."""
        hx = hx or self.hx
        if hx is None:
            raise ValueError("no measurement function given")
        sigmas, q = self._sigma_points(members)
        predicted = np.asarray(hx(q, sigmas[..., 6:]), dtype=float).reshape(len(sigmas), -1)
        z_hat = predicted @ self.points.Wm
        deviation = predicted - z_hat[:, None]
        weighted = deviation * self.points.Wc
        s_state = np.einsum("bs,bs->b", weighted, deviation)
        cross = np.einsum("bs,bsn->bn", weighted, sigmas - sigmas[:, :1])
        return z_hat, s_state, cross

    def evaluate(
        self, z: Any, r: Any, hx: Measurement | None = None, members: Any = None
    ) -> UpdateResult:
        """Innovation statistics of a measurement without using it (``gated`` all False).

        ``members`` (an index, slice or mask) evaluates only those members; ``hx`` then
        receives their sigma points only.
        """
        members = _ALL if members is None else members
        z_hat, s_state, _ = self._measurement_moments(hx, members)
        result = _innovation(z, r, z_hat, s_state, np.full(len(z_hat), np.inf))
        result.log_likelihood[self.diverged[members]] = -np.inf
        return result

    def update(self, z: Any, r: Any, hx: Measurement | None = None) -> UpdateResult:
        """Scalar measurement update (USQUE step 3) with innovation gating.

        Parameters
        ----------
        z : float or (B,) array
            Measurement of each member.
        r : float or (B,) array
            Its variance.
        hx : callable, optional
            ``hx(q (B, S, 4), θ (B, S, m)) → (B, S)`` for this measurement (else the
            default given at construction).

        Returns
        -------
        UpdateResult
        """
        z_hat, s_state, cross = self._measurement_moments(hx)
        result = _innovation(z, r, z_hat, s_state, np.full(len(self), self.gate))
        diverged = self.diverged
        if diverged.any():  # frozen: the measurement is not used and explains nothing
            result.gated[diverged] = True
            result.log_likelihood[diverged] = -np.inf
        s = result.variance
        s_gain = s + self.underweighting * s_state
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            gain = np.where(result.gated[:, None], 0.0, cross / s_gain[:, None])
            x = self.x + gain * np.where(result.gated, 0.0, result.innovation)[:, None]
            shrink = np.where(result.gated, 0.0, (2.0 * s_gain - s) / s_gain**2)
            p = self.P - np.einsum("bi,bj->bij", cross, cross) * shrink[:, None, None]
            q = quaternion_multiply(grp_to_quaternion(x[:, :3]), self.q)
        self._commit(q, x, p, lambda i: "non-finite measurement update")
        return result


def _innovation(
    z: Any, r: Any, z_hat: np.ndarray, s_state: np.ndarray, gate: np.ndarray
) -> UpdateResult:
    b = len(z_hat)
    z = np.broadcast_to(np.asarray(z, dtype=float), (b,))
    r = np.broadcast_to(np.asarray(r, dtype=float), (b,))
    s = s_state + r
    nu = z - z_hat
    nis = nu * nu / s
    log_likelihood = -0.5 * (np.log(2.0 * math.pi * s) + nis)
    return UpdateResult(z_hat, nu, s, nis, log_likelihood, ~(nis <= gate))


def _cholesky(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(P, L)`` with ``L Lᵀ = P``; covariances without a Cholesky factor get their
    eigenvalues floored first (returned as the new ``P``)."""
    try:
        return p, np.linalg.cholesky(p)
    except np.linalg.LinAlgError:
        values, vectors = np.linalg.eigh(0.5 * (p + np.swapaxes(p, -1, -2)))
        floor = np.maximum(1e-12 * np.max(np.abs(values), axis=-1, keepdims=True), 1e-30)
        p = (vectors * np.maximum(values, floor)[..., None, :]) @ np.swapaxes(vectors, -1, -2)
        return p, np.linalg.cholesky(p)
