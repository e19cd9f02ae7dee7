"""A quasi-uniform grid of directions on the unit sphere with fast barycentric lookup.

The grid is the equiangular cube sphere (the gnomonic cube of climate models and HEALPix's
cousin): each of the six cube faces carries an ``(n+1) × (n+1)`` lattice of nodes equally
spaced in angle, ``u, v ∈ [−1, 1]`` with ``s/|m| = tan(π u / 4)``, ``t/|m| = tan(π v / 4)``
for the direction components ``(s, t, m)`` of that face; nodes on shared edges and corners are
stored once. There are ``6 n² + 2`` directions; cell solid angles vary by less than a factor
1.5, neighbouring nodes are about ``π / (2 n)`` rad apart.

A direction is located in O(1) without search: its major axis gives the face, the two
angles give the cell, and the cell is split along its diagonal into two triangles whose
three corner nodes and barycentric weights interpolate any tabulated function continuously
over the whole sphere (also across face seams, which are shared node rows). The lookup is
written once against the array API and runs on numpy arrays and torch tensors.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from array_api_compat import array_namespace

__all__ = ["CubeSphereGrid"]

# (s, t, m) component order of a face whose major axis is x, y or z.
_FACE_AXES = ((1, 2, 0), (2, 0, 1), (0, 1, 2))


class CubeSphereGrid:
    """Equiangular cube-sphere grid of resolution ``n`` (``6 n² + 2`` unit directions).

    Parameters
    ----------
    n : int
        Cells along each cube-face edge (≥ 1). ``n = 26`` gives 4058 directions ~3.5° apart.

    Attributes
    ----------
    directions : (6 n² + 2, 3) float
        Unit vectors of the nodes.
    node_index : (6, n + 1, n + 1) int
        Node ``(face, i, j)`` → row of ``directions``; face ``2·axis + (m < 0)``.
    """

    def __init__(self, n: int) -> None:
        if int(n) != n or n < 1:
            raise ValueError(f"cube-sphere resolution must be a positive integer, got {n!r}")
        self.n = int(n)
        ticks = np.tan(np.linspace(-1.0, 1.0, self.n + 1) * (math.pi / 4.0))
        ticks[0], ticks[-1] = -1.0, 1.0
        s, t = np.meshgrid(ticks, ticks, indexing="ij")
        nodes = np.empty((6, self.n + 1, self.n + 1, 3))
        for axis, order in enumerate(_FACE_AXES):
            for sign in (0, 1):
                face = nodes[2 * axis + sign]
                face[..., order[0]] = s
                face[..., order[1]] = t
                face[..., order[2]] = -1.0 if sign else 1.0
        flat = nodes.reshape(-1, 3)
        unique, first, inverse = np.unique(flat, axis=0, return_index=True, return_inverse=True)
        # keep the order of first appearance so node 0 is face 0's corner, and so on
        order = np.argsort(first)
        rank = np.empty_like(order)
        rank[order] = np.arange(len(order))
        self.directions = unique[order] / np.linalg.norm(unique[order], axis=1, keepdims=True)
        self.node_index = rank[inverse.reshape(-1)].reshape(6, self.n + 1, self.n + 1)
        self._flat_index = self.node_index.reshape(-1)
        self._torch_index: dict[Any, Any] = {}

    def __len__(self) -> int:
        return len(self.directions)

    def refinement_levels(self) -> list[tuple[np.ndarray, np.ndarray | None]]:
        """The nodes in coarse-to-fine order, each level's with its nearest nodes of the
        levels before.

        For an even ``n`` the nodes with even ``(i, j)`` on their face are the grid of
        resolution ``n / 2`` (level 0, no neighbours); level 1 are the midpoints of its cell
        edges (the two ends of the edge, ``π / (2 n)`` rad away, and the far corners of the
        two cells beside it, about ``√5 π / (2 n)``; clipped at a face's border); level 2 the cell
        centres (the four level-1 nodes around them, ``π / (2 n)`` rad away, and the cell's
        four corners, ``√2 π / (2 n)``). An odd ``n``
        has one level: every node.

        Returns
        -------
        list of (nodes, neighbours)
            ``nodes (M,)`` rows of :attr:`directions`; ``neighbours (M, m)`` rows of earlier
            levels, or None for level 0. Every node appears in exactly one level.
        """
        index = self.node_index
        if self.n % 2:
            return [(np.arange(len(self)), None)]
        coarse = np.unique(index[:, ::2, ::2])
        face, i, j = np.meshgrid(*(np.arange(k) for k in index.shape), indexing="ij")
        nodes, neighbours = [], []
        for odd, other in ((i, j), (j, i)):  # midpoints of edges along i, then along j
            at = (odd % 2 == 1) & (other % 2 == 0)
            steps = [(da, db) for da in (-1, 1) for db in (0, -2, 2)]
            rows = [
                (odd[at] + da, other[at] + db) if odd is i else (other[at] + db, odd[at] + da)
                for da, db in steps
            ]
            nodes.append(index[at])
            neighbours.append(
                np.stack(
                    [
                        index[face[at], np.clip(r, 0, self.n), np.clip(c, 0, self.n)]
                        for r, c in rows
                    ],
                    axis=1,
                )
            )
        edge, first = np.unique(np.concatenate(nodes), return_index=True)  # seams: twice
        edge_neighbours = np.concatenate(neighbours)
        centre = index[:, 1::2, 1::2]
        around = (
            index[:, :-1:2, 1::2],
            index[:, 2::2, 1::2],
            index[:, 1::2, :-1:2],
            index[:, 1::2, 2::2],
            index[:, :-1:2, :-1:2],
            index[:, 2::2, :-1:2],
            index[:, :-1:2, 2::2],
            index[:, 2::2, 2::2],
        )
        return [
            (coarse, None),
            (edge, edge_neighbours[first]),
            (centre.ravel(), np.stack([a.ravel() for a in around], axis=1)),
        ]

    def locate(self, directions: Any) -> tuple[Any, Any]:
        """Corner nodes and barycentric weights of the grid triangle containing each direction.

        Parameters
        ----------
        directions : (..., 3) array or torch.Tensor
            Non-zero direction vectors (need not be unit).

        Returns
        -------
        index : (..., 3) int array
            Rows of :attr:`directions`.
        weights : (..., 3) float array
            Non-negative, summing to 1; same dtype (and device) as the input.
        """
        xp = array_namespace(directions)
        d = directions
        x, y, z = d[..., 0], d[..., 1], d[..., 2]
        ax, ay, az = xp.abs(x), xp.abs(y), xp.abs(z)
        major_x = (ax >= ay) & (ax >= az)
        major_y = ~major_x & (ay >= az)
        s = xp.where(major_x, y, xp.where(major_y, z, x))
        t = xp.where(major_x, z, xp.where(major_y, x, y))
        m = xp.where(major_x, x, xp.where(major_y, y, z))
        axis = xp.where(major_x, 0, xp.where(major_y, 1, 2))
        face = 2 * axis + xp.astype(m < 0, axis.dtype)
        am = xp.abs(m)
        half_n = 0.5 * self.n
        gu = (xp.atan(s / am) * (4.0 / math.pi) + 1.0) * half_n
        gv = (xp.atan(t / am) * (4.0 / math.pi) + 1.0) * half_n
        i = xp.clip(xp.floor(gu), 0, self.n - 1)
        j = xp.clip(xp.floor(gv), 0, self.n - 1)
        fu, fv = gu - i, gv - j
        stride = self.n + 1
        base = face * stride * stride + xp.astype(i, face.dtype) * stride + xp.astype(j, face.dtype)
        flat = self._index_for(xp, directions)
        n00, n10, n01, n11 = (
            flat[base],
            flat[base + stride],
            flat[base + 1],
            flat[base + stride + 1],
        )
        lower = fu + fv <= 1.0
        index = xp.stack([xp.where(lower, n00, n11), n10, n01], axis=-1)
        weights = xp.stack(
            [
                xp.where(lower, 1.0 - fu - fv, fu + fv - 1.0),
                xp.where(lower, fu, 1.0 - fv),
                xp.where(lower, fv, 1.0 - fu),
            ],
            axis=-1,
        )
        return index, weights

    def _index_for(self, xp: Any, like: Any) -> Any:
        """The flat node lookup as an array of the caller's kind (cached per torch device)."""
        if isinstance(like, np.ndarray):
            return self._flat_index
        device = getattr(like, "device", None)
        if device not in self._torch_index:
            self._torch_index[device] = xp.asarray(self._flat_index, device=device)
        return self._torch_index[device]
