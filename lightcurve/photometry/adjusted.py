"""A library shape with continuous adjustments: the measurement model of an imperfect candidate.

No real object is exactly its library model: its dimensions come from drawings, its paint and
blankets age, its mass sits in tanks and engines. :class:`AdjustableShape` renders a facet
model under a vector ``θ`` of unconstrained adjustments, any of

``"scale"``
    a magnitude offset ``Δm`` (mag): the albedo–area scale ``s``, ``Δm = −2.5 log10 s``;
``"stretch"``
    three principal-axis stretch factors ``s_i = exp(b tanh(u_i/b))``, bounded by
    ``e^{±b}`` (``b = ln 1.3``: dimensions known to 30 %; beyond that a stretched box
    turned by 90° mimics another box, a degenerate route the bound closes): the affine map
    ``D = P diag(s) Pᵀ`` (``P`` the shape's principal axes) applied to the vertices. A
    facet's normal becomes ``n' = D⁻¹n/|D⁻¹n|`` and its area ``A' = det D |D⁻¹n| A``
    (Nanson's formula); ``n'·L = n·D⁻¹L/|D⁻¹n|``. Affine maps carry rays to rays, so a point
    of the stretched body is lit along ``L`` where its preimage is lit along ``D⁻¹L``: the
    shadows of a non-convex shape are the library shape's (visibility table or ray casting)
    at the directions ``D⁻¹L``, ``D⁻¹V``. The second-moment tensor of the mass follows,
    ``Σ' ∝ D Σ D`` (uniform density), and with it the inertia ``J' = tr(Σ') I − Σ'``;
``"material"``
    every BRDF parameter of every material, ``p = p₀ exp(u)`` within the parameter's
    physical range (reflectances: prior 1σ 30 %; lobe exponents and widths: a factor 2);
    the two exponents of an isotropic lobe (``nu = nv``) share one ``u``;
``"inertia"``
    the tanh inertia parameters ``k`` of Feng et al. (always physical), replacing the
    ratios of the (stretched) mesh at uniform density;
``"tilt"``
    a rotation vector (rad) of the principal axes away from the mesh's: mass placed
    asymmetrically in tanks and engines.

At ``θ = 0`` (with ``k`` at the mesh's value) the model is the library shape. The flux is the
measurement model of :mod:`lightcurve.photometry.reference` (BRDF vector forms, facet by
facet), vectorised over epochs × facets; its value at ``θ = 0`` and on a stretched copy of the
mesh is tested against :class:`~lightcurve.photometry.render.Renderer`.
"""

from __future__ import annotations

import math
from collections.abc import Collection
from dataclasses import dataclass
from typing import Any

import numpy as np

import brdf
from brdf.registry import describe
from filters.attitude import (
    PrincipalInertia,
    inertia_from_tanh,
    ratios_from_tanh,
    rotation_vector_to_quaternion,
    tanh_from_inertia,
)
from filters.attitude import (
    attitude_matrix as _matrix,
)
from lightcurve.photometry.reference import facet_flux_sum
from shapes import FacetModel, joint_visible_fraction

__all__ = ["ADJUSTMENTS", "AdjustableShape", "Parameter"]

#: The adjustments an estimator may free, in the order of their parameters in ``θ``.
ADJUSTMENTS = ("inertia", "tilt", "scale", "stretch", "material")

#: Bound ``b`` of the logarithm of a stretch factor (30 %).
STRETCH_BOUND = math.log(1.3)
#: Prior 1σ of ``u = ln(p/p₀)`` of a reflectance-like parameter (30 %).
REFLECTANCE_SIGMA = math.log(1.3)
#: Prior 1σ of ``u`` of a lobe exponent or width (a factor 2).
EXPONENT_SIGMA = math.log(2.0)
#: Lobe exponents that one parameter adjusts together when the library's are equal (an
#: isotropic Ashikhmin–Shirley lobe, ``nu = nv``, stays isotropic).
_ISOTROPIC = {"nu": "nv", "nv": "nu"}


@dataclass(frozen=True)
class Parameter:
    """One entry of ``θ``.

    Attributes
    ----------
    name : str
        ``"k1"``, ``"k2"``, ``"tilt_x"`` … ``"tilt_z"``, ``"magnitude_offset"``,
        ``"stretch_1"`` … ``"stretch_3"`` (principal axes in ascending moment order) or
        ``"<material>.<parameter>"`` (``"<material>.nu=nv"`` for the one exponent of an
        isotropic lobe).
    kind : str
        Its adjustment (one of :data:`ADJUSTMENTS`).
    initial : float
        Value at the library model (unconstrained units).
    sigma : float
        Prior 1σ (unconstrained units).
    """

    name: str
    kind: str
    initial: float
    sigma: float


class AdjustableShape:
    """A facet model rendered under continuous adjustments ``θ`` (see the module docstring).

    Parameters
    ----------
    shape : FacetModel
        The library model (body frame, metres).
    estimate : collection of str
        The adjustments to free (a subset of :data:`ADJUSTMENTS`).
    inertia_sigma : float
        Prior 1σ of each tanh parameter ``k``.
    tilt_sigma_deg : float
        Prior 1σ of each component of the principal axes' tilt (deg).
    offset_sigma_mag : float
        Prior 1σ of the magnitude offset (mag).
    stretch_sigma : float
        Prior 1σ of each ``ln s_i``.

    Attributes
    ----------
    parameters : list of Parameter
    estimate : tuple of str
        The adjustments freed, in the order of :data:`ADJUSTMENTS`.
    shadows : {"none", "table", "exact"}
        How shadows are evaluated (the renderer's ``"auto"`` choice).
    """

    def __init__(
        self,
        shape: FacetModel,
        estimate: Collection[str],
        *,
        inertia_sigma: float = 0.5,
        tilt_sigma_deg: float = 5.0,
        offset_sigma_mag: float = 0.5,
        stretch_sigma: float = 0.1,
    ) -> None:
        unknown = sorted(set(estimate) - set(ADJUSTMENTS))
        if unknown:
            raise ValueError(
                f"unknown adjustment(s) {', '.join(unknown)}; choose from {', '.join(ADJUSTMENTS)}"
            )
        self.shape = shape
        self.estimate = tuple(a for a in ADJUSTMENTS if a in estimate)
        compiled = shape.compiled()
        self.compiled = compiled
        self.axes = np.asarray(shape.principal_axes, dtype=float)
        inertia = np.asarray(shape.inertia, dtype=float)
        self._second_moment = 0.5 * np.trace(inertia) * np.eye(3) - inertia
        if not compiled.can_be_shadowed.any():
            self.shadows = "none"
        else:
            self.shadows = "table" if compiled.visibility is not None else "exact"
        self._materials = [(m.brdf, dict(m.params)) for m in compiled.materials]
        params: list[Parameter] = []
        if "inertia" in self.estimate:
            k = tanh_from_inertia(np.asarray(shape.principal_moments, dtype=float), margin=1e-6)
            params += [
                Parameter(f"k{i + 1}", "inertia", float(k[i]), inertia_sigma) for i in (0, 1)
            ]
        if "tilt" in self.estimate:
            sigma = math.radians(tilt_sigma_deg)
            params += [Parameter(f"tilt_{a}", "tilt", 0.0, sigma) for a in "xyz"]
        if "scale" in self.estimate:
            params.append(Parameter("magnitude_offset", "scale", 0.0, offset_sigma_mag))
        if "stretch" in self.estimate:
            params += [Parameter(f"stretch_{i}", "stretch", 0.0, stretch_sigma) for i in (1, 2, 3)]
        self._material_slots: list[tuple[int, tuple[str, ...], float, float, float]] = []
        if "material" in self.estimate:
            for index, (kind, values) in enumerate(self._materials):
                label = compiled.materials[index].name or f"material{index}"
                specs = {spec.name: spec for spec in describe(kind).parameters}
                for spec in specs.values():
                    value = float(values.get(spec.name, spec.default))
                    if not (value > 0 and math.isfinite(value)):
                        continue  # a zero term stays zero: nothing to scale
                    names: tuple[str, ...] = (spec.name,)
                    pair = _ISOTROPIC.get(spec.name)
                    if pair is not None and pair in specs:
                        other = float(values.get(pair, specs[pair].default))
                        if other == value and spec.name < pair:
                            names = (spec.name, pair)  # an isotropic lobe stays isotropic
                        elif other == value:
                            continue
                    sigma = EXPONENT_SIGMA if spec.log_scale else REFLECTANCE_SIGMA
                    self._material_slots.append(
                        (index, names, value, float(spec.lower), float(spec.upper))
                    )
                    params.append(Parameter(f"{label}.{'='.join(names)}", "material", 0.0, sigma))
        self.parameters = params
        self._index = {p.name: i for i, p in enumerate(params)}

    # ------------------------------------------------------------------ the vector θ
    def __len__(self) -> int:
        return len(self.parameters)

    @property
    def names(self) -> list[str]:
        """Names of the entries of ``θ``."""
        return [p.name for p in self.parameters]

    @property
    def initial(self) -> np.ndarray:
        """``θ`` of the library model, shape (m,)."""
        return np.array([p.initial for p in self.parameters], dtype=float)

    @property
    def prior_sigma(self) -> np.ndarray:
        """Prior 1σ of ``θ``, shape (m,)."""
        return np.array([p.sigma for p in self.parameters], dtype=float)

    def _values(self, theta: np.ndarray, kind: str) -> np.ndarray:
        return np.asarray(
            [theta[..., i] for i, p in enumerate(self.parameters) if p.kind == kind]
        ).reshape(-1, *theta.shape[:-1])

    def stretch_matrix(self, theta: Any) -> np.ndarray:
        """Body-frame stretch ``D = P diag(s) Pᵀ`` of ``θ (m,)`` (identity without it)."""
        if "stretch" not in self.estimate:
            return np.eye(3)
        u = self._values(np.asarray(theta, float), "stretch").reshape(3)
        return (self.axes * self.stretch_factors(u)) @ self.axes.T

    @staticmethod
    def stretch_factors(u: Any) -> np.ndarray:
        """Bounded stretch factors ``exp(b tanh(u/b))`` of the unconstrained ``u``."""
        return np.exp(STRETCH_BOUND * np.tanh(np.asarray(u, dtype=float) / STRETCH_BOUND))

    # ------------------------------------------------------------------ dynamics
    def principal_inertia(self, theta: Any) -> PrincipalInertia:
        """Principal axes and inertia ratios of a batch ``θ (N, m)`` (torque-free dynamics).

        The mesh's uniform-density inertia, stretched with the shape (``"stretch"``), its
        ratios replaced by the tanh form (``"inertia"``), its axes tilted (``"tilt"``).
        """
        theta = np.atleast_2d(np.asarray(theta, dtype=float))
        n = len(theta)
        sigma = np.broadcast_to(self._second_moment, (n, 3, 3))
        if "stretch" in self.estimate:
            d = np.stack([self.stretch_matrix(t) for t in theta])
            sigma = d @ sigma @ d
        trace = np.trace(sigma, axis1=-2, axis2=-1)[:, None, None]
        principal = PrincipalInertia.from_inertia(trace * np.eye(3) - sigma)
        axes, ratios = principal.axes, principal.ratios
        if "inertia" in self.estimate:
            ratios = ratios_from_tanh(self._values(theta, "inertia").T.reshape(n, 2))
        if "tilt" in self.estimate:
            tilt = self._values(theta, "tilt").T.reshape(n, 3)
            axes = _matrix(rotation_vector_to_quaternion(tilt)).swapaxes(-1, -2) @ axes
        return PrincipalInertia.from_tanh(np.zeros((n, 2)), axes)._replace(ratios=ratios)

    # ------------------------------------------------------------------ photometry
    def materials(self, theta: Any) -> list[brdf.BRDF]:
        """The BRDF of every compiled material under ``θ (m,)``."""
        theta = np.asarray(theta, dtype=float)
        values = [dict(v) for _, v in self._materials]
        if self._material_slots:
            u = self._values(theta, "material").reshape(-1)
            for (index, names, value, lower, upper), step in zip(
                self._material_slots, u, strict=True
            ):
                span = np.nextafter(lower, np.inf), np.nextafter(upper, -np.inf)
                for name in names:
                    values[index][name] = float(np.clip(value * math.exp(step), *span))
            for v in values:  # energy conservation of the two-lobe models
                if "rd" in v and "rs" in v and v["rd"] + v["rs"] > 1.0:
                    total = v["rd"] + v["rs"]
                    v["rd"], v["rs"] = v["rd"] / total, v["rs"] / total
        return [brdf.get(kind, **v) for (kind, _), v in zip(self._materials, values, strict=True)]

    def flux(self, theta: Any, light: np.ndarray, view: np.ndarray) -> np.ndarray:
        """Flux ratio at unit distances of the shape adjusted by ``θ (m,)``.

        Parameters
        ----------
        theta : (m,) array
        light, view : (R, 3) float
            Body-frame unit vectors to the Sun and to the observer.

        Returns
        -------
        (R,) numpy.ndarray
            ``Σ ρ A' (n'·L)(n'·V) · shadow · 10^(−0.4 Δm)`` (multiply by ``(1 AU/r_sun)²/d²``
            for the flux ratio).
        """
        theta = np.asarray(theta, dtype=float)
        c = self.compiled
        normals, areas, tangents = c.normals, c.areas, c.tangents
        d = self.stretch_matrix(theta)
        d_inv = np.linalg.inv(d)
        if "stretch" in self.estimate:
            mapped = normals @ d_inv  # D symmetric: D⁻¹n as rows
            length = np.linalg.norm(mapped, axis=1)
            normals = mapped / length[:, None]
            areas = areas * np.linalg.det(d) * length
            tangents = tangents @ d
            tangents = tangents - np.sum(tangents * normals, axis=1, keepdims=True) * normals
            tangents = tangents / np.linalg.norm(tangents, axis=1, keepdims=True)
        shadow = None
        if self.shadows != "none":
            light_0, view_0 = light @ d_inv, view @ d_inv
            if self.shadows == "table":
                shadow = c.visibility.joint(light_0, view_0, facing=False)
            else:
                shadow = joint_visible_fraction(c, light_0, view_0)
        total = facet_flux_sum(
            normals,
            areas,
            tangents,
            c.material_index,
            self.materials(theta),
            light=light,
            view=view,
            shadow=shadow,
        )
        return total * self.scale_factor(theta)

    def scale_factor(self, theta: Any) -> float:
        """The albedo–area scale ``s = 10^(−0.4 Δm)`` of ``θ (m,)`` (1 without it)."""
        if "scale" not in self.estimate:
            return 1.0
        return float(
            10.0 ** (-0.4 * np.asarray(theta, dtype=float)[self._index["magnitude_offset"]])
        )

    # ------------------------------------------------------------------ reporting
    def physical(self, theta: Any) -> dict[str, float]:
        """The adjustments of ``θ (m,)`` in physical units.

        Returns
        -------
        dict
            ``magnitude_offset`` (mag); ``stretch_1..3`` (factors along the principal axes,
            ascending moments); ``"<material>.<parameter>"`` values; ``k1``, ``k2`` and the
            principal-moment ratios ``inertia_ratio_1`` = J₁/J₃, ``inertia_ratio_2`` = J₂/J₃;
            ``tilt_deg`` (angle of the principal axes from the mesh's) — each only when
            estimated.
        """
        theta = np.asarray(theta, dtype=float)
        out: dict[str, float] = {}
        for name in ("k1", "k2", "magnitude_offset"):
            if name in self._index:
                out[name] = float(theta[self._index[name]])
        if "inertia" in self.estimate:
            k = theta[[self._index["k1"], self._index["k2"]]]
            moments = np.diag(inertia_from_tanh(k))
            out["inertia_ratio_1"] = float(moments[0] / moments[2])
            out["inertia_ratio_2"] = float(moments[1] / moments[2])
        if "tilt" in self.estimate:
            tilt = self._values(theta, "tilt").reshape(3)
            out["tilt_deg"] = float(np.degrees(np.linalg.norm(tilt)))
        if "stretch" in self.estimate:
            factors = self.stretch_factors(self._values(theta, "stretch").reshape(3))
            for i, factor in enumerate(factors):
                out[f"stretch_{i + 1}"] = float(factor)
        if self._material_slots:
            models = self.materials(theta)
            for slot, p in zip(
                self._material_slots,
                (p for p in self.parameters if p.kind == "material"),
                strict=True,
            ):
                out[p.name] = float(models[slot[0]].params[slot[1][0]])
        return out

    def describe(self, theta: Any, covariance: Any) -> dict[str, dict[str, float]]:
        """Physical values of ``θ`` with their 1σ (first-order propagation of
        ``covariance (m, m)`` through :meth:`physical`).

        Returns
        -------
        dict
            name → ``{"value": …, "sigma": …}``.
        """
        theta = np.asarray(theta, dtype=float)
        covariance = np.asarray(covariance, dtype=float)
        base = self.physical(theta)
        steps = 1e-6 * np.maximum(1.0, np.abs(theta))
        gradient = np.zeros((len(base), len(theta)))
        for j, h in enumerate(steps):
            up, down = theta.copy(), theta.copy()
            up[j] += h
            down[j] -= h
            a, b = self.physical(up), self.physical(down)
            gradient[:, j] = [(a[n] - b[n]) / (2 * h) for n in base]
        variance = np.einsum("ij,jk,ik->i", gradient, covariance, gradient)
        return {
            name: {"value": value, "sigma": float(math.sqrt(max(v, 0.0)))}
            for (name, value), v in zip(base.items(), variance, strict=True)
        }
