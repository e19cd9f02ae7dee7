"""Compiled (numba) kernels of the coarse-to-fine visibility-table build
(:mod:`shapes.visibility.build`): the facets a node's neighbours decide, the rays of the
others, and their bits.

Every kernel releases the GIL, so that the build runs them on row ranges in a pool of threads.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["agreeing_facets", "facet_rays", "set_escaping"]

_JIT = {"nogil": True, "cache": True, "error_model": "numpy"}


@njit(**_JIT)
def agreeing_facets(bits, neighbours, segment_start, segment_word, segment_mask, out, needed):
    """Facets decided by their neighbours in a coarse-to-fine table build.

    For row ``r``: a facet whose points are all visible from every node ``neighbours[r]``
    gets its segments' bits set in ``out[r]``; one whose points are all hidden from them
    keeps zeros; any other gets ``needed[r, k] = True`` (to be ray-cast).

    Parameters
    ----------
    bits : (D, W) uint64
        The table's rows (those of the neighbours filled).
    neighbours : (R, m) int64
        Rows of ``bits``.
    segment_start, segment_word, segment_mask :
        The segments sorted by facet (``segment_start`` per facet, ``K + 1``).
    out : (R, W) uint64
        Zeros on entry.
    needed : (R, K) bool
        False on entry.
    """
    for r in range(neighbours.shape[0]):
        for k in range(segment_start.shape[0] - 1):
            s0, s1 = segment_start[k], segment_start[k + 1]
            if s0 == s1:
                continue
            full, empty = True, True
            for j in range(neighbours.shape[1]):
                row = neighbours[r, j]
                for s in range(s0, s1):
                    x = bits[row, segment_word[s]] & segment_mask[s]
                    full &= x == segment_mask[s]
                    empty &= x == 0
                if not (full or empty):
                    break
            if full:
                for s in range(s0, s1):
                    out[r, segment_word[s]] |= segment_mask[s]
            elif not empty:
                needed[r, k] = True


@njit(**_JIT)
def facet_rays(directions, normals, origins, needed, first, count, ray_origins, ray_directions):
    """The rays of a table build: from every point of every ``needed[r, k]`` facet toward
    direction ``r``, in row-major then point order; behind the point's facet
    (``n·d < 0``) toward the mirror direction ``d − 2 (n·d) n`` (horizon continuation,
    :mod:`shapes.visibility.table`).

    Parameters
    ----------
    directions : (R, 3) float32
        Unit directions (scene frame = body frame up to a uniform scaling).
    normals, origins : (P, 3) float32
        Facet normal and scene-frame origin of each point.
    needed : (R, K) bool
    first, count : (K,) int64
        The points of facet ``k`` are ``first[k] … first[k] + count[k] − 1``.
    ray_origins, ray_directions : (Σ needed · count, 3) float32
        Output.
    """
    i = 0
    for r in range(needed.shape[0]):
        dx, dy, dz = directions[r, 0], directions[r, 1], directions[r, 2]
        for k in range(needed.shape[1]):
            if not needed[r, k]:
                continue
            for p in range(first[k], first[k] + count[k]):
                nx, ny, nz = normals[p, 0], normals[p, 1], normals[p, 2]
                twice = 2.0 * min(dx * nx + dy * ny + dz * nz, 0.0)
                ray_directions[i, 0] = dx - twice * nx
                ray_directions[i, 1] = dy - twice * ny
                ray_directions[i, 2] = dz - twice * nz
                ray_origins[i, 0] = origins[p, 0]
                ray_origins[i, 1] = origins[p, 1]
                ray_origins[i, 2] = origins[p, 2]
                i += 1


@njit(**_JIT)
def set_escaping(needed, first, count, position, escapes, out):
    """Set in ``out[r]`` the bit (``position[p]``) of every point whose ray of
    :func:`facet_rays` (same order) escapes, ``escapes[i]``."""
    i = 0
    one = np.uint64(1)
    for r in range(needed.shape[0]):
        for k in range(needed.shape[1]):
            if not needed[r, k]:
                continue
            for p in range(first[k], first[k] + count[k]):
                if escapes[i]:
                    bit = position[p]
                    out[r, bit >> 6] |= one << np.uint64(bit & 63)
                i += 1
