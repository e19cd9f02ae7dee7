"""Packed per-facet flags of a visibility table's grid: which facets face a direction, and
which are partly shadowed around a grid cell; the words of those facets at the cell's corners.

The flags are kept packed (one bit per facet, little-endian bytes) and unpacked one block of
rows at a time: a ``(directions, K)`` or ``(cells, K)`` bool array of a 10⁵-facet model would
take 0.4–0.8 GB.
"""

from __future__ import annotations

import numpy as np

__all__ = ["cell_corners", "cell_entries", "corner_words", "facing_flags", "partial_cells"]

_BLOCK_ROWS = 512  # directions or cells per unpacked block
_ENTRY_BLOCK = 1 << 20  # cell entries whose words are gathered at a time


def cell_entries(
    bits: np.ndarray,
    segments: dict[str, np.ndarray],
    *,
    node_index: np.ndarray,
    directions: np.ndarray,
    normals: np.ndarray,
) -> dict[str, np.ndarray]:
    """Per grid cell, the facets that face one of its corners and are not fully visible
    from all three, with their points' bits at the three corners.

    Returns ``cell_start`` (cells + 1), ``entry_facet`` (E, int32) in cell order;
    ``entry_word`` (E): first row of the entry's block of ``cell_words`` (S_cells, 3), one
    row per segment of the facet (the segment's bits at each corner, masked to the segment).
    A lookup then reads two cells' entries, each a contiguous run, instead of six scattered
    rows. ``entry_word`` is int32 when the rows fit (a 5·10⁴-facet model has ~2.5·10⁷
    entries: half the memory of int64).

    Parameters
    ----------
    bits : (D, W) uint64
        The table's bits.
    segments : dict
        ``segment_start`` (K + 1), ``segment_word``, ``segment_mask`` (S) of the segments
        sorted by facet.
    node_index : (6, n + 1, n + 1) int
        The grid's node of each face's grid point.
    directions : (D, 3) float
        Grid directions, grid frame.
    normals : (K, 3) float
        Facet normals, grid frame.
    """
    from shapes.visibility.kernels import full_flags  # numba: compiled on first use

    start, k = segments["segment_start"], len(normals)
    full_words = np.empty((len(bits), -(-k // 64)), dtype=np.uint64)
    full_flags(bits, start, segments["segment_word"], segments["segment_mask"], full_words)
    corners = cell_corners(node_index)
    front = facing_flags(directions, normals)
    cell, facet = partial_cells(full_words.view(np.uint8), front, corners, k)
    del full_words, front
    count = np.diff(start)[facet]
    entry_word = np.cumsum(count, dtype=np.int32 if count.sum() < 2**31 else np.int64)
    entry_word -= count
    del count
    cell_words = corner_words(
        bits,
        corners,
        cell,
        facet,
        segment_start=start,
        segment_word=segments["segment_word"],
        segment_mask=segments["segment_mask"],
    )
    return {
        "cell_start": np.searchsorted(cell, np.arange(len(corners) + 1)).astype(np.int64),
        "entry_facet": facet,
        "entry_word": entry_word,
        "cell_words": cell_words,
    }


def cell_corners(node_index: np.ndarray) -> np.ndarray:
    """(cells, 3) corner nodes of the grid's triangles, in the lookup kernels' cell order.

    ``node_index`` : (6, n + 1, n + 1) int, the node of each face's grid point.
    """
    ni = node_index
    lower = np.stack([ni[:, :-1, :-1], ni[:, 1:, :-1], ni[:, :-1, 1:]], axis=-1)
    upper = np.stack([ni[:, 1:, 1:], ni[:, 1:, :-1], ni[:, :-1, 1:]], axis=-1)
    return np.stack([lower, upper], axis=3).reshape(-1, 3)


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
    """``(cell, facet)`` (int32 arrays) of every facet that faces one of a cell's corners and
    is not fully visible from all three, in cell then facet order.

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
        cells.append((cell + first).astype(np.int32))
        facets.append(facet.astype(np.int32))
    return np.concatenate(cells), np.concatenate(facets)


def corner_words(
    bits: np.ndarray,
    corners: np.ndarray,
    cell: np.ndarray,
    facet: np.ndarray,
    *,
    segment_start: np.ndarray,
    segment_word: np.ndarray,
    segment_mask: np.ndarray,
) -> np.ndarray:
    """``(S_cells, 3)`` uint64: for each entry ``(cell, facet)`` (a facet partly shadowed
    around a cell), the words of the facet's segments at the cell's three corners, masked
    to the segment; entry after entry, segment after segment.

    The entries are gathered a block at a time: index arrays over every entry at once take
    several GB at 10⁵ facets.

    Parameters
    ----------
    bits : (D, W) uint64
        The table's bits.
    corners : (cells, 3) int
        Corner nodes of each cell.
    cell, facet : (E,) int
        The entries.
    segment_start : (K + 1,) int
        First segment of each facet.
    segment_word, segment_mask : (S,) arrays
        Word of each segment and its bits within the word.
    """
    count = np.diff(segment_start)
    out = np.empty((int(count[facet].sum()), 3), dtype=np.uint64)
    row0 = 0
    for first in range(0, len(facet), _ENTRY_BLOCK):
        block = facet[first : first + _ENTRY_BLOCK]
        n = count[block]
        entry = np.repeat(np.arange(len(n)), n)
        segment = segment_start[block][entry] + np.arange(len(entry))
        segment -= np.repeat(np.cumsum(n) - n, n)
        nodes = corners[cell[first : first + _ENTRY_BLOCK][entry]]
        np.bitwise_and(
            bits[nodes, segment_word[segment, None]],
            segment_mask[segment, None],
            out=out[row0 : row0 + len(entry)],
        )
        row0 += len(entry)
    return out
