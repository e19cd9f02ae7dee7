"""Perturbed copies of a facet model: a "real object" drawn around its library model.

A real satellite or rocket body is never exactly its library model: its proportions differ
by manufacturing and by what the model left out, its coatings have aged, its mass is not
uniform (tanks, engines, electronics) and it carries small parts (antennas, thrusters) the
model lacks. :func:`perturbed_model` draws such an object from a :class:`FacetModel`, with
every drawn value recorded in a :class:`Perturbation`, so that an inversion run on its light
curve can be scored against the truth it was not told:

- **Proportions.** An affine stretch about the centre of mass along the model's principal
  axes (body frame), one factor per axis uniform in ``[1 − stretch, 1 + stretch]``.
- **Materials.** Each group's reflectance parameters drawn around the model's:
  reflectances and weights (``rd``, ``rs``, ``rb``, ``rn``, ``f0``, ``fb``, ``fn`` and the
  Lommel–Seeliger albedo ``w``) multiplied by a factor uniform in ``[1 − albedo,
  1 + albedo]`` (truncated so that each stays ≤ 1 and redrawn until the weights a model
  requires to sum to at most 1 do); lobe exponents (``n``, ``nu``, ``nv``) multiplied by
  ``exponent_factor^u`` and facet slopes or roughnesses (``m``, ``ab``, ``mn``), which vary
  as the inverse square root of an exponent, by ``exponent_factor^(u/2)``, ``u`` uniform in
  ``[−1, 1]``. An isotropic Ashikhmin–Shirley lobe (``nu = nv``) stays isotropic. The
  Lommel–Seeliger phase-function shape (``c``, ``a``, ``d``, ``k``) is kept.
- **Mass.** The model's mass distribution carried by the stretch (same mass; exact for a
  uniform solid or a flat plate), then each principal moment moved by a fraction uniform in
  ``moment_range`` with a random sign (redrawn until the moments satisfy the triangle
  inequality of a rigid body) and the principal axes turned by a random rotation: axis
  uniform on the sphere, angle uniform in ``[0, tilt_deg]``. The result carries the full
  body-frame inertia tensor (``inertia=`` of :class:`FacetModel`).
- **Appendage.** Optionally an antenna (a thin square rod) or a thruster (a small octagonal
  prism) standing on a flat face of a closed part of the stretched model (one that encloses
  a volume: a bus, a tank, not a solar-array sheet), along the face's outward normal, with
  the space above its footprint clear of the model (:func:`shapes.appendage.place_appendage`:
  antenna 2–3 % wide and 20–40 % long, thruster of radius 5–8 % and height 8–15 % of the
  model's length ``√(area / 6)``). It is a closed mesh concatenated to the
  model's (no boolean union): the model is then non-convex and is rendered with ray-cast
  shadows (``shadows="exact"``). It is taken as massless (its mass is well within the drawn
  moment offsets). A model with no flat face that can hold it gets none.

The draws use only the generator passed in, in a fixed order (stretch, materials, mass,
appendage), so one seed gives one object, and ``appendage=False`` leaves the other draws
unchanged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from shapes.appendage import APPENDAGE_KINDS, Appendage, place_appendage
from shapes.errors import ShapeError
from shapes.material import Material
from shapes.model import FacetModel

__all__ = [
    "APPENDAGE_KINDS",
    "Appendage",
    "MaterialDraw",
    "Perturbation",
    "perturbed_model",
]

#: Parameters multiplied by ``1 ± albedo`` (reflectances, lobe weights, Fresnel terms, albedo).
REFLECTANCES = frozenset({"rd", "rs", "rb", "rn", "f0", "fb", "fn", "w"})
#: Of those, the ones bounded by 1 (the others: any non-negative value).
UNIT_BOUNDED = frozenset({"rd", "rs", "rb", "rn", "f0", "fb", "fn"})
#: Lobe exponents: multiplied or divided by up to ``exponent_factor``.
EXPONENTS = frozenset({"n", "nu", "nv"})
#: Slopes and roughnesses (∝ exponent^−½): multiplied or divided by up to √exponent_factor.
ROUGHNESSES = frozenset({"m", "ab", "mn"})
#: Parameters kept as they are (the Lommel–Seeliger phase-function shape).
KEPT = frozenset({"c", "a", "d", "k"})
#: Weights whose sum a model requires to stay ≤ 1 (as ``brdf.describe(model).weights``).
WEIGHT_SUMS: dict[str, tuple[str, ...]] = {
    "phong": ("rd", "rs"),
    "cook-torrance": ("rd", "rs"),
    "two-lobe": ("rd", "rb", "rn"),
}
#: Optional reflectances drawn from the value the BRDF takes when they are absent.
IMPLIED: dict[str, dict[str, float]] = {"lommel-seeliger": {"w": 1.0}}
_MAX_REDRAWS = 10_000


@dataclass(frozen=True)
class MaterialDraw:
    """The drawn material of one facet group.

    Attributes
    ----------
    group : str
    brdf : str
        BRDF registry name (unchanged).
    before, after : dict[str, float]
        Parameters of the model's material and of the drawn one (dimensionless; exponents
        and slopes as the BRDF defines them).
    factors : dict[str, float]
        ``after / before`` of every drawn parameter.
    """

    group: str
    brdf: str
    before: dict[str, float]
    after: dict[str, float]
    factors: dict[str, float]

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form."""
        return {
            "group": self.group,
            "brdf": self.brdf,
            "before": dict(self.before),
            "after": dict(self.after),
            "factors": dict(self.factors),
        }


@dataclass(frozen=True, eq=False)
class Perturbation:
    """A perturbed model and the true values drawn for it (SI units, body frame).

    Attributes
    ----------
    model : FacetModel
        The perturbed model (given inertia, no visibility table).
    parent : str
        Name of the model it was drawn from.
    center : (3,) numpy.ndarray
        Centre of the stretch: the parent's centre of mass, m.
    stretch_axes : (3, 3) numpy.ndarray
        Columns: the parent's principal axes, along which the stretch acts.
    stretch : (3,) numpy.ndarray
        Factor along each of those axes.
    materials : list of MaterialDraw
        One per facet group of the parent.
    nominal_moments : (3,) numpy.ndarray
        Moments of the stretched uniform mass distribution about ``stretch_axes``, kg m².
    moments : (3,) numpy.ndarray
        True principal moments, kg m², in the same axis order.
    moment_offsets : (3,) numpy.ndarray
        ``moments / nominal_moments − 1``.
    principal_axes : (3, 3) numpy.ndarray
        Columns: the true principal axes, ``tilt · stretch_axes``.
    tilt_deg : float
        Angle of the rotation from ``stretch_axes`` to ``principal_axes``, deg.
    tilt_axis : (3,) numpy.ndarray
        Unit axis of that rotation, body frame.
    inertia : (3, 3) numpy.ndarray
        True inertia tensor about the centre of mass, kg m², body frame.
    appendage : Appendage or None
    appendage_note : str
        Why there is no appendage (empty when there is one).
    settings : dict
        The keyword arguments of the draw.
    """

    model: FacetModel
    parent: str
    center: np.ndarray
    stretch_axes: np.ndarray
    stretch: np.ndarray
    materials: list[MaterialDraw]
    nominal_moments: np.ndarray
    moments: np.ndarray
    moment_offsets: np.ndarray
    principal_axes: np.ndarray
    tilt_deg: float
    tilt_axis: np.ndarray
    inertia: np.ndarray
    appendage: Appendage | None = None
    appendage_note: str = ""
    settings: dict[str, Any] = field(default_factory=dict)

    @property
    def moment_ratios(self) -> np.ndarray:
        """True moments over the largest one, in the order of :attr:`moments`."""
        return self.moments / self.moments.max()

    @property
    def stretch_transform(self) -> np.ndarray:
        """The affine stretch ``D = P diag(s) Pᵀ`` (``P`` :attr:`stretch_axes`, ``s``
        :attr:`stretch`) applied about :attr:`center`, body frame."""
        return _stretch_transform(self.stretch_axes, self.stretch)

    def stretched(self, vertices: np.ndarray) -> np.ndarray:
        """``vertices`` (m, body frame) stretched as the object's mesh was."""
        return _stretch_vertices(vertices, self.center, self.stretch_transform)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready record of the draw (the model itself by name and fingerprint)."""
        return {
            "name": self.model.name,
            "parent": self.parent,
            "fingerprint": self.model.fingerprint,
            "facets": len(self.model.faces),
            "settings": dict(self.settings),
            "center_m": _floats(self.center),
            "stretch_axes": _floats(self.stretch_axes),
            "stretch": _floats(self.stretch),
            "materials": [m.to_dict() for m in self.materials],
            "nominal_moments_kg_m2": _floats(self.nominal_moments),
            "moments_kg_m2": _floats(self.moments),
            "moment_offsets": _floats(self.moment_offsets),
            "moment_ratios": _floats(self.moment_ratios),
            "principal_axes": _floats(self.principal_axes),
            "tilt_deg": float(self.tilt_deg),
            "tilt_axis": _floats(self.tilt_axis),
            "inertia_kg_m2": _floats(self.inertia),
            "appendage": None if self.appendage is None else self.appendage.to_dict(),
            "appendage_note": self.appendage_note,
        }


def _floats(array: np.ndarray) -> list[Any]:
    return np.asarray(array, float).tolist()


def perturbed_model(
    model: FacetModel,
    rng: np.random.Generator,
    *,
    stretch: float = 0.15,
    albedo: float = 0.30,
    exponent_factor: float = 2.0,
    moment_range: tuple[float, float] = (0.05, 0.10),
    tilt_deg: float = 5.0,
    appendage: bool | str = True,
    name: str | None = None,
) -> Perturbation:
    """Draw a "real object" around ``model`` (module docstring).

    Parameters
    ----------
    model : FacetModel
        The library model (body frame, m).
    rng : numpy.random.Generator
        The only source of randomness.
    stretch : float
        Half-width of the stretch factors' range, in ``[0, 1)``.
    albedo : float
        Half-width of the reflectance factors' range, in ``[0, 1)``.
    exponent_factor : float
        Largest factor (≥ 1) by which a lobe exponent is multiplied or divided.
    moment_range : (float, float)
        Range of the principal moments' relative offsets (each in ``[0, 1)``).
    tilt_deg : float
        Largest angle between the true and the geometric principal axes, deg.
    appendage : bool or {"antenna", "thruster"}
        Add an appendage (True: its kind drawn), or not.
    name : str, optional
        Name of the new model (default ``"<parent>-perturbed"``).

    Returns
    -------
    Perturbation

    Raises
    ------
    ShapeError
        Settings out of range, or no physical moments drawn (a degenerate parent inertia).
    """
    _check_settings(stretch, albedo, exponent_factor, moment_range, tilt_deg, appendage)
    center = np.asarray(model.center_of_mass, float)
    axes = np.asarray(model.principal_axes, float)
    factors = rng.uniform(1.0 - stretch, 1.0 + stretch, 3)
    transform = _stretch_transform(axes, factors)
    vertices = _stretch_vertices(model.vertices, center, transform)

    draws = [
        _draw_material(group, model.materials[group], transform, rng, albedo, exponent_factor)
        for group in model.group_names
    ]
    nominal = np.diag(axes.T @ _stretched_inertia(model.inertia, transform) @ axes)
    moments, offsets = _draw_moments(nominal, moment_range, rng)
    tilt_axis = _unit(rng.standard_normal(3))
    tilt = math.radians(rng.uniform(0.0, tilt_deg))
    principal = Rotation.from_rotvec(tilt * tilt_axis).as_matrix() @ axes
    inertia = principal @ np.diag(moments) @ principal.T
    inertia = 0.5 * (inertia + inertia.T)

    parts = _with_appendage(vertices, model, appendage, rng)
    vertices, faces, group_index, group_names, added, note = parts
    materials = {d.group: d.material for d in draws}
    if added is not None:
        materials[added.group] = APPENDAGE_KINDS[added.kind]
    settings = {
        "stretch": stretch,
        "albedo": albedo,
        "exponent_factor": exponent_factor,
        "moment_range": list(moment_range),
        "tilt_deg": tilt_deg,
        "appendage": appendage,
    }
    mass = model.mass
    perturbed = FacetModel(
        vertices,
        faces,
        group_index=group_index,
        group_names=group_names,
        materials=materials,
        unit=model.unit,
        name=name or f"{model.name}-perturbed",
        provenance={**model.provenance, "perturbed_from": model.name, "perturbation": settings},
        inertia=inertia,
        mass=mass if math.isfinite(mass) else None,
        center_of_mass=center,
    )
    return Perturbation(
        model=perturbed,
        parent=model.name,
        center=center,
        stretch_axes=axes,
        stretch=factors,
        materials=[d.record for d in draws],
        nominal_moments=nominal,
        moments=moments,
        moment_offsets=offsets,
        principal_axes=principal,
        tilt_deg=math.degrees(tilt),
        tilt_axis=tilt_axis,
        inertia=inertia,
        appendage=added,
        appendage_note=note,
        settings=settings,
    )


def _with_appendage(
    vertices: np.ndarray, model: FacetModel, appendage: bool | str, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[str], Appendage | None, str]:
    """The stretched mesh (``vertices``, the model's facets) with the appendage, if asked
    and placed: vertices, faces, group index, group names, the record and the note."""
    faces, group_index = model.faces, model.group_index
    group_names = list(model.group_names)
    if not appendage:
        return vertices, faces, group_index, group_names, None, "not requested"
    kinds = list(APPENDAGE_KINDS)
    kind = str(appendage) if isinstance(appendage, str) else kinds[int(rng.integers(len(kinds)))]
    placed = place_appendage(vertices, faces, group_index, group_names, kind, rng)
    if placed is None:
        note = "no flat face of a closed part of the model can hold it clear of the rest"
        return vertices, faces, group_index, group_names, None, note
    part_vertices, part_faces, added = placed
    group_index = np.concatenate(
        [group_index, np.full(len(part_faces), len(group_names), dtype=np.int64)]
    )
    faces = np.concatenate([faces, part_faces + len(vertices)])
    return (
        np.concatenate([vertices, part_vertices]),
        faces,
        group_index,
        [*group_names, added.group],
        added,
        "",
    )


def _check_settings(
    stretch: float,
    albedo: float,
    exponent_factor: float,
    moment_range: tuple[float, float],
    tilt_deg: float,
    appendage: bool | str,
) -> None:
    low, high = (float(v) for v in moment_range)
    problems = [
        (0.0 <= stretch < 1.0, f"stretch must be in [0, 1), got {stretch!r}"),
        (0.0 <= albedo < 1.0, f"albedo must be in [0, 1), got {albedo!r}"),
        (exponent_factor >= 1.0, f"exponent_factor must be ≥ 1, got {exponent_factor!r}"),
        (0.0 <= low <= high < 1.0, f"moment_range must be 0 ≤ low ≤ high < 1, got {moment_range}"),
        (0.0 <= tilt_deg <= 180.0, f"tilt_deg must be in [0, 180], got {tilt_deg!r}"),
        (
            isinstance(appendage, bool) or appendage in APPENDAGE_KINDS,
            f"appendage must be True, False or one of {', '.join(APPENDAGE_KINDS)}, "
            f"got {appendage!r}",
        ),
    ]
    for ok, message in problems:
        if not ok:
            raise ShapeError(message)


# ------------------------------------------------------------------------------ materials
@dataclass(frozen=True)
class _Drawn:
    material: Material
    record: MaterialDraw

    @property
    def group(self) -> str:
        return self.record.group


def _draw_material(
    group: str,
    material: Material,
    transform: np.ndarray,
    rng: np.random.Generator,
    albedo: float,
    exponent_factor: float,
) -> _Drawn:
    """Draw one group's material (module docstring); parameters in sorted name order."""
    before = {**IMPLIED.get(material.brdf, {}), **material.params}
    names = sorted(before)
    unknown = set(names) - (REFLECTANCES | EXPONENTS | ROUGHNESSES | KEPT)
    if unknown:  # a parameter added to shapes.material that this module does not know
        raise ShapeError(f"no perturbation rule for parameter(s) {', '.join(sorted(unknown))}")
    weights = WEIGHT_SUMS.get(material.brdf, ())
    after = dict(before)
    for _ in range(_MAX_REDRAWS):
        for key in names:
            if key in REFLECTANCES:
                top = 1.0 + albedo
                if key in UNIT_BOUNDED and before[key] > 0:
                    top = min(top, 1.0 / before[key])
                after[key] = before[key] * rng.uniform(1.0 - albedo, max(top, 1.0 - albedo))
        if sum(after[k] for k in weights) <= 1.0:
            break
    else:  # every draw broke the sum (weights summing to ~1 already): scale them back to 1
        total = sum(after[k] for k in weights)
        after.update({k: after[k] / total for k in weights})
    shared: float | None = None
    for key in names:
        if key in EXPONENTS:
            factor = exponent_factor ** rng.uniform(-1.0, 1.0)
            if material.brdf == "ashikhmin-shirley" and before["nu"] == before["nv"]:
                shared = factor if shared is None else shared
                factor = shared
            after[key] = before[key] * factor
        elif key in ROUGHNESSES:
            after[key] = before[key] * exponent_factor ** (0.5 * rng.uniform(-1.0, 1.0))
    reference = material.reference_direction
    if reference is not None:  # a tangent direction goes with the stretch
        reference = tuple(_unit(transform @ np.asarray(reference, float)))
    drawn = Material(material.brdf, after, material.name, reference)
    factors = {k: after[k] / before[k] for k in names if k not in KEPT and before[k] != 0}
    record = MaterialDraw(group, material.brdf, before, dict(drawn.params), factors)
    return _Drawn(drawn, record)


# ----------------------------------------------------------------------------------- mass
def _stretch_transform(axes: np.ndarray, factors: np.ndarray) -> np.ndarray:
    """``P diag(s) Pᵀ``: stretch factors ``s`` along the columns of ``P``."""
    return axes @ np.diag(factors) @ axes.T


def _stretch_vertices(
    vertices: np.ndarray, center: np.ndarray, transform: np.ndarray
) -> np.ndarray:
    """``vertices`` mapped by ``transform`` about ``center``."""
    return center + (vertices - center) @ transform.T


def _stretched_inertia(inertia: np.ndarray, transform: np.ndarray) -> np.ndarray:
    """Inertia about the centre of the same mass distribution mapped by ``x → A x``.

    With the second moment ``M = ∫ r rᵀ dm = ½ tr(J) I − J``, the mapped body has
    ``M' = A M Aᵀ`` and ``J' = tr(M') I − M'``.
    """
    second = 0.5 * np.trace(inertia) * np.eye(3) - inertia
    mapped = transform @ second @ transform.T
    out = np.trace(mapped) * np.eye(3) - mapped
    return 0.5 * (out + out.T)


def _draw_moments(
    nominal: np.ndarray, moment_range: tuple[float, float], rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Moments ``nominal · (1 ± δ)``, ``δ`` uniform in ``moment_range`` and a random sign per
    axis, redrawn until they satisfy the triangle inequality of a rigid body."""
    for _ in range(_MAX_REDRAWS):
        signs = np.where(rng.random(3) < 0.5, -1.0, 1.0)
        offsets = signs * rng.uniform(*moment_range, 3)
        moments = nominal * (1.0 + offsets)
        ordered = np.sort(moments)
        if ordered[0] > 0 and ordered[2] <= ordered[0] + ordered[1]:
            return moments, offsets
    raise ShapeError(
        f"no physical principal moments drawn around {nominal.tolist()} within {list(moment_range)}"
    )


def _unit(vector: np.ndarray) -> np.ndarray:
    return vector / np.linalg.norm(vector)
