"""The global search's problem and candidate types: the batch problem (measurements and
the model predicting them from initial states), the Gaussian prior on the initial state,
batches of candidates and the ranked result.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np
import torch

from filters.attitude import (
    PrincipalInertia,
    quaternion_conjugate,
    quaternion_multiply,
    quaternion_to_rotation_vector,
    ratios_from_tanh,
    rotation_vector_to_quaternion,
    tanh_from_inertia,
    torque_free_trajectory,
)

#: ``measure(q (N, E, 4), epochs (E,), shape (N,)) → (N, E)`` predicted measurements.
Measure = Callable[[torch.Tensor, np.ndarray, torch.Tensor], torch.Tensor]
#: A number of candidates, shared by every shape index or one per shape index.
Count = int | np.ndarray
#: ``twins(q, ω, shape) → [(q', ω', has_twin), …]`` (numpy), one triple per kind of twin.
Twins = Callable[[np.ndarray, np.ndarray, np.ndarray], Sequence[tuple]]


@dataclass(frozen=True)
class Prior:
    """Gaussian prior on the initial state: ``δθ ~ N(0, σ_θ² I)`` about ``q``,
    ``ω ~ N(ω̄, diag σ_ω²)``.

    Parameters
    ----------
    q : (4,) array
        Prior mean attitude (inertial → body).
    omega : (3,) array
        Prior mean body rates (rad/s).
    attitude_sigma : float
        1σ of each component of the body-frame rotation vector (rad).
    omega_sigma : float or (3,) array
        1σ of the rates (rad/s).
    """

    q: np.ndarray
    omega: np.ndarray
    attitude_sigma: float
    omega_sigma: Any

    @classmethod
    def rates_only(cls, omega_max: float) -> Prior:
        """The weak rate prior ``ω ~ N(0, omega_max²)`` with no attitude term, which bounds
        the rates along directions the data leave unobserved (the spin about a symmetry
        axis): without it Levenberg–Marquardt wanders there to rates where the
        propagation breaks down."""
        return cls(np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3), math.inf, omega_max)

    def sample(self, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """``n`` draws; the first one is the prior mean itself."""
        dtheta = rng.standard_normal((n, 3)) * self.attitude_sigma
        dtheta[0] = 0.0
        q = quaternion_multiply(rotation_vector_to_quaternion(dtheta), np.asarray(self.q, float))
        omega = np.asarray(self.omega, float) + rng.standard_normal((n, 3)) * np.asarray(
            self.omega_sigma, float
        )
        omega[0] = self.omega
        return q, omega

    def residuals(self, q: torch.Tensor, omega: torch.Tensor) -> torch.Tensor:
        """Whitened deviations ``[rotvec(q ⊗ q̄⁻¹)/σ_θ, (ω − ω̄)/σ_ω]``, shape (N, 6)."""
        q_bar = torch.as_tensor(np.asarray(self.q, float), dtype=q.dtype)
        dtheta = quaternion_to_rotation_vector(quaternion_multiply(q, quaternion_conjugate(q_bar)))
        sigma_w = torch.as_tensor(np.broadcast_to(self.omega_sigma, (3,)).copy(), dtype=q.dtype)
        w_bar = torch.as_tensor(np.asarray(self.omega, float), dtype=q.dtype)
        return torch.cat([dtheta / self.attitude_sigma, (omega - w_bar) / sigma_w], dim=1)

    def information(self, n_params: int) -> torch.Tensor:
        """Diagonal information ``diag(1/σ²)`` on ``[δθ, ω]`` (zero for further unknowns)."""
        sigma = np.concatenate(
            [np.full(3, self.attitude_sigma), np.broadcast_to(self.omega_sigma, (3,))]
        )
        info = np.zeros(n_params)
        info[:6] = 1.0 / sigma**2
        return torch.diag(torch.as_tensor(info))


@dataclass
class BatchProblem:
    """Measurements of one object and the model predicting them from initial states.

    Parameters
    ----------
    times : (E,) array
        Measurement times (s) since the reference epoch of the initial states.
    measured : (E,) array
        Measurements.
    sigma : (E,) array
        Their 1σ errors.
    measure : callable
        ``measure(q, epochs, shape)``: predictions for attitudes ``q (N, E_sel, 4)`` at
        the measurement indices ``epochs (E_sel,)`` for candidates of shape index
        ``shape (N,)`` (torch; evaluated without gradients).
    inertias : sequence of (3, 3) arrays
        Body-frame inertia of each shape (any scale).
    principal_axes : sequence of (3, 3) arrays, optional
        Principal axes (columns) of each shape, used when the tanh inertia parameters
        ``k`` are estimated (``J = P diag(J(k)) Pᵀ``).
    estimate_inertia : bool
        Add the tanh parameters ``k = [k1, k2]`` (Feng et al.) to the unknowns.
    inertia_sigma : float
        With ``estimate_inertia``: 1σ of a Gaussian prior on ``k`` about each shape's own
        value (its mesh's inertia), whose whitened deviations join the residuals, and the
        candidates start at that value. ``inf`` (default): no prior, and the candidates'
        ``k`` are searched uniformly (an inertia not known at all). Without a prior, ``k``
        is free to run along the directions a short window does not constrain (values of
        10⁴ were seen), where ``tanh`` saturates at the most extreme inertia.
    free_offset : bool
        The measurements carry an unknown common offset (a magnitude offset: the
        albedo–area scale of a candidate that is not exactly the object). It is profiled
        out: every candidate's residuals are those at its best offset, the projection
        ``r ← r − u (uᵀr)/(uᵀu)``, ``u = 1/σ`` (a linear nuisance parameter eliminated
        exactly, Golub & Pereyra 1973), and so are the data rows of the Jacobian.
    max_step : float
        Largest RK4 step of the propagation (s). RK4's error per step on a rotation by
        ``θ = |ω| h`` is about ``θ⁵/3840`` rad: 1.4·10⁻⁶ rad at 5°/s and 4 s, 0.01° over
        10 min, far below what 0.05 mag photometry resolves.
    dtype : torch.dtype
        Precision of the propagation and of the least squares.
    """

    times: np.ndarray
    measured: np.ndarray
    sigma: np.ndarray
    measure: Measure
    inertias: Sequence[np.ndarray]
    principal_axes: Sequence[np.ndarray] | None = None
    estimate_inertia: bool = False
    inertia_sigma: float = math.inf
    free_offset: bool = False
    max_step: float = 4.0
    dtype: torch.dtype = torch.float64
    _principal: PrincipalInertia = field(init=False, repr=False)
    _tanh_frames: PrincipalInertia = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.times = np.asarray(self.times, dtype=float)
        self.measured = np.asarray(self.measured, dtype=float)
        self.sigma = np.asarray(self.sigma, dtype=float)
        if np.any(np.diff(self.times) < 0):
            raise ValueError("times must be non-decreasing")
        self._principal = PrincipalInertia.from_inertia(np.stack(self.inertias))
        axes = self.principal_axes or [np.eye(3)] * len(self.inertias)
        self._tanh_frames = PrincipalInertia.from_tanh(np.zeros(2), np.stack(axes))

    @property
    def k_mean(self) -> np.ndarray:
        """Tanh parameters of every shape's own inertia, shape (S, 2) (a plate-like
        inertia's nearest tanh form)."""
        moments = np.sort(np.linalg.eigvalsh(np.stack(self.inertias)), axis=-1)
        return np.stack([tanh_from_inertia(m, margin=1e-6) for m in moments])  # (3,) each

    @property
    def has_inertia_prior(self) -> bool:
        """``k`` is estimated under a prior (finite ``inertia_sigma``)."""
        return self.estimate_inertia and math.isfinite(self.inertia_sigma)

    def inertia_residuals(self, k: torch.Tensor, shape: torch.Tensor) -> torch.Tensor:
        """Whitened prior deviations ``(k − k̄_shape)/σ_k``, shape (N, 2)."""
        mean = torch.as_tensor(self.k_mean, dtype=k.dtype)[shape]
        return (k - mean) / self.inertia_sigma

    @property
    def n_params(self) -> int:
        """Unknowns per candidate: 6, or 8 with the inertia."""
        return 8 if self.estimate_inertia else 6

    def window(self, duration: float, count: int) -> np.ndarray:
        """Indices of at most ``count`` measurements, evenly spread over the first
        ``duration`` seconds."""
        inside = np.flatnonzero(self.times <= self.times[0] + duration)
        if len(inside) <= count:
            return inside
        return inside[np.round(np.linspace(0, len(inside) - 1, count)).astype(int)]

    def trajectory(
        self,
        q0: torch.Tensor,
        omega0: torch.Tensor,
        k: Any,
        shape: torch.Tensor,
        epochs: Any,
        t_start: float = 0.0,
    ) -> torch.Tensor:
        """Attitudes at the given epochs of states known at ``t_start`` (torque-free RK4).

        Parameters
        ----------
        q0 : (N, 4) tensor
        omega0 : (N, 3) tensor
        k : (N, 2) tensor or None
            Tanh inertia parameters (with ``estimate_inertia``).
        shape : (N,) long tensor
        epochs : (E,) int array
            Measurement indices; epochs before ``t_start`` are reached backwards in time.
        t_start : float
            Time of the given states (s, on the axis of :attr:`times`).

        Returns
        -------
        (N, E, 4) tensor
        """
        rows = shape.numpy()
        if k is None:
            shared = bool((rows == rows[0]).all())
            inertia = self._principal.select(rows[0] if shared else rows)
        else:
            frames = self._tanh_frames.select(rows)
            inertia = frames._replace(ratios=ratios_from_tanh(k.detach().numpy()))
        offsets = self.times[np.asarray(epochs)] - t_start
        q, _ = torque_free_trajectory(q0, omega0, offsets, inertia, self.max_step)
        return q

    def residuals_of(self, q: torch.Tensor, shape: torch.Tensor, epochs: Any) -> torch.Tensor:
        """Normalised residuals ``(m̂ − m)/σ`` of attitudes ``q (N, E, 4)``, shape (N, E)."""
        measured = torch.as_tensor(self.measured[epochs], dtype=self.dtype)
        sigma = torch.as_tensor(self.sigma[epochs], dtype=self.dtype)
        return (self.measure(q, np.asarray(epochs), shape) - measured) / sigma

    def residuals(
        self, q0: torch.Tensor, omega0: torch.Tensor, k: Any, shape: torch.Tensor, epochs: Any
    ) -> torch.Tensor:
        """Normalised residuals of initial states (offset profiled out with
        ``free_offset``), shape (N, E)."""
        r = self.residuals_of(self.trajectory(q0, omega0, k, shape, epochs), shape, epochs)
        return self.profiled(r, epochs)

    def profiled(self, values: torch.Tensor, epochs: Any) -> torch.Tensor:
        """Residuals ``(N, E)`` or Jacobian rows ``(N, E, p)`` of the measurements
        ``epochs`` with the common offset profiled out (unchanged without
        ``free_offset``)."""
        if not self.free_offset:
            return values
        u = torch.as_tensor(1.0 / self.sigma[np.asarray(epochs)], dtype=values.dtype)
        if values.dim() == 2:
            return values - u * ((values @ u) / (u @ u))[:, None]
        return values - u[:, None] * (torch.einsum("nep,e->np", values, u) / (u @ u))[:, None]


@dataclass
class SearchResult:
    """Ranked candidate initial states at the reference epoch.

    Attributes
    ----------
    q : (M, 4) numpy.ndarray
        Attitudes (inertial → body).
    omega : (M, 3) numpy.ndarray
        Body rates (rad/s).
    k : (M, 2) numpy.ndarray or None
        Tanh inertia parameters (when estimated).
    shape : (M,) int numpy.ndarray
        Shape index.
    chi2 : (M,) numpy.ndarray
        ``Σ r²`` on the final window (ascending).
    covariance : (M, p, p) numpy.ndarray
        Gauss–Newton covariance ``(JᵀJ)⁻¹`` of ``[δθ, ω(, k)]``.
    epochs : (E,) int numpy.ndarray
        Measurement indices of the final window.
    screened : int
        Number of candidates screened.
    """

    q: np.ndarray
    omega: np.ndarray
    k: np.ndarray | None
    shape: np.ndarray
    chi2: np.ndarray
    covariance: np.ndarray
    epochs: np.ndarray
    screened: int

    def __len__(self) -> int:
        return len(self.chi2)


@dataclass
class Candidates:
    """A batch of candidate states at one epoch: torch tensors, one row per candidate.

    Attributes
    ----------
    q : (N, 4) tensor
        Attitudes (inertial → body).
    omega : (N, 3) tensor
        Body rates (rad/s).
    shape : (N,) long tensor
        Shape index.
    k : (N, 2) tensor or None
        Tanh inertia parameters (with ``estimate_inertia``).
    chi2 : (N,) tensor or None
        ``Σ r²`` of the last fit (prior rows included); None before any fit.
    covariance : (N, p, p) tensor or None
        Gauss–Newton covariance of ``[η, ω(, k)]`` at the last fit.
    """

    q: torch.Tensor
    omega: torch.Tensor
    shape: torch.Tensor
    k: torch.Tensor | None = None
    chi2: torch.Tensor | None = None
    covariance: torch.Tensor | None = None

    def __len__(self) -> int:
        return len(self.q)

    @property
    def params(self) -> torch.Tensor:
        """``[ω(, k)]``, shape (N, p − 3)."""
        return self.omega if self.k is None else torch.cat([self.omega, self.k], dim=1)

    def take(self, index: Any) -> Candidates:
        """The candidates selected by an index tensor, slice or mask."""
        return Candidates(
            **{
                f.name: None if getattr(self, f.name) is None else getattr(self, f.name)[index]
                for f in fields(self)
            }
        )

    @classmethod
    def concat(cls, parts: Sequence[Candidates]) -> Candidates:
        """The candidates of several batches, in order (a field missing in any batch is
        dropped)."""
        return cls(
            **{
                f.name: None
                if any(getattr(p, f.name) is None for p in parts)
                else torch.cat([getattr(p, f.name) for p in parts])
                for f in fields(cls)
            }
        )
