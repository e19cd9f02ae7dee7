"""The models an attitude UKF propagates with: torque-free dynamics and process noise.

``fx(q, ω, θ, Δt) → (q', ω')`` propagates the attitude and body rates of every sigma point
(:class:`TorqueFreeDynamics`: fixed-step RK4 in principal axes, the inertia fixed or
estimated through the tanh parameters of Feng et al.); :class:`ProcessNoise` discretises the
continuous white-noise densities of the state ``[δp, ω, θ]`` over one step. Both are used by
:class:`filters.ukf.AttitudeUKF` (and importable from :mod:`filters.ukf`).

References
----------
Crassidis, J. L. & Markley, F. L. (2003). Unscented filtering for spacecraft attitude
estimation. *J. Guidance, Control, and Dynamics* 26(4), 536–542.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from filters.attitude import PrincipalInertia, propagate_torque_free, ratios_from_tanh

__all__ = [
    "Dynamics",
    "Measurement",
    "ProcessNoise",
    "TorqueFreeDynamics",
    "stack_dynamics",
    "torque_free_dynamics",
]

#: ``fx(q (..., 4), ω (..., 3), θ (..., m), Δt) → (q', ω')``.
Dynamics = Callable[[np.ndarray, np.ndarray, np.ndarray, float], tuple[np.ndarray, np.ndarray]]
#: ``hx(q (B, S, 4), θ (B, S, m)) → z (B, S)``.
Measurement = Callable[[np.ndarray, np.ndarray], np.ndarray]


@dataclass(frozen=True)
class TorqueFreeDynamics:
    """``fx`` of torque-free motion: fixed-step RK4 in principal axes
    (:func:`~filters.attitude.propagate_torque_free`), with the inertia fixed or estimated.

    Build it with :func:`torque_free_dynamics`; :func:`stack_dynamics` joins the dynamics of
    several filters into one whose members each keep their own inertia.

    Attributes
    ----------
    inertia : PrincipalInertia
        Principal axes and ratios, shared or per member (leading member axis and a
        singleton sigma-point axis, ``(B, 1, ...)``). With ``tanh_index`` the ratios come
        from the parameters and only the axes are used.
    max_step : float
        Largest RK4 step (s).
    tanh_index : (int, int) or None
        Positions of ``k1, k2`` in the parameter vector ``θ``.
    """

    inertia: PrincipalInertia
    max_step: float = 1.0
    tanh_index: tuple[int, int] | None = None

    def __call__(self, q: Any, omega: Any, params: Any, dt: float) -> tuple[Any, Any]:
        inertia = self.inertia
        if self.tanh_index is not None:
            k = params[..., list(self.tanh_index)]
            inertia = inertia._replace(ratios=ratios_from_tanh(k))
        return propagate_torque_free(q, omega, inertia, dt, self.max_step)


def torque_free_dynamics(
    inertia: Any,
    max_step: float = 1.0,
    tanh_index: tuple[int, int] | None = None,
    principal_axes: Any = None,
) -> TorqueFreeDynamics:
    """Build ``fx`` for torque-free motion, with the inertia fixed or estimated.

    Parameters
    ----------
    inertia : (3, 3) array
        Body-frame inertia used when ``tanh_index`` is None.
    max_step : float
        Largest RK4 step (s).
    tanh_index : (int, int), optional
        Positions of ``k1, k2`` in the parameter vector ``θ``: then every sigma point has
        its own inertia ``J = P diag(J(k)) Pᵀ`` (the tanh form of Feng et al., always physical).
    principal_axes : (3, 3) array, optional
        Columns = principal axes in the body frame (``P`` above); identity by default.

    Returns
    -------
    TorqueFreeDynamics
        ``fx(q, ω, θ, Δt) → (q', ω')``.
    """
    if tanh_index is None:
        principal = PrincipalInertia.from_inertia(np.asarray(inertia, dtype=float))
    else:
        principal = PrincipalInertia.from_tanh(np.zeros(2), principal_axes)
    return TorqueFreeDynamics(principal, float(max_step), tanh_index)


def stack_dynamics(dynamics: Sequence[Dynamics], counts: Sequence[int]) -> Dynamics:
    """The dynamics of a stack of filters: ``counts[j]`` members following ``dynamics[j]``.

    Torque-free dynamics with the same step and parameterisation become one
    :class:`TorqueFreeDynamics` with an inertia per member, propagated in one call; other
    callables are applied to their own members in turn.
    """
    counts = [int(c) for c in counts]
    first = dynamics[0]
    if all(
        isinstance(d, TorqueFreeDynamics)
        and (d.max_step, d.tanh_index) == (first.max_step, first.tanh_index)
        for d in dynamics
    ):
        fields = [
            np.concatenate(
                [
                    np.repeat(np.asarray(f)[None], c, axis=0)
                    for f, c in zip(parts, counts, strict=True)
                ]
            )[:, None]
            for parts in zip(*(d.inertia for d in dynamics), strict=True)
        ]
        return TorqueFreeDynamics(PrincipalInertia(*fields), first.max_step, first.tanh_index)
    bounds = np.cumsum([0, *counts])

    def stacked(q: Any, omega: Any, params: Any, dt: float) -> tuple[Any, Any]:
        out = [
            f(q[a:b], omega[a:b], params[a:b], dt)
            for f, a, b in zip(dynamics, bounds[:-1], bounds[1:], strict=True)
        ]
        return np.concatenate([o[0] for o in out]), np.concatenate([o[1] for o in out])

    return stacked


@dataclass(frozen=True)
class ProcessNoise:
    """Continuous white-noise densities of the UKF state, discretised per step.

    Attitude-error noise ``σ_θ²`` (rad²/s) and angular-acceleration noise ``σ_a²``
    (rad²/s³, acting on ``ω``) give, for a step ``Δt`` (the kinematic pair
    ``δθ̇ = δω``):

    ``Q_θθ = σ_θ² Δt + σ_a² Δt³/3``, ``Q_θω = σ_a² Δt²/2``, ``Q_ωω = σ_a² Δt``,

    and each parameter random-walks with density ``σ_p²`` (units²/s). The GRP scale
    ``f = 4`` makes the attitude error in GRPs equal to the angle in radians to first order.

    Parameters
    ----------
    attitude : float
        ``σ_θ²``, rad²/s.
    rate : float
        ``σ_a²``, rad²/s³.
    params : tuple of float
        ``σ_p²`` per parameter, units²/s.
    """

    attitude: float = 1e-10
    rate: float = 1e-12
    params: tuple[float, ...] = ()

    def __call__(self, dt: float, n: int) -> np.ndarray:
        dt = abs(dt)
        q = np.zeros((n, n))
        eye = np.eye(3)
        q[:3, :3] = (self.attitude * dt + self.rate * dt**3 / 3.0) * eye
        q[:3, 3:6] = q[3:6, :3] = self.rate * dt**2 / 2.0 * eye
        q[3:6, 3:6] = self.rate * dt * eye
        for i, density in enumerate(self.params):
            q[6 + i, 6 + i] = density * dt
        return q
