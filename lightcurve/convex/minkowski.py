"""The convex polyhedron of a Gaussian image (Minkowski's problem), and its proportions.

Given outward normals ``n_i`` and areas ``A_i`` with ``Σ A_i n_i = 0``, Minkowski's theorem
gives a unique convex polyhedron (up to translation) with those facets. Its support
distances ``h_i`` minimise ``Σ A_i h_i`` at fixed volume (Minkowski 1897; the variational
method of Little 1983 and Lamberg 1993 used by Kaasalainen & Torppa 2001, sec. 3.4). We
minimise the scale-free ``g(h) = Σ A_i h_i / V(h)^{1/3}`` with L-BFGS, using
``∂V/∂h_i = F_i(h)`` (the area of facet i of the polytope ``{x : n_i · x ≤ h_i}``), which
scipy's (qhull) half-space intersection gives exactly.

A Gaussian image from a fit is closed by the *dark facet* ``−Σ A_i n_i`` (Kaasalainen &
Torppa 2001, sec. 3.3) or, by default, by the smallest relative change of the areas that
makes the sum vanish.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize
from scipy.spatial import HalfspaceIntersection
from threadpoolctl import threadpool_limits

from shapes import FacetModel
from shapes.mass import solid_properties

__all__ = ["close_gaussian_image", "equivalent_ellipsoid", "minkowski_polyhedron", "polytope"]


def close_gaussian_image(
    normals: np.ndarray, areas: np.ndarray, dark_facet: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """Make ``Σ A_i n_i = 0``.

    Parameters
    ----------
    normals : (F, 3) float
        Unit normals.
    areas : (F,) float
        Non-negative areas.
    dark_facet : bool
        Append the dark facet (normal ``−v/|v|``, area ``|v|``, ``v = Σ A_i n_i``) instead
        of changing the areas by ``δA = −A² ∘ (N λ)``, the least change in
        ``Σ (δA_i/A_i)²``.

    Returns
    -------
    normals, areas
    """
    normals = np.asarray(normals, float)
    areas = np.asarray(areas, float)
    v = areas @ normals
    if dark_facet:
        size = np.linalg.norm(v)
        if size == 0:
            return normals, areas
        return np.vstack([normals, -v / size]), np.append(areas, size)
    weights = areas**2
    lagrange = np.linalg.solve(normals.T @ (weights[:, None] * normals), v)
    return normals, np.clip(areas - weights * (normals @ lagrange), 0.0, None)


def polytope(normals: np.ndarray, support: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vertices, outward triangles and per-normal facet areas of ``{x : n_i · x ≤ h_i}``.

    One qhull half-space intersection gives the vertices and, for each, the planes meeting
    there; each facet's vertices are ordered by angle about its centre, which yields its
    area (shoelace formula) and a fan triangulation.

    Parameters
    ----------
    normals : (F, 3) float
    support : (F,) float
        Support distances ``h_i`` (> 0: the origin must be inside).

    Returns
    -------
    vertices : (V, 3) float
    faces : (T, 3) int
        Triangles wound counter-clockwise seen from outside.
    facet_areas : (F,) float
        Area of the polytope facet with normal ``n_i`` (0 for redundant planes).
    """
    halfspaces = np.column_stack([normals, -support])
    hs = HalfspaceIntersection(halfspaces, np.zeros(3))
    vertices = hs.intersections
    counts = np.array([len(f) for f in hs.dual_facets])
    vertex = np.repeat(np.arange(len(vertices)), counts)
    facet = np.concatenate(hs.dual_facets)
    # In-plane frame (u, w = n × u) of each facet; angles about the facet's vertex mean.
    n = normals[facet]
    helper = np.where(np.abs(n[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    u = np.cross(n, helper)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    w = np.cross(n, u)
    size = np.bincount(facet, minlength=len(normals))
    center = (
        np.stack([np.bincount(facet, vertices[vertex, k], len(normals)) for k in range(3)], axis=1)
        / np.maximum(size, 1)[:, None]
    )
    rel = vertices[vertex] - center[facet]
    order = np.lexsort((np.arctan2(np.sum(rel * w, 1), np.sum(rel * u, 1)), facet))
    vertex, facet = vertex[order], facet[order]
    first = np.r_[0, np.cumsum(size)[:-1]][facet]
    position = np.arange(len(facet)) - first
    following = np.where(position + 1 < size[facet], np.arange(len(facet)) + 1, first)
    a, b = vertices[vertex], vertices[vertex[following]]
    twice = np.sum(np.cross(a, b) * normals[facet], axis=1)
    facet_areas = 0.5 * np.bincount(facet, twice, len(normals))
    fan = (position >= 1) & (position + 1 < size[facet])
    faces = np.column_stack([vertex[first[fan]], vertex[fan], vertex[following[fan]]])
    return vertices, faces, facet_areas


def minkowski_polyhedron(
    normals: np.ndarray,
    areas: np.ndarray,
    dark_facet: bool = False,
    volume: float = 1.0,
    tol: float = 1e-10,
    max_iter: int = 2000,
) -> tuple[np.ndarray, np.ndarray]:
    """Convex polyhedron whose facets have the given normals and (relative) areas.

    Parameters
    ----------
    normals : (F, 3) float
        Unit outward normals.
    areas : (F,) float
        Facet areas (any scale); closed first with :func:`close_gaussian_image`.
    dark_facet : bool
        How to close the image (see :func:`close_gaussian_image`).
    volume : float
        Volume of the result (the areas fix the shape, not the size).
    tol : float
        L-BFGS gradient tolerance.
    max_iter : int
        L-BFGS iterations.

    Returns
    -------
    vertices : (V, 3) float
        Centred on the centroid.
    faces : (T, 3) int
        Outward triangles.
    """
    normals, areas = close_gaussian_image(normals, areas, dark_facet)
    areas = areas / areas.sum()
    # Translations leave g(h) unchanged; the origin is kept inside by re-centring.
    state = {"center": np.zeros(3)}

    def objective(h: np.ndarray) -> tuple[float, np.ndarray]:
        shifted = h - normals @ state["center"]
        if np.min(shifted) <= 1e-9:
            return np.inf, np.zeros_like(h)
        _, _, facet = polytope(normals, shifted)
        vol = np.sum(shifted * facet) / 3.0
        support_sum = float(areas @ h)
        value = support_sum / vol ** (1 / 3)
        grad = areas / vol ** (1 / 3) - support_sum / 3.0 * vol ** (-4 / 3) * facet
        return value, grad

    h = np.ones(len(normals))
    # L-BFGS's vector operations are small (one per facet): on one BLAS thread they take
    # less than half the CPU time of two threads handing them back and forth.
    with threadpool_limits(limits=1, user_api="blas"):
        for _ in range(5):
            result = minimize(
                objective,
                h,
                jac=True,
                method="L-BFGS-B",
                options={"gtol": tol, "maxiter": max_iter},
            )
            h = result.x
            vertices, _, _ = polytope(normals, h - normals @ state["center"])
            state["center"] = state["center"] + vertices.mean(axis=0)
            if result.success:
                break
    vertices, faces, _ = polytope(normals, h - normals @ state["center"])
    mass = solid_properties(vertices[faces])
    vertices = vertices - mass.center_of_mass
    vertices *= (volume / mass.measure) ** (1 / 3)
    return vertices, faces


def equivalent_ellipsoid(shape: FacetModel | tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Semi-axes ``a ≥ b ≥ c`` of the uniform ellipsoid with the same inertia, over the
    radius of the sphere of equal volume (scale-free "volume-normalised axis ratios").

    For a solid ellipsoid ``J_a = m (b² + c²)/5`` etc., so ``a² = 5 (J_b + J_c − J_a)/(2m)``.

    Parameters
    ----------
    shape : FacetModel or (vertices, faces)
        A closed, outward-wound mesh.

    Returns
    -------
    (3,) float
        ``(a, b, c) / R_eq``, descending.
    """
    if isinstance(shape, FacetModel):
        triangles = shape.triangles
    else:
        vertices, faces = shape
        triangles = np.asarray(vertices)[np.asarray(faces)]
    props = solid_properties(triangles)
    moments = np.linalg.eigvalsh(props.inertia)
    axes = np.sqrt(np.clip(5.0 * (moments.sum() - 2 * moments) / (2 * props.mass), 0, None))
    radius = (3 * props.measure / (4 * np.pi)) ** (1 / 3)
    return np.sort(axes)[::-1] / radius
