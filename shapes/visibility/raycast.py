"""Occlusion ray casting against a triangle mesh, and stratified sample points on facets.

:class:`Occluder` answers "does a ray from this origin along this direction hit the mesh?"
for millions of rays. With ``embreex`` installed it asks Embree's occlusion query directly
(about 2.6× faster than trimesh's first-hit wrapper on Bennu, 1.7 vs 2.7 Mrays/s on one
core); without it, it falls back to trimesh's pure-numpy ``ray_triangle`` intersector, which
is exact but ~500× slower, so large visibility tables need Embree.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import trimesh

__all__ = ["Occluder", "facet_sample_points", "has_embree"]

try:  # pragma: no cover - depends on the platform
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    has_embree = True
except ImportError:  # pragma: no cover
    has_embree = False


class Occluder:
    """Boolean ray–mesh occlusion queries.

    Parameters
    ----------
    vertices : (V, 3) float
        Mesh vertices, m.
    faces : (F, 3) int
        Triangles.
    backend : {"auto", "embree", "trimesh"}
        ``"auto"`` uses Embree when ``embreex`` is importable.
    """

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, backend: str = "auto") -> None:
        if backend == "auto":
            backend = "embree" if has_embree else "trimesh"
        if backend == "embree" and not has_embree:
            raise ValueError("backend 'embree' needs the embreex package")
        if backend not in ("embree", "trimesh"):
            raise ValueError(f"unknown ray-casting backend {backend!r}")
        self.backend = backend
        vertices = np.asarray(vertices, float)
        if backend == "embree":
            # shift and scale into a unit box, as trimesh does, for float32 precision
            self._origin = vertices.min(axis=0)
            self._scale = 1.0 / max(float(np.ptp(vertices, axis=0).max()), 1e-300)
            self._scene = rtcore_scene.EmbreeScene()
            TriangleMesh(
                scene=self._scene,
                vertices=((vertices - self._origin) * self._scale).astype(np.float32),
                indices=np.asarray(faces, dtype=np.int32),
            )
        else:
            mesh = trimesh.Trimesh(vertices, faces, process=False)
            self._intersector = trimesh.ray.ray_triangle.RayMeshIntersector(mesh)

    def to_scene(self, points: np.ndarray) -> np.ndarray:
        """Points in the ray caster's own coordinates (for repeated :meth:`query` calls)."""
        if self.backend == "embree":
            return ((np.asarray(points, float) - self._origin) * self._scale).astype(np.float32)
        return np.asarray(points, float)

    def query(self, scene_origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """Occlusion of rays whose origins are already in scene coordinates (:meth:`to_scene`).

        Parameters
        ----------
        scene_origins : (n, 3) float
        directions : (n, 3) float
            Unit directions (the scene transform is a uniform scaling and shift).

        Returns
        -------
        (n,) bool
            True where the ray hits the mesh.
        """
        if len(scene_origins) == 0:
            return np.zeros(0, dtype=bool)
        if self.backend == "embree":
            result = self._scene.run(
                np.ascontiguousarray(scene_origins, dtype=np.float32),
                np.ascontiguousarray(directions, dtype=np.float32),
                query="OCCLUDED",
            )
            return np.asarray(result) != -1
        return np.asarray(self._intersector.intersects_any(scene_origins, directions), dtype=bool)

    def __call__(self, origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """Whether each ray ``origin + τ·direction`` (τ > 0) hits the mesh.

        Parameters
        ----------
        origins : (n, 3) float
            Ray origins, m (offset them off the surface they start on).
        directions : (n, 3) float
            Unit directions.

        Returns
        -------
        (n,) bool
        """
        return self.query(self.to_scene(origins), directions)


@lru_cache(maxsize=64)
def _barycentric_pattern(m: int) -> np.ndarray:
    """Barycentric (w_b, w_c) of the centroids of the m² congruent sub-triangles."""
    i, j = np.meshgrid(np.arange(m), np.arange(m), indexing="ij")
    up = i + j <= m - 1
    down = i + j <= m - 2
    uv = np.concatenate(
        [
            np.stack([(3 * i[up] + 1), (3 * j[up] + 1)], axis=1),
            np.stack([(3 * i[down] + 2), (3 * j[down] + 2)], axis=1),
        ]
    ) / (3.0 * m)
    uv.setflags(write=False)
    return uv


def facet_sample_points(
    triangles: np.ndarray, subdivisions: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stratified, equal-area sample points on triangles.

    Triangle ``i`` is cut into ``m_i²`` congruent sub-triangles (``m_i = subdivisions[i]``)
    and sampled at their centroids, so each point stands for area ``A_i / m_i²``.

    Parameters
    ----------
    triangles : (F, 3, 3) float
        Facet vertices, m.
    subdivisions : (F,) int
        ``m_i ≥ 1``.

    Returns
    -------
    points : (P, 3) float
        m.
    facet : (P,) int
        Triangle of each point.
    weight : (P,) float
        Area represented by each point, m².
    """
    tri = np.asarray(triangles, float)
    m = np.asarray(subdivisions, dtype=np.int64)
    areas = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    points, facet, weight = [], [], []
    for level in np.unique(m):
        rows = np.flatnonzero(m == level)
        uv = _barycentric_pattern(int(level))
        a, b, c = tri[rows, 0], tri[rows, 1], tri[rows, 2]
        pts = (
            a[:, None, :]
            + uv[None, :, 0, None] * (b - a)[:, None, :]
            + uv[None, :, 1, None] * (c - a)[:, None, :]
        )
        points.append(pts.reshape(-1, 3))
        facet.append(np.repeat(rows, len(uv)))
        weight.append(np.repeat(areas[rows] / len(uv), len(uv)))
    return np.concatenate(points), np.concatenate(facet), np.concatenate(weight)
