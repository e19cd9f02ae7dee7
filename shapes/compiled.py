"""The compiled (render-ready) form of a facet model: coplanar facets merged by material.

For an unshadowed facet the reflected flux depends on the facet only through its normal,
area and material (docs/rendering.md, the measurement model), so facets with the same
normal and the same material add up exactly into one effective facet, wherever they sit:
``Σ_i ρ(n, L, V) A_i (n·L)(n·V) = ρ(n, L, V) (Σ_i A_i) (n·L)(n·V)``. A CAD box-wing of
thousands of triangles compiles to a dozen or two facets. For shadowed facets the visible
fraction of the merged facet is the area-weighted mean of its members' fractions, which is
what :mod:`shapes.visibility` computes.
"""

from __future__ import annotations

import dataclasses
import hashlib
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from shapes.material import Material
from shapes.protocols import FacetVisibility

__all__ = ["DEFAULT_ANGLE_TOLERANCE", "CompiledFacets", "compile_facets", "facet_tangents"]

#: Normals closer than this angle (rad) count as identical when merging.
DEFAULT_ANGLE_TOLERANCE = 1e-6


@dataclass(frozen=True, eq=False)
class CompiledFacets:
    """Effective facets for rendering (body frame, SI).

    Attributes
    ----------
    normals : (K, 3) float
        Outward unit normals.
    areas : (K, ) float
        m² (sum of the member facets' areas).
    centroids : (K, 3) float
        Area-weighted centroid of the members, m.
    tangents : (K, 3) float
        Unit tangent ``u``: the material's reference direction projected on the facet, or
        (no reference direction, or one parallel to the normal) the projection of the body
        axis least aligned with the normal.
    material_index : (K,) int
        Row of :attr:`materials`.
    materials : list of Material
        Distinct materials.
    can_be_shadowed : (K,) bool
        False when no part of the model lies in front of any member's plane, so the facet is
        never shadowed nor occluded (every facet of a convex body).
    members : tuple of (n_k,) int arrays
        Original facets merged into each effective facet.
    facet_map : (F,) int
        Effective facet of each original facet.
    angle_tolerance : float
        Merging tolerance used, rad.
    vertices, faces : arrays
        The source mesh (m), used for ray casting.
    visibility : VisibilityTable or None
        Precomputed visible fractions, when available (non-convex models).
    """

    normals: np.ndarray
    areas: np.ndarray
    centroids: np.ndarray
    tangents: np.ndarray
    material_index: np.ndarray
    materials: list[Material]
    can_be_shadowed: np.ndarray
    members: tuple[np.ndarray, ...]
    facet_map: np.ndarray
    angle_tolerance: float
    vertices: np.ndarray
    faces: np.ndarray
    visibility: FacetVisibility | None = None

    def __len__(self) -> int:
        return len(self.areas)

    @property
    def structure(self) -> str:
        """Digest of the merge (facet count, membership, materials, tolerance).

        Depends only on integers and the tolerance, so it is stable across platforms and
        rotations of the model; visibility tables record it to check they fit.
        """
        digest = hashlib.sha256()
        digest.update(np.asarray(self.facet_map, dtype="<i8").tobytes())
        digest.update(np.asarray(self.material_index, dtype="<i8").tobytes())
        digest.update(repr(float(self.angle_tolerance)).encode())
        return digest.hexdigest()

    def with_visibility(self, table: FacetVisibility | None) -> CompiledFacets:
        """Return a copy carrying ``table`` (checked to fit these facets)."""
        if table is not None:
            table.check_fits(self)
        return dataclasses.replace(self, visibility=table)


def facet_tangents(normals: np.ndarray, references: np.ndarray) -> np.ndarray:
    """Unit tangents: reference directions projected on the facet planes.

    Parameters
    ----------
    normals : (K, 3) float
        Unit normals.
    references : (K, 3) float
        Reference directions; rows of zeros, or rows (nearly) parallel to the normal, fall
        back to the body axis least aligned with the normal.

    Returns
    -------
    (K, 3) float
        Unit vectors orthogonal to the normals.
    """
    n = np.asarray(normals, float)
    fallback = np.eye(3)[np.argmin(np.abs(n), axis=1)]
    ref = np.asarray(references, float)
    projected = ref - np.sum(ref * n, axis=1, keepdims=True) * n
    norm = np.linalg.norm(projected, axis=1, keepdims=True)
    usable = norm[:, 0] > 1e-6
    alt = fallback - np.sum(fallback * n, axis=1, keepdims=True) * n
    tangents = np.where(usable[:, None], projected, alt)
    return tangents / np.linalg.norm(tangents, axis=1, keepdims=True)


def _merge_clusters(
    normals: np.ndarray, material_of_facet: np.ndarray, angle_tolerance: float
) -> np.ndarray:
    """Cluster label of each facet: same material and normals within the tolerance.

    Normals are first snapped to 1e-9 so that exactly coplanar facets (the bulk of a CAD
    mesh) collapse to one key, then keys of one material closer than the tolerance are joined
    transitively (connected components of the neighbour graph).
    """
    keys = np.column_stack([material_of_facet.astype(float), np.round(normals, 9)])
    unique, key_of_facet = np.unique(keys, axis=0, return_inverse=True)
    key_of_facet = key_of_facet.reshape(-1)
    radius = 2.0 * np.sin(0.5 * angle_tolerance)
    pairs = cKDTree(unique[:, 1:]).query_pairs(radius, output_type="ndarray")
    if len(pairs):
        pairs = pairs[unique[pairs[:, 0], 0] == unique[pairs[:, 1], 0]]
    graph = coo_matrix(
        (np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(unique), len(unique))
    )
    _, key_label = connected_components(graph, directed=False)
    label = key_label[key_of_facet]
    # number clusters by their first facet, so the order follows the mesh
    first = np.full(label.max() + 1, len(label))
    np.minimum.at(first, label, np.arange(len(label)))
    rank = np.empty_like(first)
    rank[np.argsort(first)] = np.arange(len(first))
    return rank[label]


def compile_facets(
    vertices: np.ndarray,
    faces: np.ndarray,
    normals: np.ndarray,
    areas: np.ndarray,
    centroids: np.ndarray,
    material_of_facet: np.ndarray,
    *,
    materials: Sequence[Material],
    can_be_shadowed: np.ndarray,
    angle_tolerance: float = DEFAULT_ANGLE_TOLERANCE,
) -> CompiledFacets:
    """Merge facets with identical normal and material into effective facets.

    Parameters
    ----------
    vertices, faces : arrays
        The mesh (m).
    normals : (F, 3) float
        Outward unit normals.
    areas : (F,) float
        m².
    centroids : (F, 3) float
        m.
    material_of_facet : (F,) int
        Index into ``materials``.
    materials : sequence of Material
        Distinct materials.
    can_be_shadowed : (F,) bool
        Per original facet (see :class:`CompiledFacets`).
    angle_tolerance : float
        rad; normals closer than this merge.

    Returns
    -------
    CompiledFacets
    """
    if not angle_tolerance >= 0.0:
        raise ValueError(f"angle_tolerance must be ≥ 0 rad, got {angle_tolerance!r}")
    label = _merge_clusters(normals, material_of_facet, angle_tolerance)
    k = int(label.max()) + 1
    area = np.bincount(label, weights=areas, minlength=k)
    summed_normal = np.stack(
        [np.bincount(label, weights=areas * normals[:, c], minlength=k) for c in range(3)], 1
    )
    merged_normal = summed_normal / np.linalg.norm(summed_normal, axis=1, keepdims=True)
    centroid = (
        np.stack(
            [np.bincount(label, weights=areas * centroids[:, c], minlength=k) for c in range(3)], 1
        )
        / area[:, None]
    )
    order = np.argsort(label, kind="stable")
    members = tuple(np.split(order, np.cumsum(np.bincount(label, minlength=k))[:-1]))
    material_index = material_of_facet[[m[0] for m in members]]
    references = np.array(
        [
            materials[i].reference_direction
            if materials[i].reference_direction is not None
            else (0.0, 0.0, 0.0)
            for i in material_index
        ],
        dtype=float,
    ).reshape(-1, 3)
    shadowed = np.bincount(label, weights=can_be_shadowed.astype(float), minlength=k) > 0
    return CompiledFacets(
        normals=merged_normal,
        areas=area,
        centroids=centroid,
        tangents=facet_tangents(merged_normal, references),
        material_index=material_index,
        materials=list(materials),
        can_be_shadowed=shadowed,
        members=members,
        facet_map=label,
        angle_tolerance=float(angle_tolerance),
        vertices=vertices,
        faces=faces,
    )
