"""Primitive facet models with named groups and default materials (SI, metres).

Every primitive is centred on its centre of symmetry with its symmetry axis along z (the
box-wing's array axis along y). Rectangular panels can be cut into ``n × n`` cells
(``subdivisions``) to imitate a CAD tessellation; coplanar cells merge again when compiled.
The default materials are the presets of :mod:`shapes.material`; ``materials=`` overrides
them per group (or all groups, given one :class:`~shapes.material.Material`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import trimesh

from shapes import mass as mass_props
from shapes.errors import ShapeError
from shapes.material import (
    ALUMINIUM,
    ARRAY_BACK,
    BLACK_PAINT,
    MLI,
    REGOLITH,
    SOLAR_CELL,
    WHITE_PAINT,
    Material,
)
from shapes.model import FacetModel

__all__ = [
    "box",
    "box_wing",
    "cylinder",
    "ellipsoid",
    "icosphere",
    "panels",
    "plate",
    "rocket_body",
]

Materials = Material | Mapping[str, Material] | None
Part = tuple[np.ndarray, np.ndarray]  # (vertices, faces)


def _materials(defaults: dict[str, Material], override: Materials) -> dict[str, Material]:
    if isinstance(override, Material):
        return dict.fromkeys(defaults, override)
    unknown = set(override or {}) - set(defaults)
    if unknown:
        raise ShapeError(
            f"no group(s) {', '.join(sorted(unknown))}; groups are {', '.join(defaults)}"
        )
    return {**defaults, **dict(override or {})}


def _model(
    part: Part,
    groups: dict[str, Material],
    materials: Materials,
    name: str,
    provenance: dict[str, object],
    *,
    group_index: np.ndarray | None = None,
    **mass_properties: object,
) -> FacetModel:
    """A primitive's model: ``groups`` (name → default material) in the order of
    ``group_index``, the defaults overridden by ``materials``; ``mass_properties`` are the
    ``inertia``, ``mass`` and ``center_of_mass`` of `FacetModel` where they are given."""
    vertices, faces = part
    return FacetModel(
        vertices,
        faces,
        group_index=group_index,
        group_names=list(groups),
        materials=_materials(groups, materials),
        name=name,
        provenance=provenance,
        **mass_properties,
    )


def _positive(**values: float) -> None:
    for key, value in values.items():
        if not np.all(np.isfinite(value)) or np.any(np.asarray(value) <= 0):
            raise ShapeError(f"{key} must be positive and finite, got {value!r}")


def _cells(n: int) -> np.ndarray:
    """Faces of an (n+1) × (n+1) node lattice (row-major), wound +u × +v."""
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    a = (i * (n + 1) + j).ravel()
    b, c, d = a + (n + 1), a + (n + 2), a + 1
    return np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


def _dedupe(vertices: np.ndarray, faces: np.ndarray) -> Part:
    """Merge bit-identical vertices (shared panel edges) so closed parts are watertight."""
    unique, first, inverse = np.unique(vertices, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    return unique[order], rank[inverse.reshape(-1)][faces]


def _box_part(size: Sequence[float], center: Sequence[float], n: int) -> Part:
    """Closed box with every face cut into n × n cells, outward winding."""
    ticks = [c + np.linspace(-0.5 * s, 0.5 * s, n + 1) for s, c in zip(size, center, strict=True)]
    vertices, faces = [], []
    for axis in range(3):
        u_axis, v_axis = (axis + 1) % 3, (axis + 2) % 3
        u, v = np.meshgrid(ticks[u_axis], ticks[v_axis], indexing="ij")
        for side in (0, -1):
            face = np.empty((u.size, 3))
            face[:, axis] = ticks[axis][side]
            face[:, u_axis], face[:, v_axis] = u.ravel(), v.ravel()
            cells = _cells(n) if side == -1 else _cells(n)[:, ::-1]
            faces.append(cells + sum(len(p) for p in vertices))
            vertices.append(face)
    return _dedupe(np.concatenate(vertices), np.concatenate(faces))


def _sheet(
    center: np.ndarray, e_u: np.ndarray, e_v: np.ndarray, size: tuple[float, float], n: int
) -> Part:
    """Open rectangle ``size[0]`` along ``e_u`` by ``size[1]`` along ``e_v``; normal e_u × e_v."""
    a = np.linspace(-0.5, 0.5, n + 1)
    u, v = np.meshgrid(a * size[0], a * size[1], indexing="ij")
    vertices = center + u.reshape(-1, 1) * e_u + v.reshape(-1, 1) * e_v
    return vertices, _cells(n)


def _assemble(parts: Sequence[tuple[str, Part]], group_names: list[str]) -> tuple:
    """Stack parts (group name, (vertices, faces)) into one mesh with a group index."""
    vertices, faces, index = [], [], []
    offset = 0
    for group, (v, f) in parts:
        vertices.append(v)
        faces.append(f + offset)
        index.append(np.full(len(f), group_names.index(group)))
        offset += len(v)
    return np.concatenate(vertices), np.concatenate(faces), np.concatenate(index)


def plate(
    width: float = 2.0,
    height: float = 1.0,
    *,
    subdivisions: int = 1,
    materials: Materials = None,
    name: str = "plate",
) -> FacetModel:
    """Two-sided flat plate in the x–y plane: group ``front`` (normal +z) and ``back`` (−z).

    The two sides are separate sheets on the same vertices' positions, so the model is
    open and its inertia is that of a thin shell (default). Defaults: front solar cell,
    back painted panel.

    Parameters
    ----------
    width, height : float
        Extent along x and y, m.
    subdivisions : int
        Cells per side of each sheet.
    """
    _positive(width=width, height=height)
    front = _sheet(np.zeros(3), np.eye(3)[0], np.eye(3)[1], (width, height), subdivisions)
    back = (front[0].copy(), front[1][:, ::-1])
    groups = {"front": SOLAR_CELL, "back": ARRAY_BACK}
    vertices, faces, index = _assemble([("front", front), ("back", back)], list(groups))
    return _model(
        (vertices, faces),
        groups,
        materials,
        name,
        {"source": f"shapes.primitives.plate({width}, {height})"},
        group_index=index,
    )


def panels(
    layout: Mapping[str, tuple[Sequence[float], float, Sequence[float]]],
    materials: Mapping[str, Material],
    *,
    name: str = "panels",
) -> FacetModel:
    """One-sided square panels, one material group each: a satellite modelled by its
    surfaces (e.g. a nadir face and a solar array) rather than by a closed body.

    Parameters
    ----------
    layout : mapping
        Group name → ``(normal, area, center)``: the panel's outward unit normal (body
        frame), its area (m²) and its centre (m).
    materials : mapping
        Group name → material, for every group of ``layout``.

    Returns
    -------
    FacetModel
        Open; inertia of a thin shell (default).
    """
    missing = set(layout) - set(materials)
    if missing:
        raise ShapeError(f"no material for panel(s) {', '.join(sorted(missing))}")
    parts = []
    for group, (normal, area, center) in layout.items():
        _positive(**{f"{group} area": area})
        n = np.asarray(normal, dtype=float)
        n = n / np.linalg.norm(n)
        e_u = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
        e_u /= np.linalg.norm(e_u)
        side = float(np.sqrt(area))
        parts.append(
            (group, _sheet(np.asarray(center, float), e_u, np.cross(n, e_u), (side, side), 1))
        )
    groups = {group: materials[group] for group in layout}
    vertices, faces, index = _assemble(parts, list(groups))
    return _model(
        (vertices, faces),
        groups,
        None,
        name,
        {"source": "shapes.primitives.panels"},
        group_index=index,
    )


def box(
    size: Sequence[float] = (1.0, 1.0, 1.0),
    *,
    subdivisions: int = 1,
    materials: Materials = None,
    name: str = "box",
) -> FacetModel:
    """Closed box of edge lengths ``size`` (x, y, z), m; one group ``body`` (default MLI)."""
    _positive(size=np.asarray(size, float))
    return _model(
        _box_part(size, (0.0, 0.0, 0.0), subdivisions),
        {"body": MLI},
        materials,
        name,
        {"source": f"shapes.primitives.box({list(map(float, size))})"},
    )


def cylinder(
    radius: float = 0.5,
    height: float = 2.0,
    *,
    sections: int = 32,
    materials: Materials = None,
    name: str = "cylinder",
) -> FacetModel:
    """Closed right prism with a regular ``sections``-gon base (circumradius ``radius``).

    Axis z, centred on the origin. Groups ``side`` and ``ends`` (default aluminium, white
    paint).
    """
    _positive(radius=radius, height=height)
    mesh = trimesh.creation.cylinder(radius=radius, height=height, sections=sections)
    return _model(
        (mesh.vertices, mesh.faces),
        {"side": ALUMINIUM, "ends": WHITE_PAINT},
        materials,
        name,
        {"source": f"shapes.primitives.cylinder({radius}, {height}, sections={sections})"},
        group_index=(np.abs(mesh.face_normals[:, 2]) > 0.5).astype(int),
    )


def rocket_body(
    radius: float = 1.95,
    length: float = 9.0,
    nose_length: float = 2.0,
    *,
    sections: int = 32,
    materials: Materials = None,
    name: str = "rocket_body",
) -> FacetModel:
    """Cone-capped cylinder (upper stage): groups ``aft`` (flat end at z = 0), ``body``, ``nose``.

    The default proportions are those of a Zenit-2 / SL-16 second stage (3.9 m diameter,
    11 m long); defaults: black aft end, white-painted body and nose.

    Parameters
    ----------
    radius : float
        m.
    length : float
        Cylindrical part, m (from z = 0).
    nose_length : float
        Cone height, m (apex at z = length + nose_length).
    sections : int
        Facets around the axis.
    """
    _positive(radius=radius, length=length, nose_length=nose_length)
    profile = np.array([[0.0, 0.0], [radius, 0.0], [radius, length], [0.0, length + nose_length]])
    mesh = trimesh.creation.revolve(profile, sections=sections)
    aft, nose = mesh.face_normals[:, 2] < -0.99, mesh.triangles_center[:, 2] > length
    source = (
        f"shapes.primitives.rocket_body({radius}, {length}, {nose_length}, sections={sections})"
    )
    return _model(
        (mesh.vertices, mesh.faces),
        {"aft": BLACK_PAINT, "body": WHITE_PAINT, "nose": WHITE_PAINT},
        materials,
        name,
        {"source": source},
        group_index=np.where(aft, 0, np.where(nose, 2, 1)),
    )


def box_wing(
    bus_size: Sequence[float] = (2.5, 2.5, 3.0),
    wing_length: float = 5.5,
    wing_width: float = 2.2,
    yoke_length: float = 1.0,
    yoke_width: float = 0.1,
    array_normal: Sequence[float] = (1.0, 0.0, 0.0),
    *,
    subdivisions: int = 1,
    bus_mass: float = 3000.0,
    array_areal_density: float = 3.0,
    yoke_mass: float = 10.0,
    materials: Materials = None,
    name: str = "box_wing",
) -> FacetModel:
    """GEO box-wing satellite: bus, two solar-array wings along ±y on yokes.

    Groups ``bus`` (MLI), ``solar_array`` (cell side, solar cell), ``array_back`` (rear of
    the panels), ``yoke`` (aluminium). The arrays rotate about y: ``array_normal`` (projected
    perpendicular to y) is the normal of the cell side. The default is about 15.5 m tip to
    tip. With ``subdivisions = n`` every rectangle is cut into ``n × n`` cells
    (``44 n²`` triangles; n = 7 gives 2156).

    The inertia is given, assembled from a uniform solid bus of ``bus_mass`` kg, panels of
    ``array_areal_density`` kg/m² and solid yokes of ``yoke_mass`` kg each.
    """
    _positive(
        bus_size=np.asarray(bus_size, float),
        wing_length=wing_length,
        wing_width=wing_width,
        yoke_length=yoke_length,
        yoke_width=yoke_width,
    )
    e_y = np.array([0.0, 1.0, 0.0])
    normal = np.asarray(array_normal, float)
    normal = normal - (normal @ e_y) * e_y
    if not np.linalg.norm(normal) > 1e-9:
        raise ShapeError(f"array_normal {list(array_normal)} must not be parallel to y")
    normal /= np.linalg.norm(normal)
    e_v = np.cross(normal, e_y)
    n = subdivisions
    half_bus = 0.5 * bus_size[1]
    parts: list[tuple[str, Part]] = [("bus", _box_part(bus_size, (0.0, 0.0, 0.0), n))]
    yoke_size = (yoke_width, yoke_length, yoke_width)
    wing_parts = []
    for sign in (1.0, -1.0):
        yoke_center = (0.0, sign * (half_bus + 0.5 * yoke_length), 0.0)
        parts.append(("yoke", _box_part(yoke_size, yoke_center, n)))
        center = np.array([0.0, sign * (half_bus + yoke_length + 0.5 * wing_length), 0.0])
        front = _sheet(center, e_y, e_v, (wing_length, wing_width), n)
        parts.append(("solar_array", front))
        parts.append(("array_back", (front[0].copy(), front[1][:, ::-1])))
        wing_parts.append(front)
    groups = {"bus": MLI, "solar_array": SOLAR_CELL, "array_back": ARRAY_BACK, "yoke": ALUMINIUM}
    vertices, faces, index = _assemble(parts, list(groups))

    def solid(part: Part, kg: float) -> mass_props.MassProperties:
        props = mass_props.solid_properties(part[0][part[1]])
        scale = kg / props.mass
        return mass_props.MassProperties(kg, props.center_of_mass, props.inertia * scale, 0.0)

    assembly = mass_props.combine(
        [solid(parts[0][1], bus_mass)]
        + [solid(p, yoke_mass) for g, p in parts if g == "yoke"]
        + [mass_props.shell_properties(p[0][p[1]], array_areal_density) for p in wing_parts]
    )
    return _model(
        (vertices, faces),
        groups,
        materials,
        name,
        {
            "source": "shapes.primitives.box_wing",
            "array_normal": normal.tolist(),
            "span_m": float(bus_size[1] + 2 * (yoke_length + wing_length)),
        },
        group_index=index,
        inertia=assembly.inertia,
        mass=assembly.mass,
        center_of_mass=assembly.center_of_mass,
    )


def icosphere(
    radius: float = 1.0,
    subdivisions: int = 4,
    *,
    materials: Materials = None,
    name: str = "icosphere",
) -> FacetModel:
    """Geodesic sphere: icosahedron split ``subdivisions`` times (``20·4^s`` facets).

    Vertices lie on the sphere of ``radius`` m; s = 4 gives 5120 facets. One group
    ``surface`` (default Lommel–Seeliger regolith).
    """
    return ellipsoid((radius, radius, radius), subdivisions, materials=materials, name=name)


def ellipsoid(
    radii: Sequence[float] = (1.0, 0.8, 0.6),
    subdivisions: int = 4,
    *,
    materials: Materials = None,
    name: str = "ellipsoid",
) -> FacetModel:
    """Triaxial ellipsoid: a scaled icosphere (``20·4^s`` facets), group ``surface``."""
    radii = np.asarray(radii, float)
    _positive(radii=radii)
    if int(subdivisions) != subdivisions or not 0 <= subdivisions <= 7:
        raise ShapeError(f"subdivisions must be an integer in 0..7, got {subdivisions!r}")
    mesh = trimesh.creation.icosphere(subdivisions=int(subdivisions))
    return _model(
        (np.asarray(mesh.vertices) * radii, mesh.faces),
        {"surface": REGOLITH},
        materials,
        name,
        {"source": f"shapes.primitives.ellipsoid({radii.tolist()}, {int(subdivisions)})"},
    )
