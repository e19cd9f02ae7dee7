"""Gravity of a small body: point mass plus normalised spherical harmonics.

The exterior potential of Li et al. 2024, eq. 3 (Kaula's form, geodesy sign convention ``U = ∇V``),

``V = μ/a Σ_{n=0}^{N} Σ_{m=0}^{n} (a/r)^{n+1} P̄_nm(sin φ) (C̄_nm cos mλ + S̄_nm sin mλ)``,

with fully normalised coefficients ``C̄_nm, S̄_nm`` (``C̄_00 = 1``) and Legendre functions
``P̄_nm = N_nm P_nm``, ``N_nm = √((2 − δ_0m)(2n + 1)(n − m)!/(n + m)!)``. Potential and
acceleration are evaluated with Cunningham's recursion of the solid harmonics ``V_nm, W_nm``
in Cartesian body-fixed coordinates, which has no singularity at the poles (Montenbruck &
Gill 2000, *Satellite Orbits*, sec. 3.2.4–3.2.5, eqs. 3.28–3.33). Degree 0 is exactly the
point mass ``V = μ/r``, ``U = −μ r/r³``.

Positions are in the body-fixed frame of the small body (m); ``μ`` in m³/s²; accelerations in
m/s²; potentials in m²/s². Every function accepts numpy arrays or torch tensors with leading
batch dimensions (the torch path lets autograd differentiate the potential).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from array_api_compat import device as array_device

from filters.attitude.arrays import as_arrays

__all__ = [
    "EROS_DEGREE2",
    "EROS_MU",
    "EROS_REFERENCE_RADIUS",
    "SphericalHarmonicGravity",
    "normalization_factor",
]

#: Gravitational parameter of 433 Eros (m³/s²), Li et al. 2024, table 1 (Yeomans et al. 2000).
EROS_MU = 446300.0
#: Reference radius (m) of the Eros coefficients below (Miller et al. 2002).
EROS_REFERENCE_RADIUS = 16000.0
#: Degree-2 normalised coefficients of 433 Eros ``(n, m, C̄_nm, S̄_nm)`` from the NEAR radio
#: science solution (Miller et al. 2002, Icarus 155, table III; reference radius 16 km).
EROS_DEGREE2 = ((2, 0, -0.052478, 0.0), (2, 1, 0.0, 0.0), (2, 2, 0.082538, -0.027745))


def normalization_factor(n: int, m: int) -> float:
    """Kaula's normalisation ``N_nm`` with ``C_nm = N_nm C̄_nm`` (unnormalised = N × normalised).

    Parameters
    ----------
    n, m : int
        Degree and order, ``0 ≤ m ≤ n``.

    Returns
    -------
    float
    """
    if not 0 <= m <= n:
        raise ValueError(f"order m={m} must satisfy 0 <= m <= n={n}")
    delta = 1.0 if m == 0 else 2.0
    return math.sqrt(delta * (2 * n + 1) * math.factorial(n - m) / math.factorial(n + m))


@dataclass(frozen=True)
class SphericalHarmonicGravity:
    """Spherical-harmonic gravity field of a small body (Li et al. 2024, eqs. 2–3).

    Parameters
    ----------
    mu : float
        Gravitational parameter ``μ = GM`` (m³/s²).
    radius : float
        Reference radius ``a`` of the coefficients (m).
    c, s : (N+1, N+1) array
        Normalised coefficients ``C̄_nm``, ``S̄_nm`` in the lower triangle (``m ≤ n``);
        ``c[0, 0]`` is the mass term (1 for the true mass), ``s[:, 0]`` is ignored.

    Examples
    --------
    >>> field = SphericalHarmonicGravity.from_coefficients(EROS_MU, 16000.0, EROS_DEGREE2)
    >>> field.acceleration([20000.0, 0.0, 0.0]).shape
    (3,)
    """

    mu: float
    radius: float
    c: np.ndarray = field(repr=False)
    s: np.ndarray = field(repr=False)
    _weights: dict[str, list] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.mu) and self.mu > 0):
            raise ValueError(
                f"gravitational parameter mu must be positive (m^3/s^2), got {self.mu}"
            )
        if not (math.isfinite(self.radius) and self.radius > 0):
            raise ValueError(f"reference radius must be positive (m), got {self.radius}")
        c = np.array(self.c, dtype=float)
        s = np.array(self.s, dtype=float)
        if c.ndim != 2 or c.shape[0] != c.shape[1] or c.shape != s.shape:
            raise ValueError("coefficient arrays c and s must both be square (N+1, N+1)")
        c = np.tril(c)
        s = np.tril(s) * (np.arange(c.shape[0]) > 0)[None, :]
        object.__setattr__(self, "c", c)
        object.__setattr__(self, "s", s)
        object.__setattr__(self, "_weights", _contraction_weights(c, s))

    @classmethod
    def point_mass(cls, mu: float, radius: float = 1.0) -> SphericalHarmonicGravity:
        """Degree-0 field ``V = μ/r``."""
        return cls(mu, radius, np.ones((1, 1)), np.zeros((1, 1)))

    @classmethod
    def from_coefficients(
        cls,
        mu: float,
        radius: float,
        coefficients: Sequence[Sequence[float]],
        degree: int | None = None,
    ) -> SphericalHarmonicGravity:
        """Field from rows ``(n, m, C̄_nm, S̄_nm)``; ``C̄_00 = 1`` is implied.

        Parameters
        ----------
        mu, radius : float
            ``μ`` (m³/s²) and reference radius (m).
        coefficients : sequence of (n, m, C, S)
            Normalised coefficients; unlisted ones are zero.
        degree : int, optional
            Truncation degree (default: the largest ``n`` listed). Rows above it are dropped.

        Returns
        -------
        SphericalHarmonicGravity
        """
        rows = [tuple(row) for row in coefficients]
        for i, row in enumerate(rows):
            if len(row) != 4:
                raise ValueError(f"coefficient row {i} must be [n, m, C, S], got {list(row)}")
            n, m = row[0], row[1]
            if int(n) != n or int(m) != m or not 0 <= m <= n:
                raise ValueError(f"coefficient row {i}: need integers 0 <= m <= n, got n={n} m={m}")
        top = max((int(r[0]) for r in rows), default=0)
        degree = top if degree is None else int(degree)
        if degree < 0:
            raise ValueError(f"degree must be >= 0, got {degree}")
        c = np.zeros((degree + 1, degree + 1))
        s = np.zeros_like(c)
        c[0, 0] = 1.0
        for n, m, cnm, snm in rows:
            if int(n) <= degree:
                c[int(n), int(m)] = cnm
                s[int(n), int(m)] = snm
        return cls(mu, radius, c, s)

    @property
    def degree(self) -> int:
        """Truncation degree ``N``."""
        return self.c.shape[0] - 1

    def truncated(self, degree: int) -> SphericalHarmonicGravity:
        """The same field up to ``degree`` (0 gives the point mass)."""
        if not 0 <= degree <= self.degree:
            raise ValueError(f"degree must be in [0, {self.degree}], got {degree}")
        k = degree + 1
        return SphericalHarmonicGravity(self.mu, self.radius, self.c[:k, :k], self.s[:k, :k])

    def _solid_harmonics(self, position: Any) -> tuple[Any, list[list[Any]]]:
        """Cunningham's ``Z_nm = V_nm + i W_nm`` up to degree ``N + 1`` (M&G eqs. 3.29–3.31).

        ``V_nm = (a/r)^{n+1} P_nm(sin φ) cos mλ`` and ``W_nm`` the same with ``sin mλ``
        (unnormalised ``P_nm``); returns the namespace and the nested list ``Z[n][m]``.
        """
        xp, (r,) = as_arrays(position)
        x, y, z = r[..., 0], r[..., 1], r[..., 2]
        r2 = x * x + y * y + z * z
        a = self.radius
        xy, z0, rho = (a * x + 1j * (a * y)) / r2, a * z / r2, a * a / r2
        top = self.degree + 1
        zz: list[list[Any]] = [[None] * (top + 1) for _ in range(top + 1)]
        zz[0][0] = a / xp.sqrt(r2) + 0j
        for m in range(top + 1):
            if m > 0:
                zz[m][m] = (2 * m - 1) * xy * zz[m - 1][m - 1]
            for n in range(m + 1, top + 1):
                k1, k2 = (2 * n - 1) / (n - m), (n + m - 1) / (n - m)
                zz[n][m] = k1 * z0 * zz[n - 1][m]
                if n - 2 >= m:
                    zz[n][m] = zz[n][m] - k2 * rho * zz[n - 2][m]
        return xp, zz

    def _contract(self, zz: list[list[Any]], name: str) -> Any:
        total = 0
        for n, m, w in self._weights[name]:
            total = total + w * zz[n][m]
        return total

    def potential(self, position: Any) -> Any:
        """Gravitational potential ``V`` (m²/s², positive, ``U = ∇V``), Li et al. 2024, eq. 3.

        Parameters
        ----------
        position : (..., 3) array
            Body-fixed position (m), outside the reference sphere for a convergent series.

        Returns
        -------
        (...) array
        """
        xp, zz = self._solid_harmonics(position)
        return self.mu / self.radius * xp.real(self._contract(zz, "potential"))

    def acceleration(self, position: Any) -> Any:
        """Gravitational acceleration ``U = ∂V/∂r`` (m/s²), Li et al. 2024, eq. 2.

        Montenbruck & Gill (2000) eq. 3.33, the exact derivative of :meth:`potential`.

        Parameters
        ----------
        position : (..., 3) array
            Body-fixed position (m).

        Returns
        -------
        (..., 3) array
        """
        xp, zz = self._solid_harmonics(position)
        ax = xp.real(self._contract(zz, "x"))
        ay = xp.imag(self._contract(zz, "y"))
        az = xp.real(self._contract(zz, "z"))
        return self.mu / self.radius**2 * xp.stack([ax, ay, az], axis=-1)

    def gradient(self, position: Any, step: float = 1e-4) -> Any:
        """Gravity-gradient tensor ``∂U/∂r`` (1/s²) by central differences of :meth:`acceleration`.

        Parameters
        ----------
        position : (..., 3) array
            Body-fixed position (m).
        step : float
            Relative step (times ``|r|``).

        Returns
        -------
        (..., 3, 3) array
            ``G[..., i, j] = ∂U_i/∂r_j``; symmetric to rounding.
        """
        xp, (r,) = as_arrays(position)
        h = step * xp.linalg.vector_norm(r, axis=-1, keepdims=True)[..., None]
        offsets = h * xp.eye(3, dtype=r.dtype, device=array_device(r))  # row j: step along j
        plus = self.acceleration(r[..., None, :] + offsets)
        minus = self.acceleration(r[..., None, :] - offsets)
        grad_t = (plus - minus) / (2 * h)  # (..., j, i)
        return xp.matrix_transpose(grad_t)


def _contraction_weights(c: np.ndarray, s: np.ndarray) -> dict[str, list]:
    """Complex weights turning ``Z_nm`` into ``V`` and ``U`` (M&G eq. 3.33).

    With ``K_nm = N_nm (C̄_nm − i S̄_nm)``, ``C V + S W = Re(K Z)`` and ``C W − S V = Im(K Z)``,
    so the potential is ``Re Σ K_nm Z_nm`` and each acceleration component is the real or
    imaginary part of a weighted sum of degree-``n + 1`` harmonics. Returns, per quantity,
    the non-zero ``(n, m, weight)`` terms.
    """
    degree = c.shape[0] - 1
    size = degree + 2
    dense = {key: np.zeros((size, size), dtype=complex) for key in ("potential", "x", "y", "z")}
    for n in range(degree + 1):
        for m in range(n + 1):
            k = normalization_factor(n, m) * (c[n, m] - 1j * s[n, m])
            if k == 0:
                continue
            dense["potential"][n, m] += k
            dense["z"][n + 1, m] -= (n - m + 1) * k
            if m == 0:
                dense["x"][n + 1, 1] -= k
                dense["y"][n + 1, 1] -= k
            else:
                f = math.factorial(n - m + 2) / math.factorial(n - m)
                dense["x"][n + 1, m + 1] -= 0.5 * k
                dense["x"][n + 1, m - 1] += 0.5 * f * k
                dense["y"][n + 1, m + 1] -= 0.5 * k
                dense["y"][n + 1, m - 1] -= 0.5 * f * k
    return {
        key: [(int(n), int(m), complex(w[n, m])) for n, m in zip(*np.nonzero(w), strict=True)]
        for key, w in dense.items()
    }
