"""Checks of facet models, each raising :class:`~shapes.errors.ShapeError` with a clear message.

:func:`validate` runs them all: facet count limit, non-finite coordinates, degenerate
(zero-area) facets, inconsistent winding, closed parts with inward normals, and (on request)
a mesh that must be watertight. The constructor of :class:`~shapes.model.FacetModel` already
enforces array shapes, finite coordinates and a known unit.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from shapes.errors import ShapeError
from shapes.protocols import FacetMesh

__all__ = [
    "DEFAULT_MAX_FACETS",
    "UNIT_SCALE",
    "check_arrays",
    "check_degenerate",
    "check_unit",
    "degenerate_facets",
    "require_solid",
    "validate",
]

#: Length of the supported source units in metres.
UNIT_SCALE = {"m": 1.0, "km": 1000.0}
#: Default facet-count limit of :func:`validate`.
DEFAULT_MAX_FACETS = 200_000
_DEGENERATE = 1e-14  # facet area below this fraction of the squared model size is degenerate


def _facet_list(indices: np.ndarray, limit: int = 5) -> str:
    shown = ", ".join(str(int(i)) for i in indices[:limit])
    return shown + (f", … ({len(indices)} in all)" if len(indices) > limit else "")


def check_unit(unit: str) -> str:
    """Return ``unit`` if it is a supported length unit ("m" or "km")."""
    if unit not in UNIT_SCALE:
        raise ShapeError(f"unknown unit {unit!r}; use one of {', '.join(UNIT_SCALE)}")
    return unit


def check_arrays(vertices: Any, faces: Any, where: str = "mesh") -> tuple[np.ndarray, np.ndarray]:
    """Vertices as (V, 3) float64 and faces as (F, 3) int64, checked.

    Raises
    ------
    ShapeError
        Wrong shapes, non-finite coordinates (naming the vertices), indices out of range.
    """
    v = np.array(vertices, dtype=np.float64)
    f = np.array(faces)
    if v.ndim != 2 or v.shape[1] != 3:
        raise ShapeError(f"{where}: vertices must be a (V, 3) array, got shape {v.shape}")
    if f.size == 0:
        raise ShapeError(f"{where}: the mesh has no facets")
    if f.ndim != 2 or f.shape[1] != 3 or not np.issubdtype(f.dtype, np.integer):
        raise ShapeError(f"{where}: faces must be a (F, 3) integer array, got {f.dtype} {f.shape}")
    bad = np.flatnonzero(~np.isfinite(v).all(axis=1))
    if len(bad):
        raise ShapeError(f"{where}: non-finite coordinates at vertex {_facet_list(bad)}")
    f = f.astype(np.int64)
    out = np.flatnonzero(((f < 0) | (f >= len(v))).any(axis=1))
    if len(out):
        raise ShapeError(
            f"{where}: facet {_facet_list(out)} refers to vertices outside 0..{len(v) - 1}"
        )
    return v, f


def degenerate_facets(areas: np.ndarray, scale: float) -> np.ndarray:
    """Mask of the (nearly) zero-area facets among ``areas`` of a model of size ``scale``
    (areas below 10⁻¹⁴ of its square)."""
    return np.asarray(areas) <= _DEGENERATE * scale**2


def check_degenerate(model: FacetMesh) -> None:
    """Raise if any facet has (nearly) zero area."""
    bad = np.flatnonzero(degenerate_facets(model.areas, model.scale))
    if len(bad):
        raise ShapeError(f"{model.name}: degenerate (zero-area) facet {_facet_list(bad)}")


def require_solid(model: FacetMesh, purpose: str = "a solid") -> None:
    """Raise unless the mesh is watertight (closed, consistently wound)."""
    if not model.is_watertight:
        _, _, counts = _undirected_edges(model.faces)
        raise ShapeError(
            f"{model.name}: {purpose} needs a watertight mesh, but "
            f"{int(np.count_nonzero(counts != 2))} edge(s) are not shared by exactly two facets"
        )


def _undirected_edges(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Directed edges (3F, 2), the undirected edge of each, and each undirected edge's use."""
    directed = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    _, inverse, counts = np.unique(
        np.sort(directed, axis=1), axis=0, return_inverse=True, return_counts=True
    )
    return directed, inverse.reshape(-1), counts


def _check_winding(model: FacetMesh) -> None:
    directed, _, _ = _undirected_edges(model.faces)
    _, inverse, counts = np.unique(directed, axis=0, return_inverse=True, return_counts=True)
    facets = np.unique(np.flatnonzero(counts[inverse.reshape(-1)] > 1) // 3)
    if len(facets):
        raise ShapeError(
            f"{model.name}: inconsistent winding: facets {_facet_list(facets)} traverse a shared "
            "edge in the same direction as a neighbour"
        )


def _check_inward(model: FacetMesh) -> None:
    """Closed connected parts must enclose positive volume (outward normals)."""
    import trimesh

    n_facets = len(model.faces)
    parts = trimesh.graph.connected_components(
        model.mesh.face_adjacency, nodes=np.arange(n_facets), min_len=1
    )
    label = np.empty(n_facets, dtype=np.int64)
    for k, part in enumerate(parts):
        label[part] = k
    _, inverse, counts = _undirected_edges(model.faces)
    edge_facet = np.repeat(np.arange(n_facets), 3)
    open_part = np.zeros(len(parts), dtype=bool)
    open_part[label[edge_facet[counts[inverse] != 2]]] = True
    tri = model.triangles
    signed = np.einsum("fi,fi->f", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])) / 6.0
    volume = np.bincount(label, weights=signed, minlength=len(parts))
    inward = np.flatnonzero(~open_part & (volume < 0))
    if len(inward):
        k = inward[0]
        groups = sorted({model.group_names[g] for g in model.group_index[parts[k]]})
        raise ShapeError(
            f"{model.name}: inward normals: the closed part of facets {_facet_list(parts[k])} "
            f"(group {', '.join(groups)}) encloses a negative volume ({volume[k]:.6g} m³); "
            "reverse its winding"
        )


def validate(
    model: FacetMesh,
    *,
    require_watertight: bool = False,
    max_facets: int = DEFAULT_MAX_FACETS,
) -> None:
    """Check a facet model; raise :class:`ShapeError` at the first problem.

    Parameters
    ----------
    model : FacetModel
    require_watertight : bool
        Also require a closed mesh (e.g. for a solid inertia).
    max_facets : int
        Largest accepted facet count.
    """
    if len(model.faces) > max_facets:
        raise ShapeError(
            f"{model.name}: {len(model.faces)} facets exceed the limit of {max_facets}"
        )
    check_arrays(model.vertices, model.faces, model.name)
    check_unit(model.unit)
    check_degenerate(model)
    _check_winding(model)
    _check_inward(model)
    if require_watertight:
        require_solid(model)
