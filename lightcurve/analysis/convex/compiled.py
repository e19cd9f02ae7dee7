"""The convex-inversion model and its exact Jacobian on the CPU: numpy + compiled kernels.

The same model as :class:`lightcurve.analysis.convex.model.ConvexModel` (its equations and parameter
layout; ``test_compiled_model_matches_the_torch_model`` checks the two agree): for a batch of
parameter vectors the brightness at epoch j is (Kaasalainen & Torppa 2001, eq. 1;
Kaasalainen, Torppa & Muinonen 2001, eqs. 3–4)

``L_j = f(α_j) Σ_i A_i S(μ0_ij, μ_ij)``,  ``S = μ μ0 (1/(μ + μ0) + c)``,
``f(α) = max(0, a e^{−α/d} + k α + 1)``,  ``A_i = ΔA_i exp(Σ_k c_k Y_k(n_i))``,

relative curves compared as ``L/⟨L⟩_curve`` and calibrated ones as ``e^s L``, plus the three
convexity residuals ``w √N Σ A_i n_i / (σ̃ Σ A_i)``. The facet × epoch sums run in the
kernels of :mod:`lightcurve.analysis.convex.kernels` (one fused pass per epoch, facets in shadow or
out of view skipped); everything per epoch (body-frame directions from the pole matrix of
:func:`lightcurve.analysis.spin.pole_matrix` and the rotation angle, the phase function, the chain
rule into the parameters, the per-curve normalisation) is numpy on (B, N) arrays.
"""

from __future__ import annotations

import numpy as np

from lightcurve.analysis.convex import kernels
from lightcurve.analysis.convex.data import Photometry
from lightcurve.analysis.convex.layout import CONVEXITY_WEIGHT, SECONDS_PER_DAY, ModelSetup
from lightcurve.analysis.convex.sphere import GaussianSphere
from lightcurve.analysis.spin import pole_matrix

__all__ = ["CompiledModel"]


class CompiledModel(ModelSetup):
    """Batched model light curves and Jacobians (numpy arrays) for one data set and sphere.

    Parameters
    ----------
    data : Photometry
    sphere : GaussianSphere
    epoch_mjd : float
        Reference epoch t0 of the rotation angle.
    convexity_weight : float
        Weight ``w`` of the convexity regularisation.
    dtype : numpy dtype
        Precision of the facet × epoch sums (float64 or float32); everything per epoch
        (rotation phase, chain rule, normalisation) is float64.
    """

    def __init__(
        self,
        data: Photometry,
        sphere: GaussianSphere,
        epoch_mjd: float,
        convexity_weight: float = CONVEXITY_WEIGHT,
        dtype: np.dtype | type = np.float64,
    ) -> None:
        self._set_up(data, sphere, epoch_mjd, convexity_weight)
        self.dtype = np.dtype(dtype)
        if self.dtype not in (np.float32, np.float64):
            raise ValueError(f"dtype must be float32 or float64, got {self.dtype}")
        self.seconds = np.ascontiguousarray((data.mjd - self.epoch_mjd) * SECONDS_PER_DAY)
        self.sun = np.ascontiguousarray(data.sun, float)
        self.earth = np.ascontiguousarray(data.earth, float)
        self.alpha = np.ascontiguousarray(data.phase_angle)
        self.brightness = np.asarray(data.brightness, float)
        self.sigma = np.asarray(data.sigma, float)
        self.normals = sphere.normals
        self.normal_rows = np.ascontiguousarray(sphere.normals.T, self.dtype)
        self.facet_areas = sphere.areas
        self.basis = sphere.basis
        self.curve = np.ascontiguousarray(data.curve, dtype=np.int64)
        counts = np.bincount(data.curve, minlength=data.n_curves)
        if not counts.all():
            raise ValueError(f"light curve(s) {np.flatnonzero(counts == 0).tolist()} have no point")
        self._order = np.argsort(data.curve, kind="stable")
        self._starts = np.r_[0, np.cumsum(counts)[:-1]]
        self._per_curve = 1.0 / counts
        self.relative_rows = np.ascontiguousarray(data.relative[data.curve])
        self._buffers: dict[str, np.ndarray] = {}

    # ------------------------------------------------------------------ pieces
    def areas(self, coefficients: np.ndarray) -> np.ndarray:
        """Facet areas ``ΔA_i exp(Σ c_k Y_k(n_i))``, shape (B, F)."""
        return self.facet_areas * np.exp(coefficients @ self.basis.T)

    def convexity(self, areas: np.ndarray) -> np.ndarray:
        """``Σ A_i n_i / Σ A_i`` (the dark facet's area vector relative to the total), (B, 3)."""
        return (areas @ self.normals) / areas.sum(axis=1, keepdims=True)

    def _kernel_inputs(self, params: np.ndarray):
        lay = self.layout
        lam, beta = params[:, lay.index("lambda")], params[:, lay.index("beta")]
        poles = np.stack(pole_matrix(lam, beta, derivatives=True), axis=1)  # (B, 3, 3, 3)
        order = [lay.index(name) for name in ("phi0", "rate", "a", "d", "k", "c")]
        scalars = np.ascontiguousarray(params[:, order])
        areas = self.areas(params[:, : lay.n_coefficients])
        return areas, poles, scalars

    def _brightness(self, params: np.ndarray) -> np.ndarray:
        areas, poles, scalars = self._kernel_inputs(params)
        out = np.empty((len(params), len(self.seconds)))
        kernels.brightness(*self._geometry(areas), poles, scalars, out)
        return out

    def _geometry(self, areas: np.ndarray) -> tuple[np.ndarray, ...]:
        """The kernels' first arguments: epochs, directions, phase angles, facets."""
        return (
            self.seconds,
            self.sun,
            self.earth,
            self.alpha,
            self.normal_rows,
            areas.astype(self.dtype),
        )

    def _normalise(self, brightness: np.ndarray, params: np.ndarray) -> np.ndarray:
        """Relative curves → ``L/⟨L⟩``; calibrated curves → ``e^s L``."""
        totals = np.add.reduceat(brightness[:, self._order], self._starts, axis=1)
        mean = (totals * self._per_curve)[:, self.curve]
        scale = np.exp(params[:, self.layout.log_scale])[:, None]
        return np.where(self.relative_rows, brightness / mean, scale * brightness)

    # ------------------------------------------------------------------ evaluation
    def evaluate(
        self, params: np.ndarray, jacobian: bool = True, lambert_free: bool = False
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Model brightness (comparable to ``data.brightness``) and its Jacobian.

        Parameters
        ----------
        params : (B, P) float array
            Parameter vectors (:class:`~lightcurve.analysis.convex.layout.ParameterLayout`).
        jacobian : bool
            Also return ∂model/∂params.
        lambert_free : bool
            Compute the Lambert-weight column (otherwise it is zero).

        Returns
        -------
        model : (B, N) numpy.ndarray
        jac : (B, N, P) numpy.ndarray or None
        """
        params = np.asarray(params, float)
        if not jacobian:
            return self._normalise(self._brightness(params), params), None
        r, jac = self.residuals(params, True, lambert_free)
        n = len(self.seconds)
        return self.brightness - self.sigma * r[:, :n], -self.sigma[:, None] * jac[:, :n]

    def residuals(
        self,
        params: np.ndarray,
        jacobian: bool = True,
        lambert_free: bool = False,
        columns: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """Weighted residuals ``(y − model)/σ`` plus the 3 regularisation rows.

        Parameters
        ----------
        params : (B, P) float array
        jacobian : bool
        lambert_free : bool
            Compute the Lambert-weight column (otherwise it is zero).
        columns : (Q,) int array, optional
            Parameters whose Jacobian columns to return (default all P, in order).

        Returns
        -------
        r : (B, N + 3) numpy.ndarray
        jac : (B, N + 3, Q) numpy.ndarray or None
        """
        params = np.asarray(params, float)
        lay = self.layout
        k = lay.n_coefficients
        batch, n = len(params), len(self.seconds)
        r = np.empty((batch, n + 3))
        areas = self.areas(params[:, :k])
        total = areas.sum(axis=1, keepdims=True)
        vector = areas @ self.normals  # Σ A_i n_i, (B, 3)
        r[:, n:] = self.regularisation_scale * vector / total
        if not jacobian:
            r[:, :n] = (self.brightness - self._normalise(self._brightness(params), params)) / (
                self.sigma
            )
            return r, None
        index = np.arange(lay.size) if columns is None else np.asarray(columns, dtype=np.int64)
        areas, poles, scalars = self._kernel_inputs(params)
        brightness = self._scratch("brightness", (batch, n), np.float64)
        scatter = self._scratch("scatter", (batch, n, len(self.facet_areas)), self.dtype)
        partials = self._scratch("partials", (batch, n, kernels.SPIN_PHASE_COLUMNS), np.float64)
        kernels.brightness_and_jacobian(
            *self._geometry(areas), poles, scalars, brightness, scatter, partials
        )
        if not lambert_free:
            partials[..., -1] = 0.0
        weighted = areas[..., None] * self.basis  # ∂A_i/∂c_k = A_i Y_ik, (B, F, K)
        shape = self._scratch("shape", (batch, n, k), self.dtype)
        np.matmul(scatter, weighted.astype(self.dtype), out=shape)
        jac = np.empty((batch, n + 3, len(index)))
        kernels.normalise(
            brightness,
            shape,
            partials,
            self.curve,
            self.data.n_curves,
            self.relative_rows,
            params[:, lay.log_scale],
            self.brightness,
            self.sigma,
            index,
            r,
            jac,
        )
        # The derivative of Σ A n / Σ A in closed form.
        d_vector = np.einsum("fx,bfk->bxk", self.normals, weighted)
        d_total = weighted.sum(axis=1)[:, None, :]
        d_reg = np.zeros((batch, 3, lay.size))
        d_reg[..., :k] = self.regularisation_scale * (
            d_vector / total[..., None] - vector[..., None] * d_total / total[..., None] ** 2
        )
        jac[:, n:] = d_reg[..., index]
        return r, jac

    def _scratch(self, name: str, shape: tuple[int, ...], dtype) -> np.ndarray:
        """A work array kept between calls (fresh large arrays cost page faults)."""
        array = self._buffers.get(name)
        if array is None or array.shape != shape or array.dtype != dtype:
            array = self._buffers[name] = np.empty(shape, dtype)
        return array
