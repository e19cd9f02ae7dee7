"""The convex polyhedron of a Gaussian image (Minkowski's problem), and its proportions.

Given outward normals ``n_i`` and areas ``A_i`` with ``Σ A_i n_i = 0``, Minkowski's theorem
gives a unique convex polyhedron (up to translation) with those facets. Its support
distances ``h_i`` minimise ``Σ A_i h_i`` at fixed volume (Minkowski 1897; the variational
method of Little 1983 and Lamberg 1993 used by Kaasalainen & Torppa 2001, sec. 3.4). We
minimise the convex ``Φ(h) = Σ A_i h_i − ln V(h)`` by Newton's method, using
``∂V/∂h_i = F_i(h)`` (the area of facet i of the polytope ``{x : n_i · x ≤ h_i}``, which
scipy's (qhull) half-space intersection gives exactly) and the exact second derivatives
from the polytope's edges (:func:`volume_hessian`).

A Gaussian image from a fit is closed by the *dark facet* ``−Σ A_i n_i`` (Kaasalainen &
Torppa 2001, sec. 3.3) or, by default, by the smallest relative change of the areas that
makes the sum vanish.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from scipy.spatial import HalfspaceIntersection
from threadpoolctl import threadpool_limits

from shapes.mass import solid_properties

if TYPE_CHECKING:
    from shapes import FacetModel

__all__ = [
    "close_gaussian_image",
    "equivalent_ellipsoid",
    "minkowski_polyhedron",
    "polytope",
    "volume_hessian",
]


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
        ``Σ (δA_i/A_i)²``; areas that this would make negative are set to 0 and the rest
        changed again until the sum vanishes.

    Returns
    -------
    normals, areas

    Raises
    ------
    ValueError
        If no such change of the areas closes the image (use ``dark_facet``).
    """
    normals = np.asarray(normals, float)
    areas = np.asarray(areas, float)
    v = areas @ normals
    if dark_facet:
        size = np.linalg.norm(v)
        if size == 0:
            return normals, areas
        return np.vstack([normals, -v / size]), np.append(areas, size)
    closed = areas
    for _ in range(len(areas)):
        if closed.sum() > 0 and np.linalg.norm(v) <= 1e-12 * closed.sum():
            return normals, closed
        weights = np.where(closed > 0, areas, 0.0) ** 2
        try:
            lagrange = np.linalg.solve(normals.T @ (weights[:, None] * normals), v)
        except np.linalg.LinAlgError:
            break
        closed = np.clip(closed - weights * (normals @ lagrange), 0.0, None)
        v = closed @ normals
    raise ValueError(
        f"cannot close the Gaussian image by changing its areas (|Σ A n| / Σ A = "
        f"{np.linalg.norm(v) / areas.sum():.2e}); close it with the dark facet instead"
    )


class _Polytope(NamedTuple):
    """A polytope ``{x : n_i · x ≤ h_i}`` with each facet's vertices in counter-clockwise
    order (seen from outside): edge ``e`` of facet ``facet[e]`` runs from ``vertex[e]`` to
    ``vertex[following[e]]``."""

    vertices: np.ndarray  # (V, 3)
    vertex: np.ndarray  # (E,) start vertex of each directed facet edge
    facet: np.ndarray  # (E,) facet (plane) of each directed edge
    following: np.ndarray  # (E,) index of the next edge of the same facet
    first: np.ndarray  # (E,) index of the first edge of the same facet
    position: np.ndarray  # (E,) rank of the edge in its facet's cycle
    size: np.ndarray  # (F,) vertices of each facet (0: redundant plane)
    planes: list  # for each vertex, the planes meeting there (qhull's dual facets)
    facet_areas: np.ndarray  # (F,)


def _polytope(normals: np.ndarray, support: np.ndarray) -> _Polytope:
    """One qhull half-space intersection and each facet's vertex cycle (origin inside)."""
    halfspaces = np.column_stack([normals, -support])
    hs = HalfspaceIntersection(halfspaces, np.zeros(3))
    vertices = hs.intersections
    planes = hs.dual_facets
    counts = np.array([len(f) for f in planes])
    vertex = np.repeat(np.arange(len(vertices)), counts)
    facet = np.concatenate(planes)
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
    return _Polytope(vertices, vertex, facet, following, first, position, size, planes, facet_areas)


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
    p = _polytope(normals, support)
    return p.vertices, _fan(p), p.facet_areas


def _fan(p: _Polytope) -> np.ndarray:
    """Fan triangulation (T, 3) of every facet, counter-clockwise seen from outside."""
    fan = (p.position >= 1) & (p.position + 1 < p.size[p.facet])
    return np.column_stack([p.vertex[p.first[fan]], p.vertex[fan], p.vertex[p.following[fan]]])


def volume_hessian(normals: np.ndarray, support: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Facet areas ``F_i = ∂V/∂h_i`` and the Hessian ``∂²V/∂h_i∂h_j`` of the volume.

    Moving plane j out by ``dh_j`` moves the edge it shares with facet i by ``dh_j / sin θ_ij``
    within facet i's plane, and moving plane i itself moves that edge by
    ``−dh_i cot θ_ij``, so (Alexandrov 1950, *Convex Polyhedra*, sec. 7.3; Lachand-Robert &
    Oudet 2005, "Minimizing within convex bodies using a convex hull method")
    ``∂F_i/∂h_j = ℓ_ij / sin θ_ij`` for adjacent facets and
    ``∂F_i/∂h_i = −Σ_j ℓ_ij cot θ_ij``, with ``ℓ_ij`` the length of the shared edge and
    ``cos θ_ij = n_i · n_j``. ``V`` is homogeneous of degree 3, so ``H h = 2 F``.

    Parameters
    ----------
    normals : (F, 3) float
        Unit normals.
    support : (F,) float
        Support distances (> 0: the origin must be inside), any length unit L.

    Returns
    -------
    facet_areas : (F,) float
        L².
    hessian : (F, F) float
        L, symmetric; zero rows for redundant planes.
    """
    p = _polytope(normals, support)
    return p.facet_areas, _hessian(normals, p)


def _hessian(normals: np.ndarray, p: _Polytope) -> np.ndarray:
    count = len(normals)
    start, end, facet = p.vertex, p.vertex[p.following], p.facet
    # The neighbouring facet of each directed edge: the plane (other than its own) through
    # both of its vertices, looked up among the planes of the start vertex.
    counts = np.array([len(f) for f in p.planes])
    offsets = np.r_[0, np.cumsum(counts)]
    plane_list = np.concatenate(p.planes)
    incident = np.sort(np.repeat(np.arange(len(counts)), counts) * count + plane_list)
    edge = np.repeat(np.arange(len(start)), counts[start])
    within = np.arange(len(edge)) - np.repeat(
        np.cumsum(counts[start]) - counts[start], counts[start]
    )
    other = plane_list[offsets[start][edge] + within]
    key = end[edge] * count + other
    found = incident[np.minimum(np.searchsorted(incident, key), len(incident) - 1)] == key
    valid = found & (other != facet[edge])
    edge, other = edge[valid], other[valid]
    edge, unique = np.unique(edge, return_index=True)  # one neighbour per edge
    other = other[unique]
    i = facet[edge]
    length = np.linalg.norm(p.vertices[end[edge]] - p.vertices[start[edge]], axis=1)
    cosine = np.sum(normals[i] * normals[other], axis=1)
    sine = np.sqrt(np.clip(1.0 - cosine**2, 1e-30, None))
    hessian = np.zeros((count, count))
    np.add.at(hessian, (i, other), length / sine)
    hessian[np.diag_indices(count)] = -np.bincount(i, length * cosine / sine, count)
    return hessian


def minkowski_polyhedron(
    normals: np.ndarray,
    areas: np.ndarray,
    dark_facet: bool = False,
    volume: float = 1.0,
    tol: float = 1e-10,
    max_iter: int = 200,
) -> tuple[np.ndarray, np.ndarray]:
    """Convex polyhedron whose facets have the given normals and (relative) areas.

    With the areas normalised to ``Σ A_i = 1``, the support distances minimise the convex
    function ``Φ(h) = Σ A_i h_i − ln V(h)`` (convex because ``V^{1/3}`` is concave, the
    Brunn–Minkowski inequality); its minimum has ``F_i(h) = V A_i``, i.e. facet areas
    proportional to ``A_i`` (Minkowski 1897; the variational form of Little 1983 and
    Lamberg 1993 used by Kaasalainen & Torppa 2001, sec. 3.4). Damped Newton steps with the
    exact Hessian of :func:`volume_hessian` (translations, which leave ``Φ`` unchanged, are
    removed from each step) converge in a few tens of half-space intersections.

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
        Stop when ``max_i |A_i − F_i/V| ≤ tol`` (areas normalised to sum 1).
    max_iter : int
        Newton steps at most.

    Returns
    -------
    vertices : (V, 3) float
        Centred on the centroid.
    faces : (T, 3) int
        Outward triangles.

    Raises
    ------
    RuntimeError
        If the iteration does not reach ``tol`` (or the limit of float64 arithmetic) within
        ``max_iter`` steps.
    """
    normals, areas = close_gaussian_image(normals, areas, dark_facet)
    areas = areas / areas.sum()
    # Facets of relative area ≤ tol are left out: they meet the tolerance with no area.
    normals, areas = normals[areas > tol], areas[areas > tol]

    def evaluate(h: np.ndarray) -> tuple[float, _Polytope | None]:
        if np.min(h) <= 0.0:
            return np.inf, None
        p = _polytope(normals, h)
        vol = float(h @ p.facet_areas) / 3.0
        return (float(areas @ h) - np.log(vol) if vol > 0 else np.inf), p

    h = np.ones(len(normals))
    value, p = evaluate(h)
    converged = False
    # One BLAS thread: a few hundred unknowns, and threads that spin on a busy machine (set
    # once: threadpoolctl looks the libraries up on every entry).
    with threadpool_limits(limits=1, user_api="blas"):
        for _ in range(max_iter):
            # Planes cutting no facet of measurable area are moved in to touch the polytope
            # (the same polytope, a lower Φ); their step below cuts a small facet off it.
            inactive = p.facet_areas <= 1e-13 * p.facet_areas.sum()
            h[inactive] = np.max(normals[inactive] @ p.vertices.T, axis=1)
            vol = float(h @ p.facet_areas) / 3.0
            value = float(areas @ h) - np.log(vol)
            scaled = p.facet_areas / vol
            gradient = areas - scaled
            if np.max(np.abs(gradient)) <= tol:
                converged = True
                break
            hessian = np.outer(scaled, scaled) - _hessian(normals, p) / vol
            # Translations of the polytope (h → h + N t) are a null space of Φ: penalised.
            held = normals * ~inactive[:, None]
            hessian += np.mean(np.abs(np.diag(hessian))) * (held @ held.T)
            rhs = -gradient
            # A cut of depth ε at a vertex has an area of order ε²: aim at the target area.
            hessian[inactive] = 0.0
            hessian[:, inactive] = 0.0
            hessian[inactive, inactive] = 1.0
            rhs[inactive] = -0.5 * np.sqrt(vol * areas[inactive])
            step = np.linalg.solve(hessian, rhs)
            slope = float(gradient @ step)
            if -slope <= 1e-30:  # Newton decrement at float64 round-off
                converged = True
                break
            t = 1.0
            while t > 1e-12:
                trial, q = evaluate(h + t * step)
                # Armijo's decrease, and no facet cut away: the area of a small facet is far
                # from linear in h, so a full step would overshoot.
                if trial <= value + 1e-4 * t * slope and not np.any(
                    ~inactive & (q.facet_areas <= 1e-13 * q.facet_areas.sum())
                ):
                    break
                t *= 0.5
            else:
                break
            # Re-centre (Φ is unchanged by translations): keep the origin well inside.
            shift = q.vertices.mean(axis=0)
            h = h + t * step - normals @ shift
            p = q._replace(vertices=q.vertices - shift)
    if not converged:
        raise RuntimeError(
            f"Minkowski reconstruction did not converge in {max_iter} Newton steps "
            f"(largest area mismatch {np.max(np.abs(gradient)):.2e} > tol {tol:.1e})"
        )
    vertices, faces = p.vertices, _fan(p)
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
    vertices, faces = (shape.vertices, shape.faces) if hasattr(shape, "faces") else shape
    props = solid_properties(vertices[faces])
    moments = np.linalg.eigvalsh(props.inertia)
    axes = np.sqrt(np.clip(5.0 * (moments.sum() - 2 * moments) / (2 * props.measure), 0, None))
    radius = (3 * props.measure / (4 * np.pi)) ** (1 / 3)
    return np.sort(axes)[::-1] / radius
