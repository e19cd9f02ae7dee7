"""Self-shadowing as a sparse correction of the unshadowed facet sums (numba).

With a visibility table, the flux of a row is ``Σ_i t_i J_i`` (``t_i`` the facet's term
``ρ A (n·L)(n·V)``, ``J_i`` its joint lit-and-seen fraction). Only a few facets of a row
have ``J_i < 1``: those facing both ``L`` and ``V`` and listed in the table's entries of
the grid cells around ``L`` or ``V`` (about 30 of Itokawa's 768 facets and 80 of Bennu's
2692 at random geometry). So the renderer sums every facet unshadowed with the fast
kernels and subtracts

``Σ_{i listed} (1 − J_i) t_i``

evaluated only for the listed facets: :func:`subtract_shadowed` looks each row's facets up
(:func:`shapes.joint_visibility.partly_shadowed`, the fractions of the dense lookup to the
last bit) and sums their terms by the BRDF's own row kernel
(:data:`lightcurve.kernels.brdf_sums.ROW_KERNELS`) on a small table of those facets, with
``1 − J_i`` as the kernel's shadow factor. No (rows × facets) factor is formed, filled or
read. The result equals the dense product ``Σ t_i J_i`` up to the rounding of the
subtraction (relative ``~ε · Σ t_i / Σ t_i J_i``).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from lightcurve.kernels.brdf_sums import (
    ANISOTROPIC,
    ASHIKHMIN_SHIRLEY,
    COOK_TORRANCE,
    LAMBERT,
    LOMMEL_SEELIGER,
    PHONG,
    ROW_KERNELS,
    TWO_LOBE,
)
from lightcurve.kernels.tiles import TILE
from shapes.joint_visibility import (
    listed_fractions,
    listed_pairs,
    locate_rows,
    prefetch_entries,
)

__all__ = ["subtract_shadowed"]

_JIT = {"error_model": "numpy", "nogil": True, "cache": True}
_AHEAD = 2  # rows between a row's prefetch and its use
_lambert = ROW_KERNELS[LAMBERT]
_phong = ROW_KERNELS[PHONG]
_cook_torrance = ROW_KERNELS[COOK_TORRANCE]
_ashikhmin_shirley = ROW_KERNELS[ASHIKHMIN_SHIRLEY]
_anisotropic = ROW_KERNELS[ANISOTROPIC]
_lommel_seeliger = ROW_KERNELS[LOMMEL_SEELIGER]
_two_lobe = ROW_KERNELS[TWO_LOBE]


@njit(**_JIT)
def _block_sum(kind, light, view, facets, cones, tiles, p, factor, out):
    """``out[0] += Σ_i ρ A (n·L)(n·V) factor_i`` over the first ``tiles`` tiles of
    ``facets`` for the one row of ``light``/``view``, by the BRDF's row kernel."""
    if kind == LAMBERT:
        _lambert(light, view, facets, cones, 0, tiles, p, factor, out, 0, 1)
    elif kind == PHONG:
        _phong(light, view, facets, cones, 0, tiles, p, factor, out, 0, 1)
    elif kind == COOK_TORRANCE:
        _cook_torrance(light, view, facets, cones, 0, tiles, p, factor, out, 0, 1)
    elif kind == ASHIKHMIN_SHIRLEY:
        _ashikhmin_shirley(light, view, facets, cones, 0, tiles, p, factor, out, 0, 1)
    elif kind == ANISOTROPIC:
        _anisotropic(light, view, facets, cones, 0, tiles, p, factor, out, 0, 1)
    elif kind == LOMMEL_SEELIGER:
        _lommel_seeliger(light, view, facets, cones, 0, tiles, p, factor, out, 0, 1)
    else:
        _two_lobe(light, view, facets, cones, 0, tiles, p, factor, out, 0, 1)


@njit(**_JIT)
def subtract_shadowed(
    light,
    view,
    rotation,
    n,
    flat_index,
    cell_start,
    cell_word_start,
    entry_facet,
    entry_word,
    cell_words,
    ones,
    segment_start,
    segment_weight,
    normals,
    facets,
    facet_block,
    kinds,
    parameters,
    sums,
    start,
    stop,
):
    """``sums[r] −= Σ_{i listed} (1 − J_i) ρ_i A_i (n_i·L)(n_i·V)`` for rows ``start:stop``.

    Parameters
    ----------
    light, view : (R, 3) float64 arrays
        Body-frame unit vectors to the Sun and the observer (C order).
    rotation, n, flat_index, cell_start, cell_word_start, entry_facet, entry_word,
    cell_words, ones, segment_start, segment_weight, normals :
        :meth:`shapes.VisibilityTable.cell_entries` and the grid resolution ``n``.
    facets : (K, 10) array
        :func:`lightcurve.kernels.facet_table` of the table's facets (its order), in the
        compute dtype, transposed (one facet's numbers contiguous: they are gathered).
    facet_block : (K,) int64
        Material block of each facet.
    kinds : (B,) int64
        Kernel code of each block (:data:`lightcurve.kernels.brdf_sums.KINDS`).
    parameters : (B, 8) float64
        Parameter row of each block (:func:`lightcurve.kernels.block_parameters`).
    sums : (R,) float64
        The unshadowed facet sums of the rows, corrected in place.
    start, stop : int
        Rows to correct.
    """
    k_facets = facets.shape[0]
    t = facets.dtype.type
    stamp = np.full(k_facets, -1, np.int64)
    slot = np.zeros(k_facets, np.int64)
    listed = np.empty(k_facets + 1, np.int64)
    words = np.empty((k_facets + 1, 2), np.int64)
    value = np.empty(k_facets + 1)
    slots = -(-k_facets // TILE) * TILE
    table = np.empty((10, slots), facets.dtype)
    factor = np.empty((1, slots), facets.dtype)
    # cones that never skip a tile: a sine of 2 passes every test
    cones = np.zeros((4, slots // TILE), facets.dtype)
    cones[0, :] = t(1.0)
    cones[3, :] = t(2.0)
    one_light = np.empty((1, 3))
    one_view = np.empty((1, 3))
    total = np.zeros(1)
    where, geometry = locate_rows(light, view, rotation, n, flat_index, start, stop)
    flat_words = cell_words.reshape(-1)
    rows = stop - start
    for i in range(min(rows, _AHEAD)):
        prefetch_entries(where[i], cell_start, cell_word_start, entry_facet, entry_word, flat_words)
    for i in range(rows):
        if i + _AHEAD < rows:
            prefetch_entries(
                where[i + _AHEAD], cell_start, cell_word_start, entry_facet, entry_word, flat_words
            )
        g = geometry[i]
        count = listed_pairs(
            where[i], g, cell_start, entry_facet, entry_word, normals, ones, i, stamp, slot,
            listed, words,
        )  # fmt: skip
        if count == 0:
            continue
        listed_fractions(count, listed, words, cell_words, segment_start, segment_weight, g, value)
        r = start + i
        for c in range(3):
            one_light[0, c] = light[r, c]
            one_view[0, c] = view[r, c]
        for b in range(len(kinds)):
            used = 0
            for j in range(count):
                k = listed[j]
                if facet_block[k] == b and value[j] < 1.0:
                    for c in range(10):
                        table[c, used] = facets[k, c]
                    factor[0, used] = t(1.0 - value[j])
                    used += 1
            if used == 0:
                continue
            tiles = -(-used // TILE)
            for j in range(used, tiles * TILE):  # padding: a listed facet of zero area
                for c in range(10):
                    table[c, j] = table[c, 0]
                table[3, j] = t(0.0)
                factor[0, j] = t(0.0)
            total[0] = 0.0
            _block_sum(
                kinds[b], one_light, one_view, table, cones, tiles, parameters[b], factor, total
            )
            sums[r] -= total[0]
