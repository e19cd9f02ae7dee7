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
  the space above its footprint clear of the model. Its size scales with the model's
  length ``√(area / 6)`` (a cube's edge): antenna 2–3 % wide and 20–40 % long, thruster of
  radius 5–8 % and height 8–15 %. It is a closed mesh concatenated to the
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
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from shapes.errors import ShapeError
from shapes.material import ALUMINIUM, BLACK_PAINT, Material
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
#: Appendage kinds and their materials.
APPENDAGE_KINDS: dict[str, Material] = {"antenna": ALUMINIUM, "thruster": BLACK_PAINT}
#: Appendage sizes as fractions of the model's length ``√(area / 6)`` (a cube's edge):
#: antenna width and length, thruster radius and height, each drawn uniform in its range.
_ANTENNA_WIDTH = (0.02, 0.03)
_ANTENNA_LENGTH = (0.2, 0.4)
_THRUSTER_RADIUS = (0.05, 0.08)
_THRUSTER_HEIGHT = (0.08, 0.15)
_THRUSTER_SECTIONS = 8
_PLACEMENT_TRIES = 200
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
class Appendage:
    """A small part added to the model.

    Attributes
    ----------
    kind : {"antenna", "thruster"}
    group : str
        Facet group of its facets.
    host_group : str
        Group of the face it stands on.
    base : (3,) numpy.ndarray
        Centre of its footprint on the host face, m, body frame.
    direction : (3,) numpy.ndarray
        Unit outward normal of the host face, its axis (body frame).
    size : dict[str, float]
        ``width`` and ``length`` (antenna) or ``radius`` and ``height`` (thruster), m.
    facets : int
        Facets added.
    area : float
        Its surface area, m².
    """

    kind: str
    group: str
    host_group: str
    base: np.ndarray
    direction: np.ndarray
    size: dict[str, float]
    facets: int
    area: float

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form."""
        return {
            "kind": self.kind,
            "group": self.group,
            "host_group": self.host_group,
            "base_m": [float(v) for v in self.base],
            "direction": [float(v) for v in self.direction],
            "size_m": {k: float(v) for k, v in self.size.items()},
            "facets": int(self.facets),
            "area_m2": float(self.area),
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
    transform = axes @ np.diag(factors) @ axes.T
    vertices = center + (model.vertices - center) @ transform.T

    draws = [
        _draw_material(group, model.materials[group], transform, rng, albedo, exponent_factor)
        for group in model.group_names
    ]
    nominal = np.diag(axes.T @ _stretched_inertia(model.inertia, transform) @ axes)
    moments, offsets = _draw_moments(nominal, moment_range, rng)
    tilt_axis = _unit(rng.standard_normal(3))
    tilt = math.radians(rng.uniform(0.0, tilt_deg))
    principal = _rotation(tilt_axis, tilt) @ axes
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
    placed = _place_appendage(vertices, faces, group_index, group_names, kind, rng)
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


def _rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation matrix turning vectors by ``angle`` (rad) about unit ``axis`` (Rodrigues)."""
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + math.sin(angle) * k + (1.0 - math.cos(angle)) * (k @ k)


# ------------------------------------------------------------------------------ appendage
def _place_appendage(
    vertices: np.ndarray,
    faces: np.ndarray,
    group_index: np.ndarray,
    group_names: list[str],
    kind: str,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray, Appendage] | None:
    """Draw an appendage's size and a clear place on a flat face of the mesh.

    The footprint (grown by 10 %) must lie on one flat region of a closed part (coplanar
    facets of one group joined by edges; regions of at least four footprints' area are
    drawn in proportion to their area, then a point uniformly on them), the rays along the
    normal from its corners, edge midpoints and centre must not hit the mesh, no mesh edge
    may cross the part and no mesh vertex lie inside it. Up to ``_PLACEMENT_TRIES`` places
    are drawn; None when none fits.
    """
    triangles = vertices[faces]
    cross = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    areas = 0.5 * np.linalg.norm(cross, axis=1)
    length = math.sqrt(areas.sum() / 6.0)
    if kind == "antenna":
        width = length * rng.uniform(*_ANTENNA_WIDTH)
        size = {"width": width, "length": length * rng.uniform(*_ANTENNA_LENGTH)}
        half = 0.5 * width
        height = size["length"]
    else:
        size = {
            "radius": length * rng.uniform(*_THRUSTER_RADIUS),
            "height": length * rng.uniform(*_THRUSTER_HEIGHT),
        }
        half = size["radius"]
        height = size["height"]
    regions, normals = _flat_regions(triangles, cross, areas, group_index)
    footprint_area = 4.0 * half * half
    region_area = np.array([areas[r].sum() for r in regions])
    usable = np.flatnonzero(region_area >= 4.0 * footprint_area)
    if not len(usable):
        return None
    weights = region_area[usable] / region_area[usable].sum()
    tol = 1e-9 * max(float(np.ptp(vertices, axis=0).max()), 1e-300)
    for _ in range(_PLACEMENT_TRIES):
        region = int(usable[rng.choice(len(usable), p=weights)])
        members = regions[region]
        normal = normals[region]
        facet = members[rng.choice(len(members), p=areas[members] / areas[members].sum())]
        a, b = rng.random(2)
        if a + b > 1.0:
            a, b = 1.0 - a, 1.0 - b
        tri = triangles[facet]
        base = tri[0] + a * (tri[1] - tri[0]) + b * (tri[2] - tri[0])
        e_u = _unit(np.cross(normal, _least_aligned(normal)))
        turn = rng.uniform(0.0, 2.0 * math.pi)
        e_u = _rotation(normal, turn) @ e_u
        frame = np.stack([e_u, np.cross(normal, e_u), normal], axis=1)
        part_vertices, part_faces = _part_mesh(kind, size)
        if not _fits(
            triangles,
            vertices,
            faces,
            members,
            base,
            frame,
            half,
            height,
            part_vertices,
            part_faces,
            tol,
        ):
            continue
        world = base + part_vertices @ frame.T
        part_triangles = world[part_faces]
        part_cross = np.cross(
            part_triangles[:, 1] - part_triangles[:, 0], part_triangles[:, 2] - part_triangles[:, 0]
        )
        group = kind
        while group in group_names:
            group += "_"
        host = group_names[int(group_index[members[0]])]
        record = Appendage(
            kind=kind,
            group=group,
            host_group=host,
            base=base,
            direction=normal,
            size=size,
            facets=len(part_faces),
            area=float(0.5 * np.linalg.norm(part_cross, axis=1).sum()),
        )
        return world, part_faces, record
    return None


def _least_aligned(normal: np.ndarray) -> np.ndarray:
    return np.eye(3)[int(np.argmin(np.abs(normal)))]


def _part_mesh(kind: str, size: dict[str, float]) -> tuple[np.ndarray, np.ndarray]:
    """The part in its own frame: footprint centred on the origin in the x–y plane, axis +z,
    outward winding."""
    import trimesh

    if kind == "antenna":
        mesh = trimesh.creation.box(extents=(size["width"], size["width"], size["length"]))
        height = size["length"]
    else:
        mesh = trimesh.creation.cylinder(
            radius=size["radius"], height=size["height"], sections=_THRUSTER_SECTIONS
        )
        height = size["height"]
    vertices = np.array(mesh.vertices, float)
    vertices[:, 2] += 0.5 * height
    return vertices, np.array(mesh.faces, dtype=np.int64)


def _flat_regions(
    triangles: np.ndarray, cross: np.ndarray, areas: np.ndarray, group_index: np.ndarray
) -> tuple[list[np.ndarray], np.ndarray]:
    """Flat regions of the closed parts enclosing a volume: facets of one group, coplanar,
    joined by shared edges; and their normals."""
    n_faces = len(triangles)
    normals = np.divide(
        cross, 2.0 * areas[:, None], out=np.zeros_like(cross), where=areas[:, None] > 0
    )
    offsets = np.einsum("fi,fi->f", normals, triangles[:, 0])
    scale = max(float(np.ptp(triangles.reshape(-1, 3), axis=0).max()), 1e-300)
    # Edges keyed by their end points' positions (a soup of duplicated vertices still joins).
    points = np.round(triangles.reshape(-1, 3) / (1e-9 * scale)).astype(np.int64)
    _, point_id = np.unique(points, axis=0, return_inverse=True)
    point_id = point_id.reshape(n_faces, 3)
    following = np.roll(point_id, -1, axis=1)
    edges = np.stack([np.minimum(point_id, following), np.maximum(point_id, following)], -1)
    _, edge_id = np.unique(edges.reshape(-1, 2), axis=0, return_inverse=True)
    edge_id = edge_id.reshape(-1)
    face_of = np.repeat(np.arange(n_faces), 3)
    order = np.argsort(edge_id, kind="stable")
    same = edge_id[order][1:] == edge_id[order][:-1]
    i, j = face_of[order][:-1][same], face_of[order][1:][same]
    joined = (
        (group_index[i] == group_index[j])
        & (np.einsum("fi,fi->f", normals[i], normals[j]) > 1.0 - 1e-9)
        & (np.abs(offsets[i] - offsets[j]) < 1e-9 * scale)
        & (areas[i] > 0)
        & (areas[j] > 0)
    )
    graph = coo_matrix(
        (np.ones(int(joined.sum())), (i[joined], j[joined])), shape=(n_faces, n_faces)
    )
    count, labels = connected_components(graph, directed=False)
    solid = _solid_facets(triangles, edge_id, face_of, i, j, scale)
    regions = [np.flatnonzero(labels == k) for k in range(count)]
    keep = [r for r in regions if areas[r].sum() > 0 and solid[r].all()]
    region_normals = np.array([normals[r[np.argmax(areas[r])]] for r in keep]).reshape(-1, 3)
    return keep, region_normals


def _solid_facets(
    triangles: np.ndarray,
    edge_id: np.ndarray,
    face_of: np.ndarray,
    i: np.ndarray,
    j: np.ndarray,
    scale: float,
) -> np.ndarray:
    """(F,) bool: the facet belongs to a closed part (every edge shared by two facets) that
    encloses a volume (a two-sided sheet is closed but encloses none)."""
    n_faces = len(triangles)
    graph = coo_matrix((np.ones(len(i)), (i, j)), shape=(n_faces, n_faces))
    count, part = connected_components(graph, directed=False)
    open_edge = np.bincount(edge_id) != 2
    is_open = np.zeros(count, dtype=bool)
    np.logical_or.at(is_open, part[face_of], open_edge[edge_id])
    centre = triangles.reshape(-1, 3).mean(axis=0)
    a, b, c = (triangles[:, k] - centre for k in range(3))
    volume = np.bincount(part, np.einsum("fi,fi->f", a, np.cross(b, c)) / 6.0, minlength=count)
    return (~is_open & (volume > 1e-9 * scale**3))[part]


def _fits(
    triangles: np.ndarray,
    vertices: np.ndarray,
    faces: np.ndarray,
    members: np.ndarray,
    base: np.ndarray,
    frame: np.ndarray,
    half: float,
    height: float,
    part_vertices: np.ndarray,
    part_faces: np.ndarray,
    tol: float,
) -> bool:
    """Whether the part (own frame ``part_vertices``; ``frame`` columns: its x, y, z axes in
    the body frame) stands at ``base`` on region ``members`` clear of the mesh."""
    grid = np.array([-1.1, 0.0, 1.1]) * half
    u, v = np.meshgrid(grid, grid, indexing="ij")
    footprint = base + np.stack([u.ravel(), v.ravel(), np.zeros(u.size)], 1) @ frame.T
    if not _inside_any(footprint, triangles[members]):
        return False
    normal = frame[:, 2]
    lift = 1e-6 * height
    rays = np.broadcast_to(normal, footprint.shape)
    if _hits(footprint + lift * normal, rays, np.inf, triangles).any():
        return False
    # The part shrunk by a part in a million, off the face it stands on, against the mesh.
    local = part_vertices * np.array([1.0 - 1e-6, 1.0 - 1e-6, 1.0 - 2e-6]) + [0.0, 0.0, lift]
    part = base + local @ frame.T
    part_edges = _edges(part_faces)
    starts, ends = part[part_edges[:, 0]], part[part_edges[:, 1]]
    if _hits(starts, ends - starts, 1.0, triangles).any():
        return False
    mesh_edges = _edges(faces)
    starts, ends = vertices[mesh_edges[:, 0]], vertices[mesh_edges[:, 1]]
    if _hits(starts, ends - starts, 1.0, part[part_faces]).any():
        return False
    corners = part[part_faces]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    depth = np.einsum("fi,vfi->vf", normals, vertices[:, None, :] - corners[None, :, 0])
    return not bool(np.any(np.all(depth < -tol, axis=1)))


def _edges(faces: np.ndarray) -> np.ndarray:
    """Distinct undirected edges ``(E, 2)`` of a face array (vertex indices)."""
    pairs = np.stack([faces, np.roll(faces, -1, axis=1)], axis=-1).reshape(-1, 2)
    return np.unique(np.sort(pairs, axis=1), axis=0)


def _inside_any(points: np.ndarray, triangles: np.ndarray) -> bool:
    """Whether every point (in the triangles' common plane) lies in one of the triangles."""
    v0 = triangles[:, 0]
    e1, e2 = triangles[:, 1] - v0, triangles[:, 2] - v0
    d11, d12, d22 = (np.einsum("ti,ti->t", a, b) for a, b in ((e1, e1), (e1, e2), (e2, e2)))
    rel = points[:, None, :] - v0[None]
    r1, r2 = np.einsum("pti,ti->pt", rel, e1), np.einsum("pti,ti->pt", rel, e2)
    det = d11 * d22 - d12 * d12
    with np.errstate(divide="ignore", invalid="ignore"):
        a = (d22 * r1 - d12 * r2) / det
        b = (d11 * r2 - d12 * r1) / det
    eps = 1e-9
    inside = (a >= -eps) & (b >= -eps) & (a + b <= 1.0 + eps) & (det > 0)
    return bool(inside.any(axis=1).all())


def _hits(
    origins: np.ndarray, directions: np.ndarray, t_max: float, triangles: np.ndarray
) -> np.ndarray:
    """Whether each ray ``o + t d``, ``0 < t < t_max``, crosses one of the triangles.

    Möller & Trumbore (1997), "Fast, minimum storage ray-triangle intersection", Journal of
    Graphics Tools 2(1), 21–28; in chunks of rays so that the work arrays stay small.
    """
    v0 = triangles[:, 0]
    e1, e2 = triangles[:, 1] - v0, triangles[:, 2] - v0
    out = np.zeros(len(origins), dtype=bool)
    step = max(1, 200_000 // max(len(triangles), 1))
    for start in range(0, len(origins), step):
        o = origins[start : start + step, None, :]
        d = np.broadcast_to(directions[start : start + step, None, :], (len(o), 1, 3))
        p = np.cross(d, e2[None])
        det = np.einsum("sti,ti->st", p, e1)
        size = np.linalg.norm(d, axis=-1) * np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1)
        valid = np.abs(det) > 1e-12 * size
        inverse = np.divide(1.0, det, out=np.zeros_like(det), where=valid)
        s = o - v0[None]
        u = np.einsum("sti,sti->st", s, p) * inverse
        q = np.cross(s, e1[None])
        v = np.einsum("sti,sti->st", np.broadcast_to(d, q.shape), q) * inverse
        t = np.einsum("sti,ti->st", q, e2) * inverse
        hit = valid & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0) & (t < t_max)
        out[start : start + step] = hit.any(axis=1)
    return out
