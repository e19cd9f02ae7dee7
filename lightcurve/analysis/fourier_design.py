"""The weighted least-squares design of Fourier series in one or more frequencies, with
per-curve nuisance terms: shared by the one-period search
(:mod:`lightcurve.analysis.period`) and the two-period analysis
(:mod:`lightcurve.analysis.tumbling`)."""

from __future__ import annotations

import numpy as np

__all__ = ["FourierDesign"]


class FourierDesign:
    """Weighted least squares of a Fourier model with per-curve nuisance terms (shared setup).

    The model is a sum of terms ``a cos(n·ψ) + b sin(n·ψ)`` over integer combination vectors
    ``n`` of one or more phases ``ψ_d = 2π f_d t`` (the first one minus ``phase_offset``):
    one phase with ``n = 1..K`` is the K-harmonic series of :func:`period_search`, two
    phases with the combinations ``j f1 + k f2`` are the two-period series of
    :mod:`lightcurve.analysis.tumbling`. Each curve has its own zero point and, with
    ``trend_degree = d > 0``, its own polynomial ``Σ_{i ≤ d} c_i P_i(τ)`` (Legendre
    polynomials of the curve's time scaled to τ ∈ [−1, 1]): the slow change of the mean
    brightness with the geometry (range, phase angle) over a night or a pass, which a
    Fourier series of the rotation cannot follow. These nuisance columns ``G`` are
    eliminated by projection: with ``Q = G L⁻ᵀ`` (``L Lᵀ = GᵀWG``, so ``QᵀWQ = 1``) the
    normal matrix of the Fourier terms is ``XWXᵀ − (XWQ)(XWQ)ᵀ`` and the data are
    projected once, so every trial needs only a ``2P × 2P`` system for P terms.
    """

    def __init__(self, times, values, sigma, curve, phase_offset=None, *, trend_degree=0) -> None:
        self.t = np.asarray(times, float) - float(np.min(times))
        self.w = 1.0 / np.asarray(sigma, float) ** 2
        self.tau = _curve_time(self.t, curve)
        self.nuisance = _orthonormal_nuisance(self.tau, self.w, curve, trend_degree)
        self.n_nuisance = self.nuisance.shape[1]
        self.y = self._project(values)
        self.base = float(np.sum(self.w * self.y * self.y))
        self.offset = 0.0 if phase_offset is None else np.asarray(phase_offset, float)

    def _project(self, x: np.ndarray) -> np.ndarray:
        """Remove the nuisance terms' weighted least-squares fit along the last axis."""
        x = np.asarray(x, float)
        return x - ((x * self.w) @ self.nuisance) @ self.nuisance.T

    def solve(self, frequencies: np.ndarray, order: int) -> tuple[np.ndarray, np.ndarray]:
        """Coefficients ``[a_1..a_K, b_1..b_K]`` (n, 2K) and χ² (n,) at each frequency."""
        harmonics = np.arange(1, order + 1)[:, None]
        return self.solve_combinations(np.asarray(frequencies, float)[:, None], harmonics)

    def solve_combinations(
        self,
        frequencies: np.ndarray,
        combinations: np.ndarray,
        *,
        slowest: float = 0.0,
        modulation: int = 0,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Coefficients ``[a_1..a_P, b_1..b_P]`` (n, 2P) and χ² (n,) of the terms
        ``a_p cos(n_p·ψ) + b_p sin(n_p·ψ)``.

        Parameters
        ----------
        frequencies : (n, D) float
            Trial frequency tuples (Hz), one row per trial.
        combinations : (P, D) int
            Integer combination vectors ``n_p`` of the D phases (none all zero, no two of
            opposite sign).
        slowest : float
            Terms whose frequency ``|n_p·f|`` (Hz) is below this are left out (their
            coefficients are zero): slower than the curves' trend polynomials resolve, they
            would only duplicate them.
        modulation : int
            Degree d of a slow change of every coefficient within each curve: the terms are
            repeated times the Legendre polynomials ``P_1..P_d`` of the curve's scaled time
            (``2P(d + 1)`` coefficients).

        Returns
        -------
        coefficients : (n, 2P(d + 1)) float
        chi2 : (n,) float
        """
        f = np.asarray(frequencies, float)
        combinations = np.asarray(combinations, int)
        # e^{i n·ψ} as products of integer powers of e^{iψ_d}: one complex exponential per
        # phase and point, the powers by repeated multiplication (negative ones conjugate).
        z = np.ones((len(f), len(combinations), len(self.t)), complex)
        for d in range(f.shape[1]):
            # One exponential per distinct frequency (a scan row shares its first one).
            unique, inverse = np.unique(f[:, d], return_inverse=True)
            psi = 2 * np.pi * unique[:, None] * self.t[None, :] - (self.offset if d == 0 else 0.0)
            first = np.exp(1j * psi)[inverse]
            largest = int(np.max(np.abs(combinations[:, d])))
            powers = [np.ones_like(first), first]
            for _ in range(largest - 1):
                powers.append(powers[-1] * first)
            for p, n in enumerate(combinations[:, d]):
                if n:
                    z[:, p] *= powers[n] if n > 0 else np.conj(powers[-n])
        if slowest > 0:
            z *= (np.abs(f @ combinations.T) >= slowest)[..., None]
        x = np.concatenate([z.real, z.imag], axis=1)
        if modulation:
            legendre = np.polynomial.legendre.legvander(self.tau, modulation).T
            x = np.concatenate([x * row for row in legendre], axis=1)
        xw = x * self.w
        # The projected design's Gram matrix without forming it: X W Xᵀ − (X W Q)(X W Q)ᵀ;
        # the data are projected already, so X W y needs nothing.
        sums = xw @ self.nuisance
        gram = xw @ x.transpose(0, 2, 1) - sums @ sums.transpose(0, 2, 1)
        rhs = xw @ self.y
        size = x.shape[1]
        gram += 1e-12 * np.trace(gram, axis1=1, axis2=2)[:, None, None] * np.eye(size)
        solution = np.linalg.solve(gram, rhs[..., None])[..., 0]
        return solution, self.base - np.sum(solution * rhs, axis=1)


def _curve_time(t: np.ndarray, curve: np.ndarray) -> np.ndarray:
    """Each curve's time scaled to ``[−1, 1]`` (0 for a curve on one epoch)."""
    tau = np.zeros(len(t))
    for c in np.unique(curve):
        rows = curve == c
        span = np.ptp(t[rows])
        if span > 0:
            tau[rows] = 2 * (t[rows] - t[rows].min()) / span - 1
    return tau


def _orthonormal_nuisance(
    tau: np.ndarray, w: np.ndarray, curve: np.ndarray, degree: int
) -> np.ndarray:
    """Per-curve Legendre columns ``P_0..P_d`` of the curve's scaled time τ, made
    W-orthonormal (``QᵀWQ = 1``; :class:`FourierDesign`)."""
    if degree < 0:
        raise ValueError(f"the trend degree must be ≥ 0, got {degree}")
    columns = []
    for c in np.unique(curve):
        rows = curve == c
        block = np.zeros((len(tau), min(degree, len(np.unique(tau[rows])) - 1) + 1))
        block[rows] = np.polynomial.legendre.legvander(tau[rows], block.shape[1] - 1)
        columns.append(block)
    g = np.concatenate(columns, axis=1)
    normal = g.T @ (g * w[:, None])
    return g @ np.linalg.inv(np.linalg.cholesky(normal)).T
