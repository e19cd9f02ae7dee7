"""Tiles of facets with similar normals, each bounded by a cone of normals.

The specular kernels skip, for each row, the tiles in which no facet can be both lit and
seen. A tile's normals lie within a cone (unit axis ``a``, half-angle ``θ``); every normal
``n`` of the tile then has ``n·L < 0`` when ``a·L < −sin θ`` (the cone of normals test:
Shirman & Abi-Ezzi 1993, "The cone of normals technique for fast processing of curved
patches"), so two dot products per tile decide for all its facets. The test is strict by a
margin (:data:`MARGIN`) far above the rounding of the facets' own cosines, so a skipped tile
is one whose every facet the plain loop would mask to zero: the sums are the same.

Tiles are made by recursive bisection of a material's normals (median split along the axis of
largest spread, a k-d tree on the sphere), each tile holding exactly :data:`TILE` facet slots;
the slots a tile does not fill are padding facets of zero area, which add exactly zero. The
bisection keeps neighbouring tiles close in direction, so the visible tiles of a row form
a few long runs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["MARGIN", "TILE", "TileLayout", "tile_layout"]

#: Facet slots per tile (one AVX vector of float32, two of float64).
TILE = 8
#: Added to ``sin θ`` of every cone: covers the rounding of float32 normals and cosines.
MARGIN = 1e-4


@dataclass(frozen=True)
class TileLayout:
    """Facets of one or more material blocks arranged in tiles of :data:`TILE` slots.

    Attributes
    ----------
    source : (S,) int64 array
        For every slot, the index of its facet in the input arrays (padding slots repeat a
        facet of their tile).
    padding : (S,) bool array
        Whether a slot is padding (zero area).
    cones : (4, S / TILE) float64 array
        Per tile: the cone axis (unit, body frame) and ``sin θ + MARGIN`` (2 for a tile whose
        normals span a hemisphere or more: never skipped).
    block_tiles : (B, 2) int64 array
        First and last (exclusive) tile of each block.
    """

    source: np.ndarray
    padding: np.ndarray
    cones: np.ndarray
    block_tiles: np.ndarray


def _split_counts(n: np.ndarray, size: int) -> np.ndarray:
    """Facets in the left half of segments of ``n`` facets: a multiple of ``size``, so every
    tile but the last of a block is full."""
    return size * ((n + 2 * size - 1) // (2 * size))


def _bisect(normals: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray]:
    """Order of ``normals`` and the bounds of its tiles (≤ ``size`` facets each).

    All segments of one level are split at once: each along the coordinate in which its
    normals spread most, at a multiple of ``size`` near its middle (a stable sort keeps
    ties in input order).
    """
    order = np.arange(len(normals))
    bounds = np.array([0, len(normals)])
    while True:
        counts = np.diff(bounds)
        split = counts > size
        if not split.any():
            return order, bounds
        segment = np.repeat(np.arange(len(counts)), counts)
        points = normals[order]
        low = np.minimum.reduceat(points, bounds[:-1], axis=0)
        high = np.maximum.reduceat(points, bounds[:-1], axis=0)
        axis = np.argmax(high - low, axis=1)
        key = points[np.arange(len(points)), axis[segment]]
        key = np.where(split[segment], key, 0.0)  # segments that stay keep their order
        order = order[np.lexsort((key, segment))]
        middle = bounds[:-1][split] + _split_counts(counts[split], size)
        bounds = np.sort(np.concatenate([bounds, middle]))


def _cones(normals: np.ndarray, padding: np.ndarray) -> np.ndarray:
    """``(axis, sin θ + MARGIN)`` of every tile, a (4, T) array, from the (T, size, 3)
    normals of its slots (padding slots repeat a facet of their tile)."""
    total = np.where(padding[..., None], 0.0, normals).sum(axis=1)
    length = np.linalg.norm(total, axis=1)
    axes = total / np.maximum(length, 1e-300)[:, None]
    cos_theta = np.min(np.einsum("tsk,tk->ts", normals, axes), axis=1)
    sines = np.sqrt(np.maximum(0.0, 1.0 - cos_theta**2)) + MARGIN
    sines = np.where((cos_theta > 0.0) & (length > 1e-9), sines, 2.0)
    return np.ascontiguousarray(np.vstack([axes.T, sines]))


def tile_layout(normals: np.ndarray, blocks: list[np.ndarray], size: int = TILE) -> TileLayout:
    """Cone tiles of each block of facets.

    Parameters
    ----------
    normals : (K, 3) float64 array
        Unit facet normals.
    blocks : list of int arrays
        Facet indices of each block (a material); every facet in exactly one block.
    size : int
        Slots per tile.
    """
    sources, paddings, block_tiles = [], [], []
    tiles = 0
    slot = np.arange(size)
    for members in blocks:
        order, bounds = _bisect(normals[members], size)
        counts = np.diff(bounds)
        padding = slot >= counts[:, None]
        # Slot j of tile t holds facet bounds[t] + j, or the tile's first facet as padding.
        sources.append(members[order][bounds[:-1, None] + np.where(padding, 0, slot)])
        paddings.append(padding)
        block_tiles.append((tiles, tiles + len(counts)))
        tiles += len(counts)
    source = np.concatenate(sources)
    padding = np.concatenate(paddings)
    return TileLayout(
        source=source.ravel(),
        padding=padding.ravel(),
        cones=_cones(normals[source], padding),
        block_tiles=np.array(block_tiles, dtype=np.int64).reshape(-1, 2),
    )
