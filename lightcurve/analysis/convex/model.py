"""The convex-inversion forward model with its Jacobian, batched in torch.

For a batch of parameter vectors (pole starts × trial periods …) the model brightness at
epoch j is (Kaasalainen & Torppa 2001, eq. 1; Kaasalainen, Torppa & Muinonen 2001, eqs. 3–4)

``L_j = f(α_j) Σ_i A_i S(μ0_ij, μ_ij)``,  ``S = μ μ0 (1/(μ + μ0) + c)``  (μ, μ0 > 0),

with ``μ0 = n_i · s_j``, ``μ = n_i · e_j`` (Sun and Earth directions in the body frame of
:mod:`lightcurve.analysis.spin`), ``A_i = ΔA_i exp(Σ c_k Y_k(n_i))`` on the fixed Gaussian sphere,
and the three-parameter phase function ``f(α) = a e^{−α/d} + k α + 1``. The scattering law
and the phase function are those of :mod:`brdf.lommel_seeliger` (``ρ μ μ0`` with
``w = 4π``). Relative light curves are compared as ``L_j/⟨L⟩_curve``; calibrated curves as
``e^s L_j`` with one fitted scale ``s``.

The Jacobian is exact and cheap: the areas enter linearly, so the shape columns are one
matrix product ``f · S (A ∘ Y)``; the spin columns use ``∂S/∂μ0``, ``∂S/∂μ`` (autograd of the
scattering kernel, elementwise) contracted with the facet normals,
``Σ_i A_i ∂S/∂μ0 n_i · ∂s_B/∂θ``; the phase-function and spin-direction derivatives are
per-epoch and come from forward-mode autograd. The convexity regularisation adds the three
components of ``w √N Σ A_i n_i / (σ̃ Σ A_i)`` (the "dark facet" closing the Gaussian image,
Kaasalainen & Torppa 2001, sec. 3.3; σ̃ the median data error) as extra residuals.
"""

from __future__ import annotations

import numpy as np
import torch
from torch.autograd import forward_ad

from brdf import phase_function
from brdf._geometry import COSINE_FLOOR
from filters.attitude import attitude_matrix, axis_angle_to_quaternion, cross_matrix, rotate
from lightcurve.analysis.convex.data import Photometry
from lightcurve.analysis.convex.layout import (
    CONVEXITY_WEIGHT,
    SECONDS_PER_DAY,
    ModelSetup,
    ParameterLayout,
)
from lightcurve.analysis.convex.sphere import GaussianSphere
from lightcurve.analysis.spin import pole_quaternion

__all__ = ["ConvexModel", "ParameterLayout"]

#: Facet × epoch elements per block of :meth:`ConvexModel._facet_sums` (≈ 1 MB in float64).
_BLOCK = 131_072


class ConvexModel(ModelSetup):
    """Batched model light curves and Jacobians for one data set and Gaussian sphere.

    Parameters
    ----------
    data, sphere, epoch_mjd, convexity_weight
        As :class:`lightcurve.analysis.convex.compiled.CompiledModel` (the convexity weight's
        default is DAMIT's, 0.1).
    dtype : torch.dtype
        float64 (default) or float32 for the facet × epoch arrays; the rotation phase is
        always computed in float64.
    device : str or torch.device, optional
        Default: CUDA when available.
    compile : bool
        Compile the facet × epoch kernel with ``torch.compile`` (inductor, dynamic shapes):
        about 5× faster per block on CPU, after about 10 s of compilation per variant
        (with and without partials, batch of one or more), so it pays off for period scans
        and long fits.
    """

    def __init__(
        self,
        data: Photometry,
        sphere: GaussianSphere,
        epoch_mjd: float,
        convexity_weight: float = CONVEXITY_WEIGHT,
        dtype: torch.dtype = torch.float64,
        *,
        device: str | torch.device | None = None,
        compile: bool = False,
    ) -> None:
        self._set_up(data, sphere, epoch_mjd, convexity_weight)
        self._block_sums = torch.compile(_block_sums, dynamic=True) if compile else _block_sums
        self.device = torch.device(
            device if device is not None else ("cuda" if torch.cuda.is_available() else "cpu")
        )
        self.dtype = dtype

        def tensor(a: np.ndarray, dt: torch.dtype = dtype) -> torch.Tensor:
            return torch.as_tensor(np.asarray(a), dtype=dt, device=self.device)

        self.seconds = tensor((data.mjd - self.epoch_mjd) * SECONDS_PER_DAY, torch.float64)
        self.sun = tensor(data.sun, torch.float64)
        self.earth = tensor(data.earth, torch.float64)
        self.z_axis = tensor([0.0, 0.0, 1.0], torch.float64)
        self._cross_z = cross_matrix(self.z_axis)
        self._cross_y = cross_matrix(tensor([0.0, 1.0, 0.0], torch.float64))
        self.cos_alpha = tensor(np.sum(data.sun * data.earth, axis=1))
        self.brightness = tensor(data.brightness)
        self.sigma = tensor(data.sigma)
        self.normals = tensor(sphere.normals)
        self.facet_areas = tensor(sphere.areas)
        self.basis = tensor(sphere.basis)
        curve = torch.as_tensor(data.curve, device=self.device)
        self.curve = curve
        counts = np.bincount(data.curve, minlength=data.n_curves)
        averaging = np.zeros((data.n_curves, len(data)))
        averaging[data.curve, np.arange(len(data))] = 1.0 / counts[data.curve]
        self.averaging = tensor(averaging)
        self.relative_rows = tensor(data.relative[data.curve].astype(float))

    # ------------------------------------------------------------------ pieces
    def areas(self, coefficients: torch.Tensor) -> torch.Tensor:
        """Facet areas ``ΔA_i exp(Σ c_k Y_k(n_i))``, shape (B, F)."""
        return self.facet_areas * torch.exp(coefficients.to(self.dtype) @ self.basis.T)

    def body_directions(
        self, spin: torch.Tensor, derivatives: bool = False
    ) -> tuple[torch.Tensor, ...]:
        """Unit Sun and Earth directions in the body frame, each (B, N, 3) float64.

        ``v_B = R_z(φ0 + ω t) · A_pole(λ, β) · v`` (:mod:`lightcurve.analysis.spin`). With
        ``derivatives`` also their derivatives with respect to ``[λ, β, ω, φ0]``, each
        (B, N, 3, 4): ``∂v_B/∂φ0 = (v_B,y, −v_B,x, 0)``, ``∂v_B/∂ω = t ∂v_B/∂φ0``, and the
        pole derivatives ``R_z(φ) ∂A_pole/∂(λ, β) v`` by forward-mode autograd of the (B, 3, 3)
        pole matrices.

        Parameters
        ----------
        spin : (B, 4) tensor
            ``[λ, β, ω, φ0]`` (rad, rad, rad/s, rad).
        """
        rate, phi0 = spin[:, 2], spin[:, 3]
        matrix = attitude_matrix(pole_quaternion(spin[:, 0], spin[:, 1]))  # (B, 3, 3)
        if derivatives:
            # A_pole = R_y(90° − β) R_z(λ) (passive): ∂A/∂λ = −A [ẑ]×, ∂A/∂β = [ŷ]× A.
            d_matrix = torch.stack(
                [-matrix @ self._cross_z, self._cross_y @ matrix], dim=-1
            )  # (B, 3, 3, 2)
        phi = phi0[:, None] + rate[:, None] * self.seconds
        q_phi = axis_angle_to_quaternion(self.z_axis, phi)  # (B, N, 4)
        out = []
        for vector in (self.sun, self.earth):
            body = rotate(q_phi, torch.einsum("bxy,ny->bnx", matrix, vector))
            out.append(body)
            if derivatives:
                turn = torch.stack([body[..., 1], -body[..., 0], torch.zeros_like(phi)], -1)
                d_pole = rotate(
                    q_phi[:, :, None, :], torch.einsum("bxyk,ny->bnkx", d_matrix, vector)
                )
                out.append(
                    torch.cat(
                        [
                            d_pole.transpose(2, 3),
                            (turn * self.seconds[:, None])[..., None],
                            turn[..., None],
                        ],
                        dim=-1,
                    )
                )
        return tuple(out)

    def scattering(
        self, mu0: torch.Tensor, mu: torch.Tensor, c: torch.Tensor, derivatives: bool = False
    ) -> tuple[torch.Tensor, ...]:
        """``S = μ μ0 (1/(μ + μ0) + c)`` on the lit and visible facets, and its partials.

        The law of :func:`brdf.lommel_seeliger_from_cosines` (``ρ μ μ0`` with ``w = 4π``,
        ``f ≡ 1``; ``test_scattering_matches_the_brdf_kernel`` checks the two agree), fused
        here with its closed-form partials ``∂S/∂μ0 = (μ/(μ + μ0))² + c μ``,
        ``∂S/∂μ = (μ0/(μ + μ0))² + c μ0`` and ``∂S/∂c = μ μ0`` because it runs on every
        facet × epoch of every Jacobian.

        Returns
        -------
        S, or with ``derivatives`` (S, ∂S/∂μ0, ∂S/∂μ, ∂S/∂c), each shaped like ``mu0``.
        """
        return _scattering(mu0, mu, c, derivatives)

    def phase(self, phase_params: torch.Tensor) -> torch.Tensor:
        """Phase function ``f(α_j)``, shape (B, N)."""
        a, d, k = (phase_params[:, i : i + 1].to(self.dtype) for i in range(3))
        return phase_function(self.cos_alpha, a, d, k)

    def convexity(self, areas: torch.Tensor) -> torch.Tensor:
        """``Σ A_i n_i / Σ A_i`` (the dark facet's area vector relative to the total), (B, 3)."""
        return (areas @ self.normals) / areas.sum(dim=1, keepdim=True)

    # ------------------------------------------------------------------ evaluation
    def _facet_sums(
        self,
        light: torch.Tensor,
        view: torch.Tensor,
        areas: torch.Tensor,
        c: torch.Tensor,
        derivatives: bool,
    ) -> list[torch.Tensor]:
        """Per-epoch sums over the facets, computed in cache-sized blocks of epochs.

        Returns ``Σ_i A_i S_ij`` (B, N) and, with ``derivatives``, the shape columns
        ``Σ_i S_ij A_i Y_ik`` (B, N, K), ``Σ_i A_i ∂S/∂μ0 n_i`` and ``Σ_i A_i ∂S/∂μ n_i``
        (B, N, 3) and ``Σ_i A_i ∂S/∂c`` (B, N). The facet × epoch arrays never exist whole:
        blocks of about ``_BLOCK`` elements stay in cache (twice as fast here as whole
        arrays).
        """
        batch, n_epochs = light.shape[:2]
        step = max(8, _BLOCK // (batch * len(self.normals)))
        weighted = (
            (areas[..., None] * self.basis, areas[..., None] * self.normals)  # (B, F, K/3)
            if derivatives
            else (None, None)
        )
        parts = []
        for start in range(0, n_epochs, step):
            block = slice(start, start + step)
            parts.append(
                self._block_sums(
                    light[:, block].to(self.dtype),
                    view[:, block].to(self.dtype),
                    self.normals,
                    areas,
                    *weighted,
                    c=c,
                    derivatives=derivatives,
                )
            )
        return [torch.cat(column, dim=1) for column in zip(*parts, strict=True)]

    def evaluate(
        self, params: torch.Tensor, jacobian: bool = True, lambert_free: bool = False
    ) -> tuple[torch.Tensor, torch.Tensor | None]:
        """Model brightness and its Jacobian: as
        :meth:`lightcurve.analysis.convex.compiled.CompiledModel.evaluate`, with (B, P) float64
        tensors in and tensors out."""
        lay = self.layout
        k = lay.n_coefficients
        spin = params[:, lay.spin]
        c = params[:, lay.lambert].to(self.dtype)[:, None, None]
        areas = self.areas(params[:, :k])
        f = self.phase(params[:, lay.phase])
        if not jacobian:
            light, view = self.body_directions(spin)
            (s_area,) = self._facet_sums(light, view, areas, c, False)
            return self._normalise(f * s_area, None, params)[0], None

        light, d_light, view, d_view = self.body_directions(spin, derivatives=True)
        s_area, d_shape, g_light, g_view, d_c = self._facet_sums(light, view, areas, c, True)
        brightness = f * s_area
        jac = torch.zeros((*brightness.shape, lay.size), dtype=self.dtype, device=self.device)
        jac[..., :k] = f[..., None] * d_shape
        jac[..., lay.spin] = f[..., None] * (
            torch.einsum("bnx,bnxp->bnp", g_light, d_light.to(self.dtype))
            + torch.einsum("bnx,bnxp->bnp", g_view, d_view.to(self.dtype))
        )
        _, d_phase = _value_and_jacfwd(self.phase, params[:, lay.phase])
        jac[..., lay.phase] = d_phase * s_area[..., None]
        if lambert_free:
            jac[..., lay.lambert] = f * d_c
        return self._normalise(brightness, jac, params)

    def _normalise(
        self, brightness: torch.Tensor, jac: torch.Tensor | None, params: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor | None]:
        """Relative curves → ``L/⟨L⟩``; calibrated curves → ``e^s L``."""
        mean = (brightness @ self.averaging.T)[:, self.curve]
        relative = self.relative_rows
        scale = torch.exp(params[:, self.layout.log_scale].to(self.dtype))[:, None]
        model = relative * brightness / mean + (1 - relative) * scale * brightness
        if jac is None:
            return model, None
        jac_mean = torch.einsum("ln,bnp->blp", self.averaging, jac)[:, self.curve]
        rel = relative[:, None]
        out = (
            rel * (jac / mean[..., None] - (brightness / mean**2)[..., None] * jac_mean)
            + (1 - rel) * scale[..., None] * jac
        )
        out[..., self.layout.log_scale] = (1 - relative) * model
        return model, out

    def residuals(
        self, params: torch.Tensor, jacobian: bool = True, lambert_free: bool = False
    ) -> tuple[torch.Tensor, torch.Tensor | None]:
        """Weighted residuals ``(y − model)/σ`` plus the 3 regularisation rows.

        Returns
        -------
        r : (B, N + 3) tensor
        jac : (B, N + 3, P) tensor or None
        """
        model, jac = self.evaluate(params, jacobian, lambert_free)
        data_r = (self.brightness - model) / self.sigma
        k = self.layout.n_coefficients
        coefficients = params[:, :k]

        areas = self.areas(coefficients)
        total = areas.sum(dim=1, keepdim=True)
        vector = areas @ self.normals  # Σ A_i n_i, (B, 3)
        reg = self.regularisation_scale * vector / total
        if jac is None:
            return torch.cat([data_r, reg], dim=1), None
        # ∂A_i/∂c_k = A_i Y_ik: the derivative of Σ A n / Σ A in closed form.
        weighted = areas[..., None] * self.basis  # (B, F, K)
        d_vector = torch.einsum("fx,bfk->bxk", self.normals, weighted)
        d_total = weighted.sum(dim=1)[:, None, :]
        d_reg = self.regularisation_scale * (
            d_vector / total[..., None] - vector[..., None] * d_total / total[..., None] ** 2
        )
        jac_reg = torch.zeros(
            (len(params), 3, self.layout.size), dtype=self.dtype, device=self.device
        )
        jac_reg[..., :k] = d_reg
        return torch.cat([data_r, reg], 1), torch.cat([-jac / self.sigma[:, None], jac_reg], 1)


def _value_and_jacfwd(func, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Value and forward-mode Jacobian of a row-wise function of ``x`` (B, P).

    ``func`` maps each row of ``x`` independently (any output shape (B, …)); one dual-number
    pass per parameter (``torch.autograd.forward_ad``) gives ∂out/∂x[:, p], stacked last.
    """
    columns = []
    value = None
    with forward_ad.dual_level():
        for p in range(x.shape[1]):
            tangent = torch.zeros_like(x)
            tangent[:, p] = 1.0
            primal, derivative = forward_ad.unpack_dual(func(forward_ad.make_dual(x, tangent)))
            value = primal if value is None else value
            columns.append(derivative)
    return value, torch.stack(columns, dim=-1)


def _scattering(
    mu0: torch.Tensor, mu: torch.Tensor, c: torch.Tensor, derivatives: bool
) -> tuple[torch.Tensor, ...]:
    """Kernel of :meth:`ConvexModel.scattering`."""
    # Clamped cosines: S = 0 wherever either is ≤ 0 through the product; the partials are
    # masked by the other factor's sign (S ≡ 0 there).
    lit, seen = mu0 > 0, mu > 0
    mu0, mu = mu0.clamp_min(0.0), mu.clamp_min(0.0)
    inverse = (mu0 + mu).clamp_min_(COSINE_FLOOR).reciprocal_()
    product = mu0 * mu
    scatter = product * (inverse + c)
    if not derivatives:
        return (scatter,)
    d_mu0 = ((mu * inverse).square_() + c * mu) * lit
    d_mu = ((mu0 * inverse).square_() + c * mu0) * seen
    return scatter, d_mu0, d_mu, product


def _block_sums(
    light: torch.Tensor,
    view: torch.Tensor,
    normals: torch.Tensor,
    areas: torch.Tensor,
    weighted_basis: torch.Tensor | None,
    weighted_normals: torch.Tensor | None,
    *,
    c: torch.Tensor,
    derivatives: bool,
) -> list[torch.Tensor]:
    """The facet sums of :meth:`ConvexModel._facet_sums` for one block of epochs."""
    terms = _scattering(light @ normals.T, view @ normals.T, c, derivatives)
    sums = [(terms[0] @ areas[..., None])[..., 0]]
    if derivatives:
        sums += [
            terms[0] @ weighted_basis,
            terms[1] @ weighted_normals,
            terms[2] @ weighted_normals,
            (terms[3] @ areas[..., None])[..., 0],
        ]
    return sums
