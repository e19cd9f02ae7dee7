"""Self-shadowing of articulated shapes: ray casting against parts in their per-epoch pose.

A sample point of a facet contributes to the flux only when it is both lit (the ray toward
the Sun escapes the shape) and seen (the ray toward the observer escapes). With moving parts
the occluding geometry changes every epoch; instead of rebuilding a ray-casting structure
per epoch, each rigid group (the body, every moving part) keeps one structure in its own
frame and every ray is carried into that frame: a body-frame ray ``x + τ d`` tested against
group ``j`` (part → body rotation ``R_j``, pivot ``p_j``) becomes ``R_jᵀ(x − p_j) + p_j +
τ R_jᵀ d``. A ray is blocked when any group blocks it, so the cost is (sample points facing
both directions) × 2 × (number of groups) occlusion queries per epoch; a group is not tested
against itself when it is convex on its own.

Sampling is that of :func:`shapes.visibility.visible_fraction` (``m_i²`` stratified points
per triangle, about ``samples`` per effective facet, lifted 1e-4 of the shape size along the
normal), and the fraction of an effective facet is the area-weighted mean over its points.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.sparse import csr_matrix

from shapes.model import FacetModel
from shapes.visibility.raycast import Occluder, facet_sample_points
from shapes.visibility.sampling import DEFAULT_SAMPLES

__all__ = ["PosedShadows"]

_RAY_LIFT = 1e-4  # origin offset along the normal, fraction of the shape's bounding diagonal
_CHUNK_RAYS = 1 << 20


class _Group:
    """Sample points, pooling matrix and ray caster of one rigid group."""

    def __init__(
        self, model: FacetModel, pivot: np.ndarray, samples: int, lift: float, backend: str
    ) -> None:
        compiled = model.compiled()
        self.pivot = np.asarray(pivot, float)
        self.n_facets = len(compiled)
        member = np.concatenate(compiled.members)
        column = np.repeat(np.arange(len(compiled)), [len(m) for m in compiled.members])
        tri = compiled.vertices[compiled.faces[member]]
        cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        area = 0.5 * np.linalg.norm(cross, axis=1)
        share = area / compiled.areas[column]
        subdiv = np.clip(np.rint(np.sqrt(samples * share)), 1, 64).astype(np.int64)
        points, which, weight = facet_sample_points(tri, subdiv)
        unit = cross / np.maximum(2.0 * area, 1e-300)[:, None]
        self.origins = points + lift * unit[which]
        point_col = column[which]
        self.normals = compiled.normals[point_col]
        weight = weight / np.bincount(point_col, weights=weight)[point_col]
        self.pool = csr_matrix(
            (weight, (np.arange(len(points)), point_col)), shape=(len(points), self.n_facets)
        )
        self.occluder = Occluder(compiled.vertices, compiled.faces, backend=backend)
        self.self_shadowing = bool(np.any(compiled.can_be_shadowed))


class PosedShadows:
    """Lit-and-seen fractions of the effective facets of rigid groups in per-epoch poses.

    Parameters
    ----------
    groups : sequence of FacetModel
        The rigid groups, each in its own frame (mesh coordinates at joint angle 0).
    pivots : sequence of (3,) float
        A point of each group's joint axis, m, body frame (any point for the body).
    samples : int
        Target ray origins per effective facet.
    backend : {"auto", "embree", "trimesh"}
        Ray caster (:class:`~shapes.visibility.raycast.Occluder`).
    """

    def __init__(
        self,
        groups: Sequence[FacetModel],
        pivots: Sequence[np.ndarray],
        samples: int = DEFAULT_SAMPLES,
        backend: str = "auto",
    ) -> None:
        scale = float(np.linalg.norm(np.ptp(np.vstack([g.vertices for g in groups]), axis=0)))
        self.groups = [
            _Group(g, p, samples, _RAY_LIFT * scale, backend)
            for g, p in zip(groups, pivots, strict=True)
        ]

    def fractions(
        self, rotations: np.ndarray, light: np.ndarray, view: np.ndarray
    ) -> list[np.ndarray]:
        """Lit-and-seen fraction of every effective facet of every group.

        Parameters
        ----------
        rotations : (G, E, 3, 3) float
            Part → body rotation of each group at each epoch (identity for the body).
        light, view : (E, 3) float
            Unit object → Sun and object → observer directions, body frame.

        Returns
        -------
        list of (E, K_g) float
            Per group, in the order of its compiled facets; 0 where the facet faces away
            from the Sun or the observer.
        """
        rotations = np.asarray(rotations, float)
        light = np.asarray(light, float)
        view = np.asarray(view, float)
        out = []
        for i, group in enumerate(self.groups):
            result = np.zeros((len(light), group.n_facets))
            chunk = max(1, _CHUNK_RAYS // max(len(group.origins), 1))
            for start in range(0, len(light), chunk):
                rows = slice(start, start + chunk)
                result[rows] = self._group_chunk(i, rotations[:, rows], light[rows], view[rows])
            out.append(result)
        return out

    def _group_chunk(
        self, i: int, rotations: np.ndarray, light: np.ndarray, view: np.ndarray
    ) -> np.ndarray:
        group = self.groups[i]
        own = rotations[i]  # (E, 3, 3) part → body
        # directions in the group's frame: Rᵀ d
        light_i = np.einsum("eji,ej->ei", own, light)
        view_i = np.einsum("eji,ej->ei", own, view)
        facing = (light_i @ group.normals.T > 0.0) & (view_i @ group.normals.T > 0.0)
        epoch, point = np.nonzero(facing)
        visible = np.zeros(facing.shape)
        if len(epoch) == 0:
            return np.zeros((len(light), group.n_facets))
        # ray origins in the body frame
        origin = (
            np.einsum("eij,ej->ei", own[epoch], group.origins[point] - group.pivot) + group.pivot
        )
        blocked = np.zeros((2, len(epoch)), dtype=bool)
        for j, other in enumerate(self.groups):
            if j == i and not other.self_shadowing:
                continue
            pose = rotations[j][epoch]  # (n, 3, 3)
            local = np.einsum("nji,nj->ni", pose, origin - other.pivot) + other.pivot
            scene = other.occluder.to_scene(local)
            for k, direction in enumerate((light, view)):
                d = np.einsum("nji,nj->ni", pose, direction[epoch])
                todo = ~blocked[k]
                blocked[k, todo] = other.occluder.query(scene[todo], d[todo])
        visible[epoch, point] = ~(blocked[0] | blocked[1])
        return np.asarray(group.pool.T @ visible.T).T
