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

import math
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
    then order (cosine before sine); ``Y_lm`` with the Condon–Shortley phase, as
    :func:`scipy.special.sph_harm_y`. The normalised associated Legendre functions come from
    the standard stable recurrences in degree (Holmes & Featherstone 2002, "A unified
    approach to the Clenshaw summation and the recursive computation of very high degree and
    order normalised associated Legendre functions", eqs. 11–13), so no scipy is loaded.

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
    if not 0 <= order <= degree:
        raise ValueError(f"need 0 ≤ order ≤ degree, got degree {degree}, order {order}")
    d = np.asarray(directions, float)
    cos_theta = np.clip(d[:, 2], -1.0, 1.0)
    sin_theta = np.sqrt(1.0 - cos_theta**2)
    phi = np.arctan2(d[:, 1], d[:, 0])
    # legendre[l][m]: √((2l+1)/4π (l−m)!/(l+m)!) P_l^m(cos θ), Condon–Shortley phase.
    legendre = [[np.full_like(cos_theta, 1.0 / math.sqrt(4.0 * math.pi))]]
    for l in range(1, degree + 1):
        row = []
        for m in range(min(l, order) + 1):
            if m == l:
                row.append(-math.sqrt((2 * l + 1) / (2 * l)) * sin_theta * legendre[l - 1][m - 1])
                continue
            a = math.sqrt((4 * l * l - 1) / (l * l - m * m))
            value = a * cos_theta * legendre[l - 1][m]
            if l - 2 >= m:
                b = math.sqrt(((l - 1) ** 2 - m * m) / (4 * (l - 1) ** 2 - 1))
                value = value - a * b * legendre[l - 2][m]
            row.append(value)
        legendre.append(row)
    columns = []
    for l in range(degree + 1):
        columns.append(legendre[l][0])
        for m in range(1, min(l, order) + 1):
            scaled = math.sqrt(2.0) * legendre[l][m]
            columns += [scaled * np.cos(m * phi), scaled * np.sin(m * phi)]
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
    def _rings(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per ring k = 0 … 2n (the poles are rings of one point): vertex count, azimuth
        offset (in steps of the ring) and index of the ring's first vertex."""
        n = self.nrows
        k = np.arange(2 * n + 1)
        count = np.where((k == 0) | (k == 2 * n), 1, 4 * np.minimum(k, 2 * n - k))
        return count, 0.5 * (k % 2), np.r_[0, np.cumsum(count)[:-1]]

    @cached_property
    def vertices(self) -> np.ndarray:
        """(V, 3) unit vertices: poles plus rings of ``4 min(k, 2n − k)`` points, ring k at
        polar angle ``kπ/(2n)`` and azimuths ``2π (j + (k mod 2)/2) / count``."""
        count, offset, _ = self._rings
        ring = np.repeat(np.arange(len(count)), count)
        j = np.arange(len(ring)) - np.repeat(np.cumsum(count) - count, count)
        theta = ring * np.pi / (2 * self.nrows)
        phi = 2 * np.pi * (j + offset[ring]) / count[ring]
        points = np.column_stack(
            [np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)]
        )
        points[0], points[-1] = [0.0, 0.0, 1.0], [0.0, 0.0, -1.0]
        return points

    @cached_property
    def _triangles(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The convex hull of the vertices in closed form: between two neighbouring rings,
        each edge of one ring and the vertex of the other ring nearest to the edge's middle
        azimuth (the first the edge's supporting plane meets when turned about the edge;
        never a tie, as the half-step offsets of odd rings keep the rings' middle azimuths
        apart). The same triangles as qhull's hull, checked in the tests."""
        count, offset, first = self._rings
        blocks = []
        for r in range(len(count) - 1):
            for a, b in ((r, r + 1), (r + 1, r)):
                if count[a] == 1:  # a pole has no edge
                    continue
                i = np.arange(count[a])
                middle = (i + offset[a] + 0.5) * count[b] / count[a] - offset[b]
                apex = np.rint(middle).astype(np.int64) % count[b]
                blocks.append(
                    np.column_stack([first[a] + i, first[a] + (i + 1) % count[a], first[b] + apex])
                )
        faces = np.concatenate(blocks)
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
