"""The convex solid of a fitted EGI: the Minkowski polyhedron in metres, its principal frame
and its axis ratios with 1σ."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lightcurve.analysis.convex.minkowski import equivalent_ellipsoid, minkowski_polyhedron
from lightcurve.analysis.egi.fit import cluster_normals
from shapes import FacetModel

__all__ = ["ConvexSolid", "axis_ratios", "convex_solid"]

#: Normals closer than this (chord ≈ rad: 0.5°) are one facet of the polyhedron.
MERGE_RADIUS = 0.0087
#: Largest mismatch of the polyhedron's relative facet areas to the EGI's.
MINKOWSKI_TOL = 1e-8


@dataclass(frozen=True)
class ConvexSolid:
    """A convex polyhedron reconstructed from an EGI.

    Attributes
    ----------
    model : FacetModel
        In its principal frame (origin at the centroid, x, y, z the principal axes), metres.
    principal_axes : (3, 3) float
        Columns: the principal axes in the body frame of the attitudes (``v_principal =
        Pᵀ (v_body − c)``).
    centroid : (3,) float
        ``c``, body frame, m.
    n_facets : int
        Planar facets (grid normals with a facet of the polyhedron).
    axis_ratios : (2,) float
        ``a/b`` and ``b/c`` of the equivalent ellipsoid's semi-axes ``a ≥ b ≥ c``.
    axis_ratio_sigma : (2,) float
        Their 1σ over the bootstrap EGIs (NaN without any).
    """

    model: FacetModel
    principal_axes: np.ndarray
    centroid: np.ndarray
    n_facets: int
    axis_ratios: np.ndarray
    axis_ratio_sigma: np.ndarray


def axis_ratios(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """``a/b`` and ``b/c`` of the equivalent ellipsoid (same inertia) of a closed mesh."""
    a, b, c = equivalent_ellipsoid((vertices, faces))
    return np.array([a / b, b / c])


def _polyhedron(normals: np.ndarray, areas: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Minkowski polyhedron with surface area ``Σ areas`` (m²), centred on its centroid.

    Normals within :data:`MERGE_RADIUS` of each other are merged first (area-weighted mean):
    nearly parallel facets make slivers that the Newton iteration resolves slowly.
    """
    merged, total = cluster_normals(normals, areas, MERGE_RADIUS)
    vertices, faces = minkowski_polyhedron(merged, total, tol=MINKOWSKI_TOL)
    triangles = vertices[faces]
    surface = (
        0.5
        * np.linalg.norm(
            np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0]), axis=1
        ).sum()
    )
    return vertices * np.sqrt(areas.sum() / surface), faces


def convex_solid(
    normals: np.ndarray,
    areas: np.ndarray,
    *,
    samples: np.ndarray | None = None,
    name: str = "egi_shape",
) -> ConvexSolid:
    """The convex polyhedron of an EGI, in metres, and its axis ratios.

    Parameters
    ----------
    normals : (N, 3) float
        Unit normals, body frame.
    areas : (N,) float
        Areas (m²); the polyhedron's surface area is their sum.
    samples : (S, N) float, optional
        Bootstrap EGIs (:func:`~lightcurve.analysis.egi.fit.bootstrap_areas`) for the axis
        ratios' 1σ.
    name : str
        Name of the model.

    Returns
    -------
    ConvexSolid
    """
    if not np.any(areas > 0):
        raise ValueError("the fitted EGI has no area: nothing to reconstruct")
    vertices, faces = _polyhedron(normals, areas)
    body = FacetModel(vertices, faces, name=name, provenance={"source": "lightcurve shape"})
    principal = body.to_principal_frame()
    triangles = vertices[faces]
    facet_normals = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    n_facets = len(np.unique(np.argmax(facet_normals @ normals.T, axis=1)))
    ratios = axis_ratios(vertices, faces)
    sigma = np.full(2, np.nan)
    if samples is not None and len(samples) > 1:
        drawn = np.array([axis_ratios(*_polyhedron(normals, a)) for a in samples])
        sigma = drawn.std(axis=0, ddof=1)
    return ConvexSolid(principal, body.principal_axes, body.center_of_mass, n_facets, ratios, sigma)
