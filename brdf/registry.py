"""Registry of the reflectance models: names, parameters, valid ranges and the `BRDF` object.

``brdf.get("cook-torrance", rd=0.2, rs=0.6, m=0.3, f0=0.9)`` validates the parameters against
the ranges of `describe` and returns a small frozen `BRDF` that evaluates the model on direction
vectors or on cosines. Parameters may be scalars, numpy arrays or torch tensors that broadcast
against the leading dimensions of the geometry (e.g. one value per facet).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from array_api_compat import is_torch_array

from brdf.ashikhmin_shirley import ashikhmin_shirley, ashikhmin_shirley_from_cosines
from brdf.cook_torrance import cook_torrance, cook_torrance_from_cosines
from brdf.lambert import lambert, lambert_from_cosines
from brdf.lommel_seeliger import lommel_seeliger, lommel_seeliger_from_cosines
from brdf.phong import phong, phong_from_cosines
from brdf.two_lobe import two_lobe, two_lobe_from_cosines

__all__ = [
    "BRDF",
    "BRDFParameterError",
    "ModelInfo",
    "ParameterSpec",
    "available",
    "describe",
    "get",
]


class BRDFParameterError(ValueError):
    """An unknown model, an unknown parameter, or a parameter outside its valid range."""


@dataclass(frozen=True)
class ParameterSpec:
    """One model parameter: meaning, unit, default and valid range.

    Attributes
    ----------
    name : str
        Parameter name (part of the interface, ``docs/brdf.md``).
    meaning : str
        One line for humans.
    default : float
        Value taken by `get` when the parameter is not given.
    lower, upper : float
        Valid range (``±inf`` for none); ``lower_open``/``upper_open`` exclude the end.
    lower_open, upper_open : bool
    fit_range : (float, float)
        Finite search bounds used by `brdf.fit` unless the caller gives others.
    log_scale : bool
        Whether `brdf.fit` searches the logarithm of the parameter (exponents, widths).
    unit : str
    """

    name: str
    meaning: str
    default: float
    lower: float
    upper: float
    fit_range: tuple[float, float]
    lower_open: bool = False
    upper_open: bool = False
    log_scale: bool = False
    unit: str = "1"

    @property
    def range_text(self) -> str:
        """The valid range as text, e.g. ``0 ≤ rd ≤ 1`` or ``m > 0``."""
        parts = []
        if math.isfinite(self.lower):
            parts.append(f"{self.lower:g} {'<' if self.lower_open else '≤'} ")
        parts.append(self.name)
        if math.isfinite(self.upper):
            parts.append(f" {'<' if self.upper_open else '≤'} {self.upper:g}")
        text = "".join(parts)
        return text if text != self.name else f"{self.name} any real number"

    def contains(self, values: np.ndarray) -> np.ndarray:
        """Elementwise test of the valid range (NaN is outside)."""
        above = values > self.lower if self.lower_open else values >= self.lower
        below = values < self.upper if self.upper_open else values <= self.upper
        return above & below


@dataclass(frozen=True)
class ModelInfo:
    """Description of one reflectance model (returned by `describe`).

    Attributes
    ----------
    name : str
        Registry name.
    formula : str
        The BRDF in one line.
    parameters : tuple of ParameterSpec
    constraints : tuple of str
        Joint conditions beyond the per-parameter ranges.
    reference : str
    weights : tuple of str
        Parameters whose sum must not exceed 1 (the model then conserves energy); empty
        when the ranges alone suffice.
    """

    name: str
    formula: str
    parameters: tuple[ParameterSpec, ...]
    constraints: tuple[str, ...]
    reference: str
    vector: Callable[..., Any] = field(repr=False)
    cosine: Callable[..., Any] = field(repr=False)
    weights: tuple[str, ...] = ()

    @property
    def parameter_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parameters)

    def parameter(self, name: str) -> ParameterSpec:
        """The spec of parameter ``name``."""
        for spec in self.parameters:
            if spec.name == name:
                return spec
        raise BRDFParameterError(
            f"{self.name}: unknown parameter {name!r}; its parameters are "
            f"{', '.join(self.parameter_names)}"
        )

    def __str__(self) -> str:
        lines = [f"{self.name}: {self.formula}", f"  reference: {self.reference}"]
        lines += [
            f"  {p.name:>3} = {p.default:<6g} {p.range_text:<16} [{p.unit}] {p.meaning}"
            for p in self.parameters
        ]
        lines += [f"  constraint: {c}" for c in self.constraints]
        return "\n".join(lines)


def _fraction(name: str, meaning: str, default: float) -> ParameterSpec:
    """A parameter in [0, 1] (albedo, weight, reflectance), searched over all of it."""
    return ParameterSpec(name, meaning, default, 0.0, 1.0, (0.0, 1.0))


def _log_scaled(
    name: str,
    meaning: str,
    default: float,
    fit_range: tuple[float, float],
    *,
    lower_open: bool = False,
    unit: str = "1",
) -> ParameterSpec:
    """A non-negative parameter (exponent, width, slope) searched on a logarithmic scale."""
    return ParameterSpec(
        name,
        meaning,
        default,
        0.0,
        math.inf,
        fit_range,
        lower_open=lower_open,
        log_scale=True,
        unit=unit,
    )


_ALBEDO = "albedo in [0, 1]"
_MODELS: dict[str, ModelInfo] = {
    info.name: info
    for info in (
        ModelInfo(
            name="lambert",
            formula="ρ = rd/π",
            parameters=(_fraction("rd", f"diffuse {_ALBEDO}", 0.5),),
            constraints=(),
            reference="Lambert (1760)",
            vector=lambert,
            cosine=lambert_from_cosines,
        ),
        ModelInfo(
            name="phong",
            formula="ρ = rd/π + rs (n + 2)/(2π) max(0, R·V)^n, R = 2 (n·L) n − L",
            parameters=(
                _fraction("rd", f"diffuse {_ALBEDO}", 0.5),
                _fraction("rs", "specular albedo at normal incidence", 0.3),
                _log_scaled("n", "specular exponent", 10.0, (0.1, 1e7)),
            ),
            constraints=("rd + rs ≤ 1",),
            reference="Phong (1975), energy-normalised (Lewis 1994)",
            vector=phong,
            cosine=phong_from_cosines,
            weights=("rd", "rs"),
        ),
        ModelInfo(
            name="cook-torrance",
            formula="ρ = rd/π + rs D G F/(4 NL NV), Beckmann D, V-cavity G, Schlick F",
            parameters=(
                _fraction("rd", "diffuse weight", 0.3),
                _fraction("rs", "specular weight", 0.5),
                _log_scaled("m", "Beckmann RMS facet slope", 0.3, (1e-4, 3.0), lower_open=True),
                _fraction("f0", "Fresnel reflectance at normal incidence", 0.9),
            ),
            constraints=("rd + rs ≤ 1",),
            reference="Cook & Torrance (1981)",
            vector=cook_torrance,
            cosine=cook_torrance_from_cosines,
            weights=("rd", "rs"),
        ),
        ModelInfo(
            name="ashikhmin-shirley",
            formula=(
                "ρ = 28 rd/(23π)(1 − rs)(1 − (1 − NL/2)⁵)(1 − (1 − NV/2)⁵) + √((nu+1)(nv+1))/(8π)"
                " NH^((nu hu² + nv hv²)/(1 − NH²)) F/(VH max(NL, NV))"
            ),
            parameters=(
                _fraction("rd", f"diffuse {_ALBEDO}", 0.3),
                _fraction("rs", "specular reflectance at normal incidence", 0.3),
                _log_scaled("nu", "exponent along the tangent u", 100.0, (0.1, 1e7)),
                _log_scaled("nv", "exponent along v = n × u", 100.0, (0.1, 1e7)),
            ),
            constraints=("nu ≠ nv needs a tangent frame (tangent= or hu=, hv=)",),
            reference="Ashikhmin & Shirley (2000); Wetterer et al. (2014)",
            vector=ashikhmin_shirley,
            cosine=ashikhmin_shirley_from_cosines,
        ),
        ModelInfo(
            name="lommel-seeliger",
            formula="ρ = w/(4π) (a exp(−α/d) + k α + 1) (1/(NL + NV) + c), cos α = L·V",
            parameters=(
                _log_scaled("w", "single-scattering albedo", 1.0, (1e-4, 1e3)),
                ParameterSpec("c", "weight of the Lambert term", 0.1, 0.0, math.inf, (0.0, 10.0)),
                ParameterSpec("a", "opposition-effect amplitude", 0.5, 0.0, math.inf, (0.0, 10.0)),
                _log_scaled(
                    "d", "opposition-effect width", 0.1, (1e-3, 10.0), lower_open=True, unit="rad"
                ),
                ParameterSpec(
                    "k",
                    "phase-function slope",
                    -0.5,
                    -math.inf,
                    math.inf,
                    (-5.0, 5.0),
                    unit="rad⁻¹",
                ),
            ),
            constraints=(),
            reference="Kaasalainen & Torppa (2001), DAMIT convexinv; Hapke (2012) eq. 9.5",
            vector=lommel_seeliger,
            cosine=lommel_seeliger_from_cosines,
        ),
        ModelInfo(
            name="two-lobe",
            formula=(
                "ρ = rd/π + G/(4 NL NV) (rb F(fb) D_TR(ab) + rn F(fn) D_B(mn)), GGX broad and "
                "Beckmann narrow lobes, Schlick F per lobe, V-cavity G"
            ),
            parameters=(
                _fraction("rd", "diffuse weight", 0.05),
                _fraction("rb", "broad-lobe weight", 0.2),
                _log_scaled(
                    "ab",
                    "broad-lobe Trowbridge–Reitz (GGX) roughness",
                    0.1,
                    (1e-3, 3.0),
                    lower_open=True,
                ),
                _fraction("fb", "broad-lobe Fresnel reflectance at normal incidence", 1.0),
                _fraction("rn", "narrow-lobe weight", 0.5),
                _log_scaled(
                    "mn",
                    "narrow-lobe Beckmann RMS facet slope",
                    0.002,
                    (1e-5, 0.1),
                    lower_open=True,
                ),
                _fraction("fn", "narrow-lobe Fresnel reflectance at normal incidence", 0.04),
            ),
            constraints=("rd + rb + rn ≤ 1",),
            reference=(
                "Cook & Torrance (1981); Trowbridge & Reitz (1975), Walter et al. (2007); "
                "Schlick (1994); Heitz (2014)"
            ),
            vector=two_lobe,
            cosine=two_lobe_from_cosines,
            weights=("rd", "rb", "rn"),
        ),
    )
}


def _canonical_name(name: str) -> str:
    key = str(name).strip().lower().replace("_", "-")
    if key not in _MODELS:
        raise BRDFParameterError(f"unknown BRDF model {name!r}; known models: {', '.join(_MODELS)}")
    return key


def available() -> tuple[str, ...]:
    """Registry names of the reflectance models."""
    return tuple(_MODELS)


def describe(name: str) -> ModelInfo:
    """Parameters (names, defaults, valid ranges, meaning) and formula of model ``name``.

    ``print(brdf.describe("phong"))`` shows a table. ``"_"`` is accepted for ``"-"``.
    """
    return _MODELS[_canonical_name(name)]


def _as_numpy(value: Any) -> np.ndarray:
    if is_torch_array(value):
        return value.detach().cpu().numpy().astype(np.float64)
    try:
        return np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise BRDFParameterError(f"parameter value {value!r} is not a number") from error


def _check(info: ModelInfo, params: Mapping[str, Any]) -> None:
    for spec in info.parameters:
        values = _as_numpy(params[spec.name])
        inside = spec.contains(values)
        if not np.all(inside):
            bad = values[~inside] if values.ndim else values
            where = "" if values.ndim == 0 else f" (at index {np.argwhere(~inside)[0].tolist()})"
            raise BRDFParameterError(
                f"{info.name}: parameter {spec.name!r} = {np.ravel(bad)[0]:g}{where} is outside "
                f"its valid range {spec.range_text} ({spec.meaning})"
            )
    if info.weights:
        total = sum(_as_numpy(params[name]) for name in info.weights)
        if np.any(total > 1.0 + 1e-12):
            names = " + ".join(info.weights)
            raise BRDFParameterError(
                f"{info.name}: {names} = {np.max(total):g} exceeds 1; the model conserves "
                f"energy only for {names} ≤ 1"
            )


@dataclass(frozen=True, eq=False)
class BRDF:
    """A reflectance model with validated parameters (create it with `brdf.get`).

    Attributes
    ----------
    name : str
        Registry name.
    params : dict
        Parameter name → value (float, numpy array or torch tensor, broadcastable).
    anisotropic : bool
        True for Ashikhmin–Shirley with ``nu ≠ nv`` (needs the facet tangent frame).
    """

    name: str
    params: dict[str, Any]
    anisotropic: bool = False

    @property
    def info(self) -> ModelInfo:
        """The model description (`describe`)."""
        return _MODELS[self.name]

    def __call__(self, normal: Any, light: Any, view: Any, tangent: Any = None) -> Any:
        """ρ (sr⁻¹) for unit ``(..., 3)`` normals and directions to the Sun and observer.

        ``tangent`` (material reference direction) is used by anisotropic models only.
        """
        if not self.anisotropic:
            return self.info.vector(normal, light, view, **self.params)
        if tangent is None:
            raise ValueError(
                f"{self.name} with nu ≠ nv is anisotropic: pass the facet tangent direction"
            )
        return self.info.vector(normal, light, view, **self.params, tangent=tangent)

    def from_cosines(self, nl: Any, nv: Any, lv: Any, hu: Any = None, hv: Any = None) -> Any:
        """ρ (sr⁻¹) from ``nl = n·L``, ``nv = n·V`` (…, F) and ``lv = L·V`` (broadcastable).

        ``hu = H·u`` and ``hv = H·v`` are needed by anisotropic models only.
        """
        if not self.anisotropic:
            return self.info.cosine(nl, nv, lv, **self.params)
        if hu is None or hv is None:
            raise ValueError(f"{self.name} with nu ≠ nv is anisotropic: pass hu and hv")
        return self.info.cosine(nl, nv, lv, **self.params, hu=hu, hv=hv)


def get(name: str, **params: Any) -> BRDF:
    """Validated reflectance model ``name`` with the given parameters.

    Parameters
    ----------
    name : str
        One of `available()` (``"_"`` accepted for ``"-"``).
    **params : float, array or tensor
        Model parameters (see `describe`); missing ones take their defaults.

    Returns
    -------
    BRDF

    Raises
    ------
    BRDFParameterError
        Unknown model or parameter name, a value outside its range, or ``rd + rs > 1`` for
        Phong and Cook–Torrance; the message names the parameter and its range.
    """
    info = describe(name)
    unknown = sorted(set(params) - set(info.parameter_names))
    if unknown:
        raise BRDFParameterError(
            f"{info.name}: unknown parameter(s) {', '.join(unknown)}; its parameters are "
            f"{', '.join(info.parameter_names)}"
        )
    values = {
        spec.name: float(params[spec.name])
        if isinstance(params.get(spec.name), int | float)
        else params.get(spec.name, spec.default)
        for spec in info.parameters
    }
    _check(info, values)
    anisotropic = info.name == "ashikhmin-shirley" and bool(
        np.any(_as_numpy(values["nu"]) != _as_numpy(values["nv"]))
    )
    return BRDF(info.name, values, anisotropic)
