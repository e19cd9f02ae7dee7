"""Appendages for facet models: an antenna or a thruster placed clear on a flat face.

:func:`place_appendage` draws the size of a small part and a place for it on a mesh: an
antenna (a thin square rod) or a thruster (a small octagonal prism), standing along the
outward normal of a flat face of a closed part of the mesh (one that encloses a volume: a
bus, a tank, not a solar-array sheet), with the space above its footprint clear of the
mesh. Its size scales with the mesh's length ``√(area / 6)`` (a cube's edge): antenna
2–3 % wide and 20–40 % long, thruster of radius 5–8 % and height 8–15 %. The part is a
closed mesh to concatenate to the model's (no boolean union). :mod:`shapes.perturbation`
adds one to its perturbed models.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial.transform import Rotation

from shapes.material import ALUMINIUM, BLACK_PAINT, Material

__all__ = ["APPENDAGE_KINDS", "Appendage", "place_appendage"]

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


def place_appendage(
    vertices: np.ndarray,
    faces: np.ndarray,
    group_index: np.ndarray,
    group_names: list[str],
    kind: str,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray, Appendage] | None:
    """Draw an appendage's size and a clear place for it on a flat face of the mesh.

    The footprint (grown by 10 %) must lie on one flat region of a closed part (coplanar
    facets of one group joined by edges; regions of at least four footprints' area are
    drawn in proportion to their area, then a point uniformly on them), the rays along the
    normal from its corners, edge midpoints and centre must not hit the mesh, no mesh edge
    may cross the part and no mesh vertex lie inside it. Up to ``_PLACEMENT_TRIES`` places
    are drawn.

    Parameters
    ----------
    vertices : (V, 3) float
        Mesh vertices, m, body frame.
    faces : (F, 3) int
        Facets, counter-clockwise seen from outside.
    group_index : (F,) int
        Group of each facet.
    group_names : list of str
        Names of the groups (the part's group gets a name not among them).
    kind : {"antenna", "thruster"}
    rng : numpy.random.Generator
        Source of the size and the place.

    Returns
    -------
    tuple or None
        The part's vertices (m, body frame) and facets (indices into those vertices), and
        its :class:`Appendage` record; None when no place fits.
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
    mesh = _Mesh(vertices, faces, triangles, _edges(faces))
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
        e_u = Rotation.from_rotvec(turn * normal).as_matrix() @ e_u
        frame = np.stack([e_u, np.cross(normal, e_u), normal], axis=1)
        part_vertices, part_faces = _part_mesh(kind, size)
        part = _Part(part_vertices, part_faces, base, frame, half, height)
        if not _fits(mesh, members, part):
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


@dataclass(frozen=True)
class _Mesh:
    """The mesh the part must keep clear of (m, body frame)."""

    vertices: np.ndarray
    faces: np.ndarray
    triangles: np.ndarray
    edges: np.ndarray

    @property
    def tolerance(self) -> float:
        return 1e-9 * max(float(np.ptp(self.vertices, axis=0).max()), 1e-300)


@dataclass(frozen=True)
class _Part:
    """A part at a trial place: its mesh in its own frame, the centre of its footprint
    ``base`` and ``frame`` (columns: its x, y, z axes in the body frame), the half-width of
    its footprint and its height (m)."""

    vertices: np.ndarray
    faces: np.ndarray
    base: np.ndarray
    frame: np.ndarray
    half: float
    height: float


def _fits(mesh: _Mesh, members: np.ndarray, part: _Part) -> bool:
    """Whether ``part`` stands on region ``members`` clear of the mesh (see
    :func:`place_appendage`)."""
    grid = np.array([-1.1, 0.0, 1.1]) * part.half
    u, v = np.meshgrid(grid, grid, indexing="ij")
    footprint = part.base + np.stack([u.ravel(), v.ravel(), np.zeros(u.size)], 1) @ part.frame.T
    if not _inside_any(footprint, mesh.triangles[members]):
        return False
    normal = part.frame[:, 2]
    lift = 1e-6 * part.height
    rays = np.broadcast_to(normal, footprint.shape)
    if _hits(footprint + lift * normal, rays, np.inf, mesh.triangles).any():
        return False
    # The part shrunk by a part in a million, off the face it stands on, against the mesh.
    local = part.vertices * np.array([1.0 - 1e-6, 1.0 - 1e-6, 1.0 - 2e-6]) + [0.0, 0.0, lift]
    placed = part.base + local @ part.frame.T
    part_edges = _edges(part.faces)
    starts, ends = placed[part_edges[:, 0]], placed[part_edges[:, 1]]
    if _hits(starts, ends - starts, 1.0, mesh.triangles).any():
        return False
    starts, ends = mesh.vertices[mesh.edges[:, 0]], mesh.vertices[mesh.edges[:, 1]]
    if _hits(starts, ends - starts, 1.0, placed[part.faces]).any():
        return False
    corners = placed[part.faces]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    depth = np.einsum("fi,vfi->vf", normals, mesh.vertices[:, None, :] - corners[None, :, 0])
    return not bool(np.any(np.all(depth < -mesh.tolerance, axis=1)))


def _unit(vector: np.ndarray) -> np.ndarray:
    return vector / np.linalg.norm(vector)


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
