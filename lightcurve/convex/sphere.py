"""The fixed triangulated Gaussian sphere and its spherical-harmonics basis.

Convex inversion (Kaasalainen & Torppa 2001) represents a convex body by its Gaussian image:
the facet areas ``A_i`` attached to fixed unit normals ``n_i``. The normals are those of a
triangulated unit sphere with ``nrows`` rings of vertices per hemisphere (ring k at polar
angle ``kπ/(2 nrows)`` with ``4k`` vertices), ``8 nrows²`` triangles in all, as in the DAMIT
``convexinv`` program. The areas are ``A_i = ΔA_i exp(Σ_lm c_lm Y_lm(n_i))``
(Kaasalainen & Torppa 2001, eq. 12): ``ΔA_i`` the area of the sphere triangle, ``Y_lm`` the
real orthonormal spherical harmonics up to degree ``L`` and order ``M``; the exponential
keeps every area positive.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

__all__ = ["GaussianSphere", "harmonic_count", "real_harmonics"]


def harmonic_count(degree: int, order: int) -> int:
    """Number of real harmonics ``Y_lm`` with ``l ≤ degree`` and ``|m| ≤ min(l, order)``."""
    return sum(2 * min(l, order) + 1 for l in range(degree + 1))


def real_harmonics(directions: np.ndarray, degree: int, order: int) -> np.ndarray:
    """Real orthonormal spherical harmonics at unit directions.

    ``Y_l0``, ``√2 Re Y_lm`` and ``√2 Im Y_lm`` (m = 1 … min(l, order)), ordered by degree,
    then order (cosine before sine).

    Parameters
    ----------
    directions : (F, 3) float
        Unit vectors.
    degree, order : int
        Maximum degree L and order M (``0 ≤ M ≤ L``).

    Returns
    -------
    (F, K) numpy.ndarray
        ``K = harmonic_count(degree, order)``; column 0 is the constant ``1/√(4π)``.
    """
    from scipy.special import sph_harm_y

    if not 0 <= order <= degree:
        raise ValueError(f"need 0 ≤ order ≤ degree, got degree {degree}, order {order}")
    d = np.asarray(directions, float)
    theta = np.arccos(np.clip(d[:, 2], -1.0, 1.0))
    phi = np.arctan2(d[:, 1], d[:, 0])
    columns = []
    for l in range(degree + 1):
        columns.append(sph_harm_y(l, 0, theta, phi).real)
        for m in range(1, min(l, order) + 1):
            y = sph_harm_y(l, m, theta, phi)
            columns += [np.sqrt(2.0) * y.real, np.sqrt(2.0) * y.imag]
    return np.stack(columns, axis=1)


@dataclass(frozen=True)
class GaussianSphere:
    """Triangulated unit sphere: facet normals, areas, and the harmonics basis.

    Parameters
    ----------
    nrows : int
        Vertex rings per hemisphere (``8 nrows²`` facets; DAMIT's default 8 gives 512).
    degree, order : int
        Spherical-harmonics degree and order of the area expansion (default 6, 6).
    """

    nrows: int = 8
    degree: int = 6
    order: int = 6

    def __post_init__(self) -> None:
        if self.nrows < 1:
            raise ValueError(f"nrows must be ≥ 1, got {self.nrows}")
        if not 0 <= self.order <= self.degree:
            raise ValueError(f"need 0 ≤ order ≤ degree, got {self.degree}, {self.order}")

    @cached_property
    def vertices(self) -> np.ndarray:
        """(V, 3) unit vertices: poles plus rings of ``4 min(k, 2n − k)`` points."""
        n = self.nrows
        points = [[0.0, 0.0, 1.0]]
        for k in range(1, 2 * n):
            count = 4 * min(k, 2 * n - k)
            theta = k * np.pi / (2 * n)
            phi = 2 * np.pi * (np.arange(count) + 0.5 * (k % 2)) / count
            points += np.column_stack(
                [
                    np.sin(theta) * np.cos(phi),
                    np.sin(theta) * np.sin(phi),
                    np.full(count, np.cos(theta)),
                ]
            ).tolist()
        points.append([0.0, 0.0, -1.0])
        return np.array(points)

    @cached_property
    def _triangles(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        from scipy.spatial import ConvexHull

        hull = ConvexHull(self.vertices)
        faces = hull.simplices.copy()
        tri = self.vertices[faces]
        cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        outward = np.sum(cross * tri.mean(axis=1), axis=1) > 0
        faces[~outward] = faces[~outward][:, ::-1]
        cross[~outward] *= -1
        norm = np.linalg.norm(cross, axis=1)
        return faces, cross / norm[:, None], 0.5 * norm

    @property
    def faces(self) -> np.ndarray:
        """(F, 3) vertex indices, counter-clockwise seen from outside."""
        return self._triangles[0]

    @property
    def normals(self) -> np.ndarray:
        """(F, 3) outward unit facet normals ``n_i``."""
        return self._triangles[1]

    @property
    def areas(self) -> np.ndarray:
        """(F,) areas ``ΔA_i`` of the sphere's flat triangles (sum slightly below 4π)."""
        return self._triangles[2]

    @property
    def n_facets(self) -> int:
        return len(self.faces)

    @property
    def n_coefficients(self) -> int:
        return harmonic_count(self.degree, self.order)

    @cached_property
    def basis(self) -> np.ndarray:
        """(F, K) real harmonics at the facet normals."""
        return real_harmonics(self.normals, self.degree, self.order)
