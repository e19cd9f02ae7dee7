"""The facet model: a triangle mesh with named groups, materials and mass properties.

:class:`FacetModel` is a thin, cached object over plain arrays (trimesh style). Geometry is
in metres in the model (body) frame; ``unit`` only records the unit of the source file.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping, Sequence
from functools import cached_property
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from shapes import mass, validation
from shapes.compiled import DEFAULT_ANGLE_TOLERANCE, CompiledFacets, compile_facets
from shapes.errors import ShapeError
from shapes.material import Material
from shapes.protocols import FacetVisibility

if TYPE_CHECKING:  # trimesh (about a second to import) is loaded where it is used
    import trimesh

__all__ = ["DEFAULT_MATERIAL", "FacetModel", "inertia_from_components"]

#: Material of groups that were given none.
DEFAULT_MATERIAL = Material("lambert", {"rd": 0.5}, name="default grey")
_SHADOW_TOLERANCE = 1e-7  # fraction of the bounding diagonal a vertex must stand in front


def inertia_from_components(values: Sequence[float]) -> np.ndarray:
    """Inertia tensor from ``Jxx, Jyy, Jzz[, Jxy, Jxz, Jyz]`` (kg m², tensor elements).

    The off-diagonal values are the tensor elements ``J_xy = −∫ x y dm`` (the products of
    inertia with the sign of the tensor), so ``J = [[Jxx, Jxy, Jxz], [Jxy, Jyy, Jyz],
    [Jxz, Jyz, Jzz]]``.

    Raises
    ------
    ShapeError
        Wrong count, or a tensor that is not symmetric positive definite and does not satisfy
        the triangle inequalities of a rigid body.
    """
    values = [float(v) for v in values]
    if len(values) not in (3, 6):
        raise ShapeError(f"inertia needs 3 or 6 values (Jxx,Jyy,Jzz[,Jxy,Jxz,Jyz]), got {values}")
    jxx, jyy, jzz = values[:3]
    jxy, jxz, jyz = values[3:] if len(values) == 6 else (0.0, 0.0, 0.0)
    tensor = np.array([[jxx, jxy, jxz], [jxy, jyy, jyz], [jxz, jyz, jzz]])
    _check_physical(tensor)
    return tensor


def _check_physical(tensor: np.ndarray) -> None:
    if tensor.shape != (3, 3) or not np.all(np.isfinite(tensor)):
        raise ShapeError(f"inertia must be a finite 3×3 tensor, got {tensor.tolist()}")
    if not np.allclose(tensor, tensor.T, rtol=1e-9, atol=1e-12 * np.abs(tensor).max()):
        raise ShapeError(f"inertia tensor is not symmetric: {tensor.tolist()}")
    moments = np.linalg.eigvalsh(tensor)
    if moments[0] <= 0.0:
        raise ShapeError(f"inertia tensor is not positive definite (moments {moments.tolist()})")
    if moments[2] > (moments[0] + moments[1]) * (1.0 + 1e-9):
        raise ShapeError(
            f"inertia moments {moments.tolist()} violate the triangle inequality "
            "J3 ≤ J1 + J2 of a rigid body"
        )


class FacetModel:
    """A triangular facet model with groups, materials and mass properties.

    Parameters
    ----------
    vertices : (V, 3) float
        Vertex positions in the model frame, m.
    faces : (F, 3) int
        Vertex indices of each facet, counter-clockwise seen from outside.
    group_index : (F,) int, optional
        Group of each facet (default: all in group 0).
    group_names : list of str, optional
        Name of each group (default ``["body"]``).
    materials : Material or mapping group name → Material, optional
        One material per group; groups left out get :data:`DEFAULT_MATERIAL`.
    unit : {"m", "km"}
        Unit of the source file (provenance only; ``vertices`` are always metres).
    name : str
        Model name.
    provenance : dict, optional
        Source, licence, file, ... (JSON-serialisable).
    inertia : {"auto", "solid", "shell"} or (3, 3) or 3/6 values, optional
        ``"auto"``: uniform solid when the mesh is watertight, else thin shell. A tensor
        (kg m², about the centre of mass, model frame) or ``Jxx, Jyy, Jzz[, Jxy, Jxz, Jyz]``
        is taken as given.
    mass : float, optional
        Total mass, kg; sets the density of a computed inertia (default density 1 kg/m³ for a
        solid, 1 kg/m² for a shell).
    center_of_mass : (3,) float, optional
        m; with a given inertia (default: from the geometry).
    visibility : VisibilityTable, optional
        Precomputed visibility table of the compiled facets (attached by :meth:`compiled`).

    Raises
    ------
    ShapeError
        Bad arrays (shapes, non-finite coordinates, indices out of range), unknown unit or
        group, unphysical inertia.
    """

    def __init__(
        self,
        vertices: Any,
        faces: Any,
        *,
        group_index: Any = None,
        group_names: Sequence[str] | None = None,
        materials: Material | Mapping[str, Material] | None = None,
        unit: str = "m",
        name: str = "shape",
        provenance: Mapping[str, Any] | None = None,
        inertia: Any = "auto",
        mass: float | None = None,
        center_of_mass: Any = None,
        visibility: FacetVisibility | None = None,
    ) -> None:
        self.vertices, self.faces = validation.check_arrays(vertices, faces, name)
        self.unit = validation.check_unit(unit)
        self.name = str(name)
        self.group_names = list(group_names) if group_names is not None else ["body"]
        if len(set(self.group_names)) != len(self.group_names) or not self.group_names:
            raise ShapeError(f"{name}: group names must be unique and non-empty")
        if group_index is None:
            group_index = np.zeros(len(self.faces), dtype=np.int64)
        self.group_index = np.asarray(group_index, dtype=np.int64)
        if self.group_index.shape != (len(self.faces),) or (
            len(self.faces)
            and (self.group_index.min() < 0 or self.group_index.max() >= len(self.group_names))
        ):
            raise ShapeError(
                f"{name}: group_index must hold one group number in "
                f"[0, {len(self.group_names)}) per facet"
            )
        self.materials = self._resolve_materials(materials)
        self.provenance = dict(provenance or {})
        self._inertia_option = inertia
        self._mass_option = None if mass is None else float(mass)
        self._com_option = None if center_of_mass is None else np.asarray(center_of_mass, float)
        self.visibility = visibility
        for array in (self.vertices, self.faces, self.group_index):
            array.setflags(write=False)
        self._compiled: dict[float, CompiledFacets] = {}

    def _resolve_materials(self, materials: Any) -> dict[str, Material]:
        if materials is None:
            materials = {}
        if isinstance(materials, Material):
            materials = dict.fromkeys(self.group_names, materials)
        unknown = set(materials) - set(self.group_names)
        if unknown:
            raise ShapeError(
                f"{self.name}: materials given for unknown group(s) {', '.join(sorted(unknown))}; "
                f"groups are {', '.join(self.group_names)}"
            )
        for group, material in materials.items():
            if not isinstance(material, Material):
                raise ShapeError(f"{self.name}: material of group {group!r} is not a Material")
        return {g: materials.get(g, DEFAULT_MATERIAL) for g in self.group_names}

    def replace(self, **changes: Any) -> FacetModel:
        """A new model with some constructor arguments changed."""
        args: dict[str, Any] = {
            "vertices": self.vertices,
            "faces": self.faces,
            "group_index": self.group_index,
            "group_names": self.group_names,
            "materials": self.materials,
            "unit": self.unit,
            "name": self.name,
            "provenance": self.provenance,
            "inertia": self._inertia_option,
            "mass": self._mass_option,
            "center_of_mass": self._com_option,
            "visibility": self.visibility,
        }
        args.update(changes)
        vertices, faces = args.pop("vertices"), args.pop("faces")
        return FacetModel(vertices, faces, **args)

    def __repr__(self) -> str:
        return (
            f"FacetModel({self.name!r}, {len(self.faces)} facets, "
            f"groups={self.group_names}, unit={self.unit!r})"
        )

    # ----------------------------------------------------------------- geometry
    @cached_property
    def triangles(self) -> np.ndarray:
        """(F, 3, 3) float: vertices of each facet, m."""
        return self.vertices[self.faces]

    @cached_property
    def _cross(self) -> np.ndarray:
        tri = self.triangles
        return np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])

    @cached_property
    def areas(self) -> np.ndarray:
        """(F,) float: facet areas, m²."""
        return 0.5 * np.linalg.norm(self._cross, axis=1)

    @cached_property
    def normals(self) -> np.ndarray:
        """(F, 3) float: outward unit normals (zero rows for degenerate facets)."""
        norm = np.linalg.norm(self._cross, axis=1, keepdims=True)
        return np.divide(self._cross, norm, out=np.zeros_like(self._cross), where=norm > 0)

    @cached_property
    def centroids(self) -> np.ndarray:
        """(F, 3) float: facet centroids, m."""
        return self.triangles.mean(axis=1)

    @property
    def area(self) -> float:
        """Total surface area, m²."""
        return float(self.areas.sum())

    @cached_property
    def scale(self) -> float:
        """Length of the bounding-box diagonal, m."""
        return float(np.linalg.norm(np.ptp(self.vertices, axis=0))) if len(self.vertices) else 0.0

    @cached_property
    def mesh(self) -> trimesh.Trimesh:
        """The geometry as an unprocessed :class:`trimesh.Trimesh` (same vertex/face order)."""
        import trimesh

        return trimesh.Trimesh(self.vertices, self.faces, process=False, validate=False)

    @cached_property
    def is_watertight(self) -> bool:
        """Every edge is shared by exactly two facets with consistent winding."""
        return bool(self.mesh.is_watertight and self.mesh.is_winding_consistent)

    @cached_property
    def volume(self) -> float | None:
        """Enclosed volume, m³ (None for open meshes)."""
        return float(self.mesh.volume) if self.is_watertight else None

    @cached_property
    def facet_can_be_shadowed(self) -> np.ndarray:
        """(F,) bool: some vertex lies strictly in front of the facet's plane.

        When none does, the whole model lies behind that plane and nothing can shadow or
        occlude the facet.
        """
        tol = _SHADOW_TOLERANCE * self.scale
        offsets = np.einsum("fi,fi->f", self.normals, self.centroids)
        # The highest vertex above a plane is a vertex of the convex hull: testing the hull's
        # vertices only gives the same answer (qhull drops points within ~1e-13 of the scale
        # of a hull face, far below the tolerance) for a fraction of the work.
        try:
            candidates = self.vertices[ConvexHull(self.vertices).vertices]
        except (QhullError, ValueError):  # flat or degenerate: test every vertex
            candidates = self.vertices
        height = np.empty(len(self.faces))
        step = max(1, (1 << 22) // max(len(candidates), 1))
        for start in range(0, len(self.faces), step):
            part = slice(start, start + step)
            height[part] = (self.normals[part] @ candidates.T).max(axis=1) - offsets[part]
        return height > tol

    @property
    def is_convex(self) -> bool:
        """No facet can ever be shadowed or occluded by another part of the model."""
        return not bool(self.facet_can_be_shadowed.any())

    @cached_property
    def fingerprint(self) -> str:
        """SHA-256 of the geometry, groups and materials (model identity)."""
        digest = hashlib.sha256()
        digest.update(np.ascontiguousarray(self.vertices, dtype="<f8").tobytes())
        digest.update(np.ascontiguousarray(self.faces, dtype="<i8").tobytes())
        digest.update(np.ascontiguousarray(self.group_index, dtype="<i8").tobytes())
        spec = {g: self.materials[g].to_dict() for g in self.group_names}
        digest.update(json.dumps(spec, sort_keys=True).encode())
        return digest.hexdigest()

    # ----------------------------------------------------------- mass properties
    @cached_property
    def _mass_properties(self) -> tuple[mass.MassProperties, str]:
        option = self._inertia_option
        if isinstance(option, str):
            if option not in ("auto", "solid", "shell"):
                raise ShapeError(
                    f"{self.name}: inertia must be 'auto', 'solid', 'shell' or values, "
                    f"got {option!r}"
                )
            kind = option if option != "auto" else ("solid" if self.is_watertight else "shell")
            if kind == "solid":
                validation.require_solid(self, "a solid inertia")
                props = mass.solid_properties(self.triangles)
            else:
                props = mass.shell_properties(self.triangles)
            if self._mass_option is not None:
                factor = self._mass_option / props.mass
                props = mass.MassProperties(
                    props.mass * factor, props.center_of_mass, props.inertia * factor, props.measure
                )
            return props, kind
        given = np.asarray(option, float)
        tensor = inertia_from_components(given) if given.ndim == 1 else given
        _check_physical(tensor)
        geometric = (
            mass.solid_properties(self.triangles)
            if self.is_watertight
            else mass.shell_properties(self.triangles)
        )
        com = self._com_option if self._com_option is not None else geometric.center_of_mass
        total = self._mass_option if self._mass_option is not None else float("nan")
        return mass.MassProperties(total, com, tensor, geometric.measure), "given"

    @property
    def inertia_source(self) -> str:
        """ "solid", "shell" or "given"."""
        return self._mass_properties[1]

    @property
    def mass(self) -> float:
        """kg (NaN for a given inertia without a given mass)."""
        return self._mass_properties[0].mass

    @property
    def center_of_mass(self) -> np.ndarray:
        """(3,) float, m, model frame."""
        return self._mass_properties[0].center_of_mass

    @property
    def inertia(self) -> np.ndarray:
        """(3, 3) float, kg m², about the centre of mass, model frame."""
        return self._mass_properties[0].inertia

    @cached_property
    def _principal(self) -> tuple[np.ndarray, np.ndarray]:
        return mass.principal_axes(self.inertia)

    @property
    def principal_moments(self) -> np.ndarray:
        """(3,) float: principal moments of inertia, kg m², ascending."""
        return self._principal[0]

    @property
    def principal_axes(self) -> np.ndarray:
        """(3, 3) float: columns are the principal axes in the model frame (right-handed)."""
        return self._principal[1]

    # ------------------------------------------------------------ derived models
    def to_principal_frame(self) -> FacetModel:
        """The same body with the origin at its centre of mass and principal axes as x, y, z.

        Vertices become ``v' = Pᵀ (v − c)`` with ``P`` = :attr:`principal_axes` and ``c`` the
        centre of mass; material reference directions, a given inertia and the visibility
        table are rotated alike. The rotation and offset are recorded in ``provenance``.
        """
        axes, com = self.principal_axes, self.center_of_mass
        rotation = axes.T
        materials = {
            g: m
            if m.reference_direction is None
            else Material(
                m.brdf, m.params, m.name, tuple(rotation @ np.asarray(m.reference_direction))
            )
            for g, m in self.materials.items()
        }
        provenance = dict(self.provenance)
        provenance["principal_frame"] = {
            "rotation": rotation.tolist(),
            "origin": com.tolist(),
        }
        inertia = self._inertia_option
        if not isinstance(inertia, str):
            inertia = rotation @ self.inertia @ rotation.T
        return self.replace(
            vertices=(self.vertices - com) @ axes,
            materials=materials,
            provenance=provenance,
            inertia=inertia,
            center_of_mass=None if self._com_option is None else np.zeros(3),
            visibility=None if self.visibility is None else self.visibility.rotated(rotation),
        )

    def with_materials(self, materials: Material | Mapping[str, Material]) -> FacetModel:
        """A copy with the materials of some groups (or, given one Material, all) replaced."""
        if isinstance(materials, Material):
            return self.replace(materials=materials)
        merged = dict(self.materials)
        unknown = set(materials) - set(self.group_names)
        if unknown:
            raise ShapeError(
                f"{self.name}: no group(s) {', '.join(sorted(unknown))}; "
                f"groups are {', '.join(self.group_names)}"
            )
        merged.update(materials)
        return self.replace(materials=merged)

    def with_visibility(self, table: FacetVisibility | None) -> FacetModel:
        """A copy carrying a visibility table (checked against the compiled facets)."""
        if table is not None:
            table.check_fits(self.compiled())
        return self.replace(visibility=table)

    # ------------------------------------------------------------------ compiled
    @property
    def distinct_materials(self) -> tuple[list[Material], np.ndarray]:
        """Distinct materials and the index of each group's material in that list."""
        distinct: list[Material] = []
        index = []
        for group in self.group_names:
            material = self.materials[group]
            if material not in distinct:
                distinct.append(material)
            index.append(distinct.index(material))
        return distinct, np.asarray(index, dtype=np.int64)

    def compiled(self, angle_tolerance: float = DEFAULT_ANGLE_TOLERANCE) -> CompiledFacets:
        """Effective facets for rendering (cached per tolerance); see :mod:`shapes.compiled`.

        The model's visibility table is attached when it was built for these facets.
        """
        key = float(angle_tolerance)
        if key not in self._compiled:
            validation.check_degenerate(self)
            distinct, group_material = self.distinct_materials
            compiled = compile_facets(
                self.vertices,
                self.faces,
                self.normals,
                self.areas,
                self.centroids,
                group_material[self.group_index],
                materials=distinct,
                can_be_shadowed=self.facet_can_be_shadowed,
                angle_tolerance=key,
            )
            table = self.visibility
            if table is not None and table.structure == compiled.structure:
                compiled = compiled.with_visibility(table)
            self._compiled[key] = compiled
        return self._compiled[key]
