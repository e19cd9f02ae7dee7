"""Packed per-facet flags of a visibility table's grid: which facets face a direction, and
which are partly shadowed around a grid cell.

The flags are kept packed (one bit per facet, little-endian bytes) and unpacked one block of
rows at a time: a ``(directions, K)`` or ``(cells, K)`` bool array of a 10⁵-facet model would
take 0.4–0.8 GB.
"""

from __future__ import annotations

import numpy as np

__all__ = ["facing_flags", "partial_cells"]

_BLOCK_ROWS = 512  # directions or cells per unpacked block


def facing_flags(directions: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """``(D, 8 ⌈K/64⌉)`` uint8: bit ``k`` set where facet ``k`` faces direction ``d``
    (``n_k · d > 0``), the byte layout of a row of little-endian uint64 words.

    Parameters
    ----------
    directions : (D, 3) float
        Unit directions, grid frame.
    normals : (K, 3) float
        Facet normals, same frame.
    """
    out = np.zeros((len(directions), 8 * -(-len(normals) // 64)), dtype=np.uint8)
    for first in range(0, len(directions), _BLOCK_ROWS):
        front = directions[first : first + _BLOCK_ROWS] @ normals.T > 0.0
        packed = np.packbits(front, axis=1, bitorder="little")
        out[first : first + _BLOCK_ROWS, : packed.shape[1]] = packed
    return out


def partial_cells(
    full: np.ndarray, front: np.ndarray, corners: np.ndarray, n_facets: int
) -> tuple[np.ndarray, np.ndarray]:
    """``(cell, facet)`` of every facet that faces one of a cell's corners and is not fully
    visible from all three, in cell then facet order.

    Parameters
    ----------
    full, front : (D, bytes) uint8
        Packed flags (:func:`facing_flags` layout) of "every point visible" and "facing".
    corners : (cells, 3) int
        Corner nodes of each cell.
    n_facets : int
    """
    cells, facets = [], []
    for first in range(0, len(corners), _BLOCK_ROWS):
        c = corners[first : first + _BLOCK_ROWS]
        every = full[c[:, 0]] & full[c[:, 1]] & full[c[:, 2]]
        faces = front[c[:, 0]] | front[c[:, 1]] | front[c[:, 2]]
        partial = np.unpackbits(~every & faces, axis=1, bitorder="little")[:, :n_facets]
        cell, facet = np.nonzero(partial)
        cells.append(cell + first)
        facets.append(facet)
    return np.concatenate(cells), np.concatenate(facets)
