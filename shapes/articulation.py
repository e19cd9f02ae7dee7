"""Articulated shapes: named rigid parts on one-axis joints.

A part is a set of mesh groups of a :class:`~shapes.model.FacetModel` that turns rigidly
about one axis of the body frame through a pivot point. The mesh stores every part at
joint angle 0; at angle θ a part point ``x`` sits at ``R(θ)(x − p) + p`` in the body frame
(``R`` the right-handed rotation by θ about the unit axis ``a``, ``p`` the pivot), and a
direction ``d`` of the body frame reads ``R(θ)ᵀ d`` in the part frame. Groups that no part
names move with the body.

Joint kinds
-----------
``fixed``
    Always at angle 0 (the part is rigid with the body; kept as a named part for the
    record and for ``joint_<part>_deg`` output).
``sun_tracking``
    The part turns to bring its ``normal`` (a part-frame direction ⊥ axis at angle 0, e.g.
    the cell side of a solar array) as close to the Sun as the angle limits allow. With
    ``s`` the body-frame Sun direction, ``n₀`` the normal and ``a`` the axis, the ideal angle
    is ``θ* = atan2((a × n₀)·s, n₀·s)`` (``R(θ) n₀ = cos θ n₀ + sin θ a × n₀``); the
    commanded angle ``θ* + offset`` is wrapped into the 360° window centred on the limits
    and clipped to them, so the drive stops at the nearer limit when the Sun leaves its
    range. The angle depends on the body-frame Sun direction alone, so any attitude source
    (torque-free, profiles, measured) drives it alike.
``scheduled``
    The angle (degrees) is read per epoch from a named ``column`` of the observation file,
    plus ``offset_deg``; an angle outside the limits is an error naming the column and row.

Manifest form (one list entry per part)::

    {"name": "arrays", "groups": ["solar_array", "array_back"],
     "joint": {"kind": "sun_tracking", "axis": [0, 1, 0], "pivot": [0, 0, 0],
               "normal": [1, 0, 0], "limits_deg": [-180, 180], "offset_deg": 0}}
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from shapes.errors import ShapeError
from shapes.model import FacetModel

__all__ = [
    "JOINT_KINDS",
    "ArticulatedModel",
    "Articulation",
    "Joint",
    "Part",
    "axis_rotation",
]

JOINT_KINDS = ("fixed", "sun_tracking", "scheduled")
_JOINT_KEYS = {
    "fixed": {"kind"},
    "sun_tracking": {"kind", "axis", "pivot", "normal", "limits_deg", "offset_deg"},
    "scheduled": {"kind", "axis", "pivot", "column", "limits_deg", "offset_deg"},
}
_PART_KEYS = {"name", "groups", "joint"}


def axis_rotation(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rotation matrices by ``angle`` (rad, right-handed) about a unit ``axis`` (Rodrigues).

    Parameters
    ----------
    axis : (3,) float
        Unit vector.
    angle : (...) float
        rad.

    Returns
    -------
    (..., 3, 3) float
        ``R = cos θ I + sin θ [a]ₓ + (1 − cos θ) a aᵀ``.
    """
    a = np.asarray(axis, float)
    theta = np.asarray(angle, float)
    cross = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    c, s = np.cos(theta)[..., None, None], np.sin(theta)[..., None, None]
    return c * np.eye(3) + s * cross + (1.0 - c) * np.outer(a, a)


def _vector(value: Any, what: str, where: str) -> np.ndarray:
    try:
        vector = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        vector = np.zeros(0)
    if vector.shape != (3,) or not np.all(np.isfinite(vector)):
        raise ShapeError(f"{where}: joint {what} must be 3 finite numbers, got {value!r}")
    return vector


def _unit(value: Any, what: str, where: str) -> np.ndarray:
    vector = _vector(value, what, where)
    norm = float(np.linalg.norm(vector))
    if not norm > 1e-12:
        raise ShapeError(f"{where}: joint {what} {vector.tolist()} has zero length")
    return vector / norm


@dataclass(frozen=True, eq=False)
class Joint:
    """A one-axis joint (see the module docstring).

    Attributes
    ----------
    kind : {"fixed", "sun_tracking", "scheduled"}
    axis : (3,) float
        Unit rotation axis, body frame.
    pivot : (3,) float
        A point of the axis, m, body frame.
    limits_deg : (float, float)
        Lowest and highest angle, degrees (span ≤ 360).
    offset_deg : float
        Added to the tracking or scheduled angle, degrees.
    normal : (3,) float or None
        ``sun_tracking``: unit part normal at angle 0, orthogonal to the axis.
    column : str or None
        ``scheduled``: observation-file column of the angle, degrees.
    """

    kind: str
    axis: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    pivot: np.ndarray = field(default_factory=lambda: np.zeros(3))
    limits_deg: tuple[float, float] = (-180.0, 180.0)
    offset_deg: float = 0.0
    normal: np.ndarray | None = None
    column: str | None = None

    @classmethod
    def from_dict(cls, spec: Any, where: str) -> Joint:
        """Parse and validate a manifest joint (:class:`ShapeError` naming ``where``)."""
        if not isinstance(spec, Mapping):
            raise ShapeError(f"{where}: joint must be an object, got {spec!r}")
        kind = spec.get("kind")
        if kind not in JOINT_KINDS:
            raise ShapeError(
                f"{where}: unknown joint kind {kind!r} (expected {', '.join(JOINT_KINDS)})"
            )
        unknown = set(spec) - _JOINT_KEYS[kind]
        if unknown:
            raise ShapeError(
                f"{where}: unknown field(s) {', '.join(sorted(unknown))} of a {kind} joint "
                f"(allowed: {', '.join(sorted(_JOINT_KEYS[kind]))})"
            )
        if kind == "fixed":
            return cls("fixed")
        axis = _unit(spec.get("axis"), "axis", where)
        pivot = _vector(spec.get("pivot", [0.0, 0.0, 0.0]), "pivot", where)
        limits = spec.get("limits_deg", [-180.0, 180.0])
        try:
            low, high = (float(v) for v in limits)
        except (TypeError, ValueError):
            raise ShapeError(
                f"{where}: joint limits_deg must be two numbers [low, high], got {limits!r}"
            ) from None
        if not (math.isfinite(low) and math.isfinite(high) and low <= high <= low + 360.0):
            raise ShapeError(
                f"{where}: joint limits_deg {[low, high]} must be finite with "
                "low ≤ high ≤ low + 360"
            )
        try:
            offset = float(spec.get("offset_deg", 0.0))
        except (TypeError, ValueError):
            offset = math.nan
        if not math.isfinite(offset):
            raise ShapeError(f"{where}: joint offset_deg must be a finite number of degrees")
        normal = column = None
        if kind == "sun_tracking":
            normal = _unit(spec.get("normal"), "normal", where)
            normal = normal - (normal @ axis) * axis
            if not np.linalg.norm(normal) > 1e-6:
                raise ShapeError(f"{where}: joint normal must not be parallel to the axis")
            normal /= np.linalg.norm(normal)
        else:
            column = spec.get("column")
            if not isinstance(column, str) or not column:
                raise ShapeError(f"{where}: a scheduled joint needs a column name, got {column!r}")
        return cls(kind, axis, pivot, (low, high), offset, normal, column)

    def to_dict(self) -> dict[str, Any]:
        """The manifest form."""
        if self.kind == "fixed":
            return {"kind": "fixed"}
        spec: dict[str, Any] = {
            "kind": self.kind,
            "axis": self.axis.tolist(),
            "pivot": self.pivot.tolist(),
            "limits_deg": list(self.limits_deg),
            "offset_deg": self.offset_deg,
        }
        if self.normal is not None:
            spec["normal"] = self.normal.tolist()
        if self.column is not None:
            spec["column"] = self.column
        return spec

    def clip(self, angle_deg: np.ndarray) -> np.ndarray:
        """Angles wrapped into the 360° window centred on the limits, then clipped to them."""
        low, high = self.limits_deg
        centre = 0.5 * (low + high)
        wrapped = (np.asarray(angle_deg, float) - centre + 180.0) % 360.0 - 180.0 + centre
        return np.clip(wrapped, low, high)

    def angles(
        self, sun_body: np.ndarray, columns: Mapping[str, Any] | None, where: str
    ) -> np.ndarray:
        """Joint angles, degrees, shape ``sun_body.shape[:-1]``.

        Parameters
        ----------
        sun_body : (..., 3) float
            Object → Sun directions in the body frame (any length).
        columns : mapping of str to (...) arrays, optional
            Observation-file columns (``scheduled`` joints).
        where : str
            Context of error messages.
        """
        shape = np.shape(sun_body)[:-1]
        if self.kind == "fixed":
            return np.zeros(shape)
        if self.kind == "sun_tracking":
            s = np.asarray(sun_body, float)
            ideal = np.degrees(np.arctan2(s @ np.cross(self.axis, self.normal), s @ self.normal))
            if self.offset_deg == 0.0 and self.limits_deg == (-180.0, 180.0):
                return ideal  # already in (−180°, 180°]: wrapping and clipping change nothing
            return self.clip(ideal + self.offset_deg)
        if columns is None or self.column not in columns:
            raise ShapeError(
                f"{where}: scheduled joint needs column {self.column!r} in the observation file"
            )
        angle = np.asarray(columns[self.column], float) + self.offset_deg
        low, high = self.limits_deg
        bad = ~((angle >= low - 1e-9) & (angle <= high + 1e-9))
        if np.any(bad):
            row = int(np.flatnonzero(bad.ravel())[0])
            raise ShapeError(
                f"{where}: column {self.column!r}, row {row + 1}: angle "
                f"{angle.ravel()[row]:g} deg (offset included) is outside the joint limits "
                f"[{low:g}, {high:g}] deg"
            )
        return np.broadcast_to(angle, shape) if angle.shape != shape else angle


@dataclass(frozen=True, eq=False)
class Part:
    """A named rigid part: mesh groups on a joint."""

    name: str
    groups: tuple[str, ...]
    joint: Joint

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "groups": list(self.groups), "joint": self.joint.to_dict()}


@dataclass(frozen=True, eq=False)
class Articulation:
    """The parts of an articulated shape (validated against its mesh groups)."""

    parts: tuple[Part, ...]

    @classmethod
    def from_list(cls, spec: Any, group_names: Sequence[str], where: str) -> Articulation:
        """Parse the manifest ``parts`` list; :class:`ShapeError` (one line) on bad input.

        Parameters
        ----------
        spec : list of dict or Articulation
            The ``parts`` entries (module docstring), or an articulation to check against
            ``group_names``.
        group_names : sequence of str
            Groups of the mesh.
        where : str
            Context of error messages (file and shape).
        """
        if isinstance(spec, Articulation):
            spec = spec.to_list()
        if not isinstance(spec, Sequence) or isinstance(spec, str) or not spec:
            raise ShapeError(f"{where}: parts must be a non-empty list, got {spec!r}")
        parts: list[Part] = []
        owner: dict[str, str] = {}
        for index, item in enumerate(spec):
            if not isinstance(item, Mapping):
                raise ShapeError(f"{where}: part {index + 1} must be an object, got {item!r}")
            name = item.get("name")
            if not isinstance(name, str) or not name:
                raise ShapeError(f"{where}: part {index + 1} needs a non-empty name")
            here = f"{where}, part {name!r}"
            unknown = set(item) - _PART_KEYS
            if unknown:
                raise ShapeError(
                    f"{here}: unknown field(s) {', '.join(sorted(unknown))} "
                    f"(allowed: {', '.join(sorted(_PART_KEYS))})"
                )
            if any(p.name == name for p in parts):
                raise ShapeError(f"{here}: part name used twice")
            groups = item.get("groups")
            if isinstance(groups, str):
                groups = [groups]
            if not isinstance(groups, Sequence) or not groups:
                raise ShapeError(f"{here}: groups must be a non-empty list of mesh groups")
            for group in groups:
                if group not in group_names:
                    raise ShapeError(
                        f"{here}: names group {group!r}, which the mesh does not have "
                        f"(groups: {', '.join(group_names)})"
                    )
                if group in owner:
                    raise ShapeError(f"{here}: group {group!r} already belongs to {owner[group]!r}")
                owner[group] = name
            joint = Joint.from_dict(item.get("joint"), here)
            parts.append(Part(name, tuple(groups), joint))
        return cls(tuple(parts))

    def to_list(self) -> list[dict[str, Any]]:
        """The manifest form."""
        return [p.to_dict() for p in self.parts]

    @property
    def names(self) -> list[str]:
        return [p.name for p in self.parts]

    @property
    def moving(self) -> list[Part]:
        """Parts whose joint is not ``fixed`` (the ones that turn)."""
        return [p for p in self.parts if p.joint.kind != "fixed"]

    def joint_angles(
        self, sun_body: np.ndarray, columns: Mapping[str, Any] | None = None
    ) -> np.ndarray:
        """Angle of every part's joint, degrees, shape ``(n_parts, *sun_body.shape[:-1])``."""
        return np.stack([p.joint.angles(sun_body, columns, f"part {p.name!r}") for p in self.parts])

    def part_rotations(
        self, sun_body: np.ndarray, columns: Mapping[str, Any] | None = None
    ) -> np.ndarray:
        """Part → body rotation of every part, shape ``(n_parts, *sun_body.shape[:-1], 3, 3)``.

        Parameters
        ----------
        sun_body : (..., 3) float
            Object → Sun directions in the body frame, one per epoch.
        columns : mapping of str to arrays, optional
            Observation-file columns for ``scheduled`` joints.
        """
        angles = np.radians(self.joint_angles(sun_body, columns))
        return np.stack(
            [axis_rotation(p.joint.axis, a) for p, a in zip(self.parts, angles, strict=True)]
        )


class ArticulatedModel:
    """A facet model with articulated parts.

    Parameters
    ----------
    model : FacetModel
        The whole shape with every joint at angle 0.
    articulation : Articulation
        Its parts (validated against ``model.group_names``).

    Attributes
    ----------
    name, inertia, unit :
        Those of ``model`` (the inertia is that of the stored pose).
    """

    def __init__(self, model: FacetModel, articulation: Articulation) -> None:
        for part in articulation.parts:
            missing = set(part.groups) - set(model.group_names)
            if missing:
                raise ShapeError(
                    f"{model.name}: part {part.name!r} names missing group(s) "
                    f"{', '.join(sorted(missing))}"
                )
        self.model = model
        self.articulation = articulation

    def __repr__(self) -> str:
        return f"ArticulatedModel({self.model!r}, parts={self.articulation.names})"

    @property
    def name(self) -> str:
        return self.model.name

    @property
    def inertia(self) -> np.ndarray:
        return self.model.inertia

    @property
    def materials(self) -> dict[str, Any]:
        """Material of every mesh group (those of ``model``)."""
        return self.model.materials

    def replace(self, **changes: Any) -> ArticulatedModel:
        """A copy whose rigid model has ``changes`` (:meth:`FacetModel.replace
        <shapes.model.FacetModel.replace>`, e.g. ``materials``), with the same parts."""
        return ArticulatedModel(self.model.replace(**changes), self.articulation)

    def with_joint_offsets(self, offsets_deg: Mapping[str, float]) -> ArticulatedModel:
        """A copy whose named parts' joints have the offsets ``offsets_deg`` (part name →
        degrees, replacing the stored ones)."""
        unknown = set(offsets_deg) - set(self.articulation.names)
        if unknown:
            raise ShapeError(
                f"{self.name}: no part(s) {', '.join(sorted(unknown))} "
                f"(parts: {', '.join(self.articulation.names)})"
            )
        parts = tuple(
            replace(p, joint=replace(p.joint, offset_deg=float(offsets_deg[p.name])))
            if p.name in offsets_deg
            else p
            for p in self.articulation.parts
        )
        return ArticulatedModel(self.model, Articulation(parts))

    def facet_part(self) -> np.ndarray:
        """(F,) int: the moving part (index in :attr:`Articulation.moving`) of every facet,
        −1 for facets rigid with the body (unnamed groups and ``fixed`` parts)."""
        owner = np.full(len(self.model.group_names), -1)
        for index, part in enumerate(self.articulation.moving):
            for group in part.groups:
                owner[self.model.group_names.index(group)] = index
        return owner[self.model.group_index]

    def rigid_groups(self) -> list[FacetModel]:
        """Sub-models that move as one: the body (if any facet stays with it), then every
        moving part, each in its own part frame at angle 0 (the mesh coordinates)."""
        facet_part = self.facet_part()
        models = []
        for index in range(-1, len(self.articulation.moving)):
            rows = np.flatnonzero(facet_part == index)
            if index == -1 and len(rows) == 0:
                continue
            label = "body" if index == -1 else self.articulation.moving[index].name
            models.append(self.submodel(rows, f"{self.name}:{label}"))
        return models

    def submodel(self, rows: np.ndarray, name: str) -> FacetModel:
        """The facets ``rows`` (with their groups and materials) as a model of their own."""
        m = self.model
        used, index = np.unique(m.group_index[rows], return_inverse=True)
        groups = [m.group_names[k] for k in used]
        vertex_ids, faces = np.unique(m.faces[rows], return_inverse=True)
        return FacetModel(
            m.vertices[vertex_ids],
            faces.reshape(-1, 3),
            group_index=index.reshape(-1),
            group_names=groups,
            materials={g: m.materials[g] for g in groups},
            unit="m",
            name=name,
            inertia="shell",
        )

    def posed(self, rotations: np.ndarray) -> FacetModel:
        """The whole shape with its moving parts turned, as one rigid model.

        Parameters
        ----------
        rotations : (n_moving, 3, 3) float
            Part → body rotation of each moving part (rows of :meth:`part_rotations` for the
            moving parts, one epoch).
        """
        vertices = self.model.vertices.copy()
        facet_part = self.facet_part()
        for index, part in enumerate(self.articulation.moving):
            ids = np.unique(self.model.faces[facet_part == index])
            pivot = part.joint.pivot
            vertices[ids] = (self.model.vertices[ids] - pivot) @ rotations[index].T + pivot
        return self.model.replace(vertices=vertices, visibility=None)

    def moving_rotations(
        self, sun_body: np.ndarray, columns: Mapping[str, Any] | None = None
    ) -> np.ndarray:
        """Part → body rotations of the moving parts, ``(n_moving, *sun_body.shape[:-1], 3, 3)``."""
        moving = Articulation(tuple(self.articulation.moving))
        if not moving.parts:
            return np.zeros((0, *np.shape(sun_body)[:-1], 3, 3))
        return moving.part_rotations(sun_body, columns)
