"""Surface materials of facet groups, stored as plain BRDF specifications.

A :class:`Material` names a reflectance model of the ``brdf`` package by its registry name and
carries that model's parameters; ``shapes`` does not import ``brdf`` (the renderer in
``lightcurve`` turns a material into a BRDF). The parameter names are the interface of
``docs/brdf.md`` ("The models"):

=====================  =============================  =======================
model                  required parameters            optional parameters
=====================  =============================  =======================
``lambert``            ``rd``
``phong``              ``rd``, ``rs``, ``n``
``cook-torrance``      ``rd``, ``rs``, ``m``, ``f0``
``ashikhmin-shirley``  ``rd``, ``rs``, ``nu``, ``nv``
``lommel-seeliger``    ``c``                          ``w``, ``a``, ``d``, ``k``
``two-lobe``           ``rd``, ``rb``, ``ab``, ``fb``,
                       ``rn``, ``mn``, ``fn``
=====================  =============================  =======================

The presets below are the defaults of the primitives (:mod:`shapes.primitives`); they are
representative values, not measurements.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from shapes.errors import ShapeError

__all__ = [
    "ALUMINIUM",
    "ARRAY_BACK",
    "BLACK_PAINT",
    "BRDF_PARAMETERS",
    "MLI",
    "REGOLITH",
    "SOLAR_CELL",
    "STARLINK_CHASSIS",
    "STARLINK_SOLAR_ARRAY",
    "WHITE_PAINT",
    "Material",
]

#: Required and optional parameter names of each BRDF registry name.
BRDF_PARAMETERS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "lambert": (("rd",), ()),
    "phong": (("rd", "rs", "n"), ()),
    "cook-torrance": (("rd", "rs", "m", "f0"), ()),
    "ashikhmin-shirley": (("rd", "rs", "nu", "nv"), ()),
    "lommel-seeliger": (("c",), ("w", "a", "d", "k")),
    "two-lobe": (("rd", "rb", "ab", "fb", "rn", "mn", "fn"), ()),
}


@dataclass(frozen=True, eq=True)
class Material:
    """A surface material: a BRDF registry name and its parameters.

    Parameters
    ----------
    brdf : str
        Registry name of the reflectance model (see the module table).
    params : dict[str, float]
        The model's parameters (dimensionless; ``n``, ``nu``, ``nv`` are lobe exponents).
    name : str, optional
        A human-readable name ("MLI", "solar cell").
    reference_direction : (3,) float, optional
        Body-frame direction whose projection on each facet defines the anisotropic tangent
        ``u`` (Ashikhmin–Shirley ``nu`` axis). Stored as a unit vector.

    Raises
    ------
    ShapeError
        Unknown model, missing or unknown parameter, non-finite value, or a zero / non-finite
        reference direction.
    """

    brdf: str
    params: dict[str, float]
    name: str | None = None
    reference_direction: tuple[float, float, float] | None = None

    def __post_init__(self) -> None:
        if self.brdf not in BRDF_PARAMETERS:
            raise ShapeError(
                f"unknown BRDF {self.brdf!r}; known models: {', '.join(BRDF_PARAMETERS)}"
            )
        required, optional = BRDF_PARAMETERS[self.brdf]
        params = dict(self.params)
        missing = [p for p in required if p not in params]
        unknown = [p for p in params if p not in required + optional]
        if missing:
            raise ShapeError(f"BRDF {self.brdf!r} needs parameter(s) {', '.join(missing)}")
        if unknown:
            raise ShapeError(
                f"BRDF {self.brdf!r} has no parameter(s) {', '.join(unknown)}; "
                f"allowed: {', '.join(required + optional)}"
            )
        clean: dict[str, float] = {}
        for key, value in params.items():
            try:
                number = float(value)
            except (TypeError, ValueError):
                raise ShapeError(f"BRDF parameter {key}={value!r} is not a number") from None
            if not math.isfinite(number):
                raise ShapeError(f"BRDF parameter {key}={value!r} is not finite")
            clean[key] = number
        object.__setattr__(self, "params", clean)
        if self.reference_direction is not None:
            object.__setattr__(self, "reference_direction", _unit_tuple(self.reference_direction))

    def __hash__(self) -> int:
        return hash(
            (self.brdf, tuple(sorted(self.params.items())), self.name, self.reference_direction)
        )

    def to_dict(self) -> dict[str, Any]:
        """Return the JSON-ready form used in the library manifest."""
        spec: dict[str, Any] = {"brdf": self.brdf, "params": dict(self.params)}
        if self.name is not None:
            spec["name"] = self.name
        if self.reference_direction is not None:
            spec["reference_direction"] = list(self.reference_direction)
        return spec

    @classmethod
    def from_dict(cls, spec: Mapping[str, Any], where: str = "material") -> Material:
        """Build a material from its manifest form ``{"brdf", "params", "name"?, ...}``.

        Parameters
        ----------
        spec : mapping
            The manifest entry.
        where : str
            Location named in error messages (e.g. ``"manifest.json: box_wing.bus"``).
        """
        if not isinstance(spec, Mapping) or "brdf" not in spec:
            raise ShapeError(f"{where}: a material needs a 'brdf' field, got {spec!r}")
        unknown = set(spec) - {"brdf", "params", "name", "reference_direction"}
        if unknown:
            raise ShapeError(f"{where}: unknown material field(s) {', '.join(sorted(unknown))}")
        try:
            return cls(
                brdf=spec["brdf"],
                params=dict(spec.get("params", {})),
                name=spec.get("name"),
                reference_direction=spec.get("reference_direction"),
            )
        except (ShapeError, TypeError, ValueError) as exc:
            raise ShapeError(f"{where}: {exc}") from None


def _unit_tuple(vector: Any) -> tuple[float, float, float]:
    try:
        x, y, z = (float(c) for c in vector)
    except (TypeError, ValueError):
        raise ShapeError(f"reference_direction {vector!r} is not a 3-vector") from None
    norm = math.sqrt(x * x + y * y + z * z)
    if not math.isfinite(norm) or norm == 0.0:
        raise ShapeError(f"reference_direction {vector!r} must be finite and non-zero")
    return (x / norm, y / norm, z / norm)


#: Multi-layer insulation blanket (crinkled Kapton/aluminised film): broad specular lobe.
MLI = Material("ashikhmin-shirley", {"rd": 0.2, "rs": 0.5, "nu": 10, "nv": 10}, name="MLI")
#: Solar-cell cover glass over dark cells: weak diffuse, strong narrow specular lobe.
SOLAR_CELL = Material(
    "ashikhmin-shirley", {"rd": 0.05, "rs": 0.3, "nu": 1000, "nv": 1000}, name="solar cell"
)
#: Rear of a solar-array panel (painted carbon-fibre substrate).
ARRAY_BACK = Material("lambert", {"rd": 0.3}, name="array back")
#: White paint with a faint gloss (rocket bodies, radiators).
WHITE_PAINT = Material(
    "ashikhmin-shirley", {"rd": 0.6, "rs": 0.05, "nu": 10, "nv": 10}, name="white paint"
)
#: Black paint (engine sections, baffles).
BLACK_PAINT = Material("lambert", {"rd": 0.05}, name="black paint")
#: Bare aluminium: specular with a moderate lobe.
ALUMINIUM = Material(
    "ashikhmin-shirley", {"rd": 0.2, "rs": 0.6, "nu": 200, "nv": 200}, name="aluminium"
)
#: Asteroid regolith: Lommel–Seeliger with DAMIT's Lambert weight c = 0.1 and phase function
#: a = 0.5, d = 0.1 rad, k = −0.5 rad⁻¹ (the convexinv defaults); the albedo scale ``w`` is
#: left to the BRDF's default (relative photometry).
REGOLITH = Material("lommel-seeliger", {"c": 0.1, "a": 0.5, "d": 0.1, "k": -0.5}, name="regolith")

#: Starlink v1.5 chassis underside and solar array: the two-lobe fits to the laboratory
#: BRDFs of Fankhauser, Askari & Tyson (2023) (the presets ``starlink-chassis`` and
#: ``starlink-solar-array`` of ``brdf/data/materials.toml``, where their fit is described;
#: a test keeps the two equal).
STARLINK_CHASSIS = Material(
    "two-lobe",
    {
        "rd": 0.02819,
        "rb": 0.2179,
        "ab": 0.06428,
        "fb": 1.0,
        "rn": 0.5631,
        "mn": 0.007205,
        "fn": 1.0,
    },
    name="chassis",
)
STARLINK_SOLAR_ARRAY = Material(
    "two-lobe",
    {
        "rd": 0.006184,
        "rb": 0.02062,
        "ab": 0.08117,
        "fb": 1.0,
        "rn": 0.9731,
        "mn": 0.001805,
        "fn": 0.02208,
    },
    name="solar_array",
)
