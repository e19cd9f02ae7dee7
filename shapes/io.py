"""Reading and writing facet models: trimesh formats, the DAMIT shape format, grouped OBJ.

:func:`load` picks a reader of :data:`READERS` (astropy-style registry) by file extension
(:data:`EXTENSIONS`; anything else goes to trimesh):

- OBJ, PLY, STL, OFF, GLB/GLTF, … through trimesh. OBJ groups (``g``) and objects (``o``)
  become facet groups, split further by ``usemtl`` material where a group uses several; files
  without groups are grouped by material. GLB/GLTF scenes give one group per node, with the
  node transforms applied. Diffuse colours (MTL ``Kd``, glTF base colour) become Lambert
  materials with ``rd`` = mean diffuse reflectance; give ``materials=`` to override.
  Triangle soups (STL) are welded at coincident vertices; indexed meshes keep their
  connectivity as authored.
- DAMIT shape files (``.txt``, ``.damit``, ``.shape``): first line ``nv nf``, then ``nv``
  vertex lines ``x y z`` and ``nf`` facet lines of 1-based vertex indices (Ďurech et al.,
  DAMIT database format).

Coordinates are converted to metres from the declared ``unit`` ("m" or "km").
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from shapes.errors import ShapeError
from shapes.files import atomic_write
from shapes.material import Material
from shapes.model import FacetModel
from shapes.validation import DEFAULT_MAX_FACETS, UNIT_SCALE, check_unit, validate

if TYPE_CHECKING:  # trimesh (about a second to import) is loaded where it is used
    import trimesh

__all__ = ["EXTENSIONS", "READERS", "load", "load_damit", "read_damit", "read_trimesh", "write_obj"]

# A reader returns (vertices in file units, faces, group_index, group_names, materials).
MeshParts = tuple[np.ndarray, np.ndarray, np.ndarray, list[str], dict[str, Material]]


def read_damit(path: str | os.PathLike[str]) -> MeshParts:
    """Read a DAMIT shape file (``nv nf`` header, vertices, 1-based facets)."""
    path = Path(path)
    try:
        lines = [line.split() for line in path.read_text().splitlines() if line.strip()]
    except UnicodeDecodeError:
        raise ShapeError(f"{path}: not a text file (DAMIT shape format expected)") from None
    try:
        nv, nf = (int(x) for x in lines[0])
    except (IndexError, ValueError):
        raise ShapeError(
            f"{path}: line 1: expected 'vertex_count facet_count' (DAMIT shape format)"
        ) from None
    if len(lines) < 1 + nv + nf:
        raise ShapeError(
            f"{path}: header announces {nv} vertices and {nf} facets but the file has "
            f"only {len(lines) - 1} data lines"
        )
    rows = []
    for number, fields in enumerate(lines[1 : 1 + nv + nf], start=2):
        expected = float if number <= nv + 1 else int
        try:
            if len(fields) != 3:
                raise ValueError
            rows.append([expected(x) for x in fields])
        except ValueError:
            kind = "vertex 'x y z'" if expected is float else "facet 'i j k'"
            raise ShapeError(f"{path}: line {number}: expected a {kind}, got {fields}") from None
    faces = np.asarray(rows[nv:], dtype=np.int64) - 1
    return (
        np.asarray(rows[:nv], dtype=float),
        faces,
        np.zeros(nf, dtype=np.int64),
        ["body"],
        {},
    )


def _material_from_visual(geometry: trimesh.Trimesh) -> Material | None:
    """A Lambert material from a trimesh visual's diffuse / base colour, if any."""
    material = getattr(geometry.visual, "material", None)
    if material is None:
        return None
    colour = getattr(material, "diffuse", None)
    if colour is None:
        colour = getattr(material, "baseColorFactor", None)
    if colour is None:
        return None
    rgb = np.asarray(colour, float).reshape(-1)[:3]
    rd = float(np.clip(rgb.mean() / (255.0 if rgb.max() > 1.0 else 1.0), 0.0, 1.0))
    return Material("lambert", {"rd": rd}, name=getattr(material, "name", None))


def _group_name(key: str, geometry: trimesh.Trimesh, path: Path, keys: list[str]) -> str:
    """Readable group name: strip trimesh's ``_<material>`` suffix when unambiguous."""
    material = getattr(getattr(geometry.visual, "material", None), "name", None)
    if key == path.name:
        return material or "body"
    if material and key.endswith(f"_{material}"):
        stem = key[: -len(material) - 1]
        if sum(k.startswith(f"{stem}_") for k in keys) == 1 and stem not in keys:
            return stem
    return key


def read_trimesh(path: str | os.PathLike[str]) -> MeshParts:
    """Read any mesh trimesh loads, one group per OBJ group/object/material or scene node."""
    import trimesh

    path = Path(path)
    try:
        scene = trimesh.load(
            path,
            force="scene",
            process=False,
            maintain_order=True,
            split_objects=True,
            split_groups=True,
            group_material=True,
        )
    except Exception as exc:  # trimesh raises many kinds on malformed input
        raise ShapeError(f"{path}: cannot read mesh ({type(exc).__name__}: {exc})") from None
    meshes = []  # (node name, geometry, transform), by node name: trimesh's scene order
    for node in sorted(scene.graph.nodes_geometry):  # is not the file's; sorting makes it stable
        transform, geom = scene.graph[node]
        geometry = scene.geometry.get(geom)
        if isinstance(geometry, trimesh.Trimesh) and len(geometry.faces):
            meshes.append((node, geometry, transform))
    if not meshes:
        raise ShapeError(f"{path}: no triangle mesh found")
    keys = [name for name, _, _ in meshes]
    shared = all(
        np.array_equal(g.vertices, meshes[0][1].vertices) and np.allclose(t, np.eye(4))
        for _, g, t in meshes
    )
    vertices, faces, group_index, names, materials = [], [], [], [], {}
    offset = 0
    for k, (key, geometry, transform) in enumerate(meshes):
        name = _group_name(key, geometry, path, keys)
        if name in names:
            name = f"{name}_{k}"
        names.append(name)
        material = _material_from_visual(geometry)
        if material is not None:
            materials[name] = material
        if shared:  # OBJ: every group indexes the file's one vertex list
            faces.append(np.asarray(geometry.faces))
        else:
            v, f = _weld_if_soup(np.asarray(geometry.vertices), np.asarray(geometry.faces))
            vertices.append(trimesh.transform_points(v, transform))
            faces.append(f + offset)
            offset += len(v)
        group_index.append(np.full(len(faces[-1]), k))
    if shared:
        all_vertices, all_faces = _weld_if_soup(
            np.asarray(meshes[0][1].vertices), np.concatenate(faces)
        )
    else:
        all_vertices, all_faces = np.concatenate(vertices), np.concatenate(faces)
    return all_vertices, all_faces, np.concatenate(group_index), names, materials


def _weld_if_soup(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Merge coincident vertices of a triangle soup (each vertex used by one facet, as in STL).

    Indexed meshes are kept as authored: their connectivity is data (two-sided sheets share
    positions but not vertices).
    """
    uses = np.bincount(faces.ravel(), minlength=len(vertices))
    if len(faces) < 2 or uses.max() > 1:
        return vertices, faces
    import trimesh

    mesh = trimesh.Trimesh(vertices, faces, process=False)
    mesh.merge_vertices(merge_tex=True, merge_norm=True)
    return np.asarray(mesh.vertices), np.asarray(mesh.faces)


#: Reader of each format name.
READERS: dict[str, Callable[[str | os.PathLike[str]], MeshParts]] = {
    "damit": read_damit,
    "trimesh": read_trimesh,
}
#: Format of file extensions (lower case) that are not trimesh's.
EXTENSIONS = {".txt": "damit", ".damit": "damit", ".shape": "damit"}


def load(
    path: str | os.PathLike[str],
    *,
    unit: str = "m",
    name: str | None = None,
    materials: Material | Mapping[str, Material] | None = None,
    inertia: Any = "auto",
    mass: float | None = None,
    center_of_mass: Any = None,
    provenance: Mapping[str, Any] | None = None,
    file_format: str | None = None,
    check: bool = True,
    max_facets: int = DEFAULT_MAX_FACETS,
) -> FacetModel:
    """Load a facet model from a mesh file.

    Parameters
    ----------
    path : path-like
        OBJ/PLY/STL/GLB/GLTF/OFF (trimesh) or DAMIT shape file.
    unit : {"m", "km"}
        Unit of the file's coordinates.
    name : str, optional
        Model name (default: the file stem).
    materials : Material or mapping group → Material, optional
        Override the file's materials (one Material: every group).
    inertia, mass, center_of_mass :
        See :class:`~shapes.model.FacetModel` (SI).
    provenance : mapping, optional
        Extra provenance; ``file`` and ``unit`` are recorded.
    file_format : {"trimesh", "damit"}, optional
        Reader (default: from the extension, see :data:`EXTENSIONS`).
    check : bool
        Run :func:`~shapes.validation.validate` (errors name the file).
    max_facets : int
        Facet limit of the validation.

    Raises
    ------
    ShapeError
        Unreadable or invalid mesh (the message names the file), unknown unit or format.
    """
    path = Path(path)
    check_unit(unit)
    if not path.is_file():
        raise ShapeError(f"{path}: no such mesh file")
    file_format = file_format or EXTENSIONS.get(path.suffix.lower(), "trimesh")
    if file_format not in READERS:
        raise ShapeError(f"unknown mesh format {file_format!r}; use one of {', '.join(READERS)}")
    vertices, faces, group_index, group_names, file_materials = READERS[file_format](path)
    chosen: Any = (
        materials
        if isinstance(materials, Material)
        else {**file_materials, **dict(materials or {})}
    )
    try:
        model = FacetModel(
            vertices * UNIT_SCALE[unit],
            faces,
            group_index=group_index,
            group_names=group_names,
            materials=chosen,
            unit=unit,
            name=name or path.stem,
            provenance={"file": path.name, "unit": unit, **dict(provenance or {})},
            inertia=inertia,
            mass=mass,
            center_of_mass=center_of_mass,
        )
        if check:
            validate(model, max_facets=max_facets)
    except ShapeError as exc:
        raise ShapeError(f"{path}: {exc}") from None
    return model


def load_damit(path: str | os.PathLike[str], **options: Any) -> FacetModel:
    """Load a DAMIT shape file whatever its extension (options as :func:`load`)."""
    return load(path, file_format="damit", **options)


def write_obj(
    model: FacetModel,
    path: str | os.PathLike[str],
    unit: str | None = None,
    *,
    comments: Sequence[str] = (),
) -> None:
    """Write a model as a grouped OBJ (``g <group>`` blocks), atomically.

    Parameters
    ----------
    model : FacetModel
    path : path-like
        Destination; written to a temporary file in the same folder, then renamed.
    unit : {"m", "km"}, optional
        Unit of the written coordinates (default: the model's source unit).
    comments : sequence of str
        Lines written as ``# …`` comments after the header line.

    Notes
    -----
    Vertex order is kept and coordinates are written with 17 significant digits, so loading
    the file back gives the same facets (up to the unit conversion's rounding). Materials
    are not written (the shape library keeps them in its manifest).
    """
    unit = check_unit(unit or model.unit)
    path = Path(path)
    coords = model.vertices / UNIT_SCALE[unit]
    lines = [f"# {model.name}: {len(model.faces)} facets, unit {unit}, written by shapes"]
    lines += [f"# {line}" for line in comments]
    lines += [f"v {x!r} {y!r} {z!r}" for x, y, z in coords.tolist()]
    for k, group in enumerate(model.group_names):
        lines.append(f"g {group}")
        lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in model.faces[model.group_index == k]]
    with atomic_write(path) as handle:
        handle.write("\n".join(lines) + "\n")
