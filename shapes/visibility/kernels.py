"""Compiled (numba) kernels of the visibility tables: bit-mask lookups of lit-and-seen area.

A visibility table stores, for every grid direction ``d`` and every sample point ``p`` of the
effective facets that can be shadowed, one bit: whether the ray from ``p`` toward ``d``
escapes the body (:mod:`shapes.visibility`). The points of a facet are packed into
*segments* of at most 64 points of equal weight, each inside one 64-bit word of a
direction's row of words, so that the weighted number of points passing two directions is a
handful of ``popcount(x & y)``.

The joint fraction of facet ``k`` for a Sun direction ``L`` and an observer direction ``V``
is interpolated per sample point: with ``a`` and ``b`` the three grid nodes around ``L`` and
``V`` (barycentric weights ``α_a``, ``β_b``), point ``p`` is lit with weight
``Σ_a α_a bit_a(p)`` and seen with weight ``Σ_b β_b bit_b(p)``, and

``J_k(L, V) = Σ_p w_p (Σ_a α_a bit_a(p)) (Σ_b β_b bit_b(p))``
``          = Σ_a Σ_b α_a β_b Σ_s ω_s popcount(x_{a,s} & x_{b,s})``

with ``ω_s`` the area share of one point of segment ``s``. At grid nodes this is the exact
fraction of sample points that are both lit and seen; it is symmetric in ``L`` and ``V``.

Speed (:func:`joint_rows`): the lookup reads per-cell entry lists
(:meth:`shapes.visibility.VisibilityTable._cells`): for every grid cell, one entry per facet
that faces one of the cell's corners and is not fully visible from all three, with the
facet's visible fraction ``f_a`` from each corner and its segments' words at the three
corners, stored contiguously. A facet in neither of the two cells' lists has ``J = 1`` (all
its points see the six corners) or faces away; one in a single list has the blend
``Σ_a α_a f_a`` of that side (the other side's words are all ones: ``Σ_b β_b = 1``); only a
facet in both lists, facing both directions, needs the nine popcounts per segment. Rows are
located first and the two runs of the row two ahead are prefetched, so their cache misses
overlap with work.
"""

from __future__ import annotations

import math

import llvmlite.ir as llvm_ir
import numpy as np
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic

__all__ = [
    "cell_fractions",
    "direction_fractions",
    "full_flags",
    "joint_rows",
    "pair_values",
    "segment_layout",
]

_JIT = {"nogil": True, "cache": True, "error_model": "numpy"}
_AHEAD = 2  # rows between a row's prefetch and its use


@intrinsic
def _popcount(typingctx, x):
    """Number of set bits of a uint64 (LLVM ``ctpop``: one instruction where the CPU has it),
    typed int64 (its conversion to float is one instruction, the unsigned one is not)."""
    if not isinstance(x, types.Integer):
        return None

    def codegen(context, builder, signature, args):
        return builder.ctpop(args[0])

    return types.int64(types.uint64), codegen


@intrinsic
def _prefetch(typingctx, array, index):
    """Hint the CPU to load the cache line of ``array[index]`` (1-D; LLVM ``prefetch``)."""
    if not isinstance(array, types.Array) or array.ndim != 1:
        return None

    def codegen(context, builder, signature, args):
        data = context.make_array(signature.args[0])(context, builder, args[0]).data
        address = builder.bitcast(builder.gep(data, [args[1]]), llvm_ir.IntType(8).as_pointer())
        i32 = llvm_ir.IntType(32)
        kind = llvm_ir.FunctionType(llvm_ir.VoidType(), [address.type, i32, i32, i32])
        prefetch = cgutils.get_or_insert_function(builder.module, kind, "llvm.prefetch.p0i8")
        builder.call(prefetch, [address, i32(0), i32(3), i32(1)])  # read, keep, data
        return context.get_dummy_value()

    return types.void(array, types.intp), codegen


@njit(**_JIT)
def _locate(x, y, z, n, flat_index):
    """Cell, corner nodes and barycentric weights of a direction on the cube-sphere grid.

    The same arithmetic as :meth:`shapes.visibility.directions.CubeSphereGrid.locate`. The cell of
    triangle ``t`` (0: lower, 1: upper) of lattice square ``(i, j)`` on face ``f`` is
    ``2 ((f n + i) n + j) + t``.
    """
    ax, ay, az = abs(x), abs(y), abs(z)
    if ax >= ay and ax >= az:
        s, t, m, axis = y, z, x, 0
    elif ay >= az:
        s, t, m, axis = z, x, y, 1
    else:
        s, t, m, axis = x, y, z, 2
    face = 2 * axis + (1 if m < 0 else 0)
    am = abs(m)
    half_n = 0.5 * n
    gu = (math.atan(s / am) * (4.0 / math.pi) + 1.0) * half_n
    gv = (math.atan(t / am) * (4.0 / math.pi) + 1.0) * half_n
    i = min(max(math.floor(gu), 0.0), n - 1.0)
    j = min(max(math.floor(gv), 0.0), n - 1.0)
    fu, fv = gu - i, gv - j
    stride = n + 1
    base = face * stride * stride + int(i) * stride + int(j)
    cell = 2 * ((face * n + int(i)) * n + int(j))
    n10 = flat_index[base + stride]
    n01 = flat_index[base + 1]
    if fu + fv <= 1.0:
        return cell, flat_index[base], n10, n01, 1.0 - fu - fv, fu, fv
    return cell + 1, flat_index[base + stride + 1], n10, n01, fu + fv - 1.0, 1.0 - fv, 1.0 - fu


@njit(**_JIT)
def _rotate(vectors, r, rotation):
    """``vectors[r] @ rotation``: body frame → the table's grid frame."""
    x, y, z = vectors[r, 0], vectors[r, 1], vectors[r, 2]
    return (
        x * rotation[0, 0] + y * rotation[1, 0] + z * rotation[2, 0],
        x * rotation[0, 1] + y * rotation[1, 1] + z * rotation[2, 1],
        x * rotation[0, 2] + y * rotation[1, 2] + z * rotation[2, 2],
    )


@njit(**_JIT)
def _pairs(x0, x1, x2, y0, y1, y2):
    """``popcount(x_a & y_b)`` for the nine node pairs, as floats (row-major in a, b)."""
    return (
        float(_popcount(x0 & y0)),
        float(_popcount(x0 & y1)),
        float(_popcount(x0 & y2)),
        float(_popcount(x1 & y0)),
        float(_popcount(x1 & y1)),
        float(_popcount(x1 & y2)),
        float(_popcount(x2 & y0)),
        float(_popcount(x2 & y1)),
        float(_popcount(x2 & y2)),
    )


@njit(**_JIT)
def joint_rows(
    light,
    view,
    rotation,
    n,
    flat_index,
    cell_start,
    cell_word_start,
    entry_value,
    entry_facet,
    entry_word,
    cell_words,
    segment_start,
    segment_weight,
    normals,
    facing,
    out,
):
    """Interpolated joint (lit and seen) fractions of every column for rows of ``(L, V)``.

    Parameters
    ----------
    light, view : (R, 3) float arrays
        Body-frame directions to the Sun and the observer (need not be unit).
    rotation : (3, 3) float64
        Grid frame → body frame.
    n : int
        Grid resolution; ``flat_index`` its ``(6 (n+1)²,)`` node lookup.
    cell_start : (cells + 1,) int64
        Entries of grid cell ``c``: ``cell_start[c]:cell_start[c+1]``, one per output column
        whose facet faces a corner of the cell and is not fully visible from all three.
    cell_word_start : (cells + 1,) int64
        Rows of ``cell_words`` holding the bits of cell ``c``'s entries (for prefetching).
    entry_value : (E, 4) float32 (float64 above 2²⁴ columns)
        Per entry: the visible fraction of its facet from each of the cell's three corners,
        and its output column (an integer-valued float: one record of 16 bytes per entry).
    entry_facet : (E,) int32
        Facet of each entry.
    entry_word : (E,) int32 (int64 above 2³¹ rows of ``cell_words``)
        First row of the entry's block in ``cell_words``: one row per segment of the facet.
    cell_words : (S_cells, 3) uint64
        A segment's points' bits from the cell's three corners (masked to the segment).
    segment_start : (K + 1,) int64
        Segments of facet ``k``: ``segment_start[k]:segment_start[k+1]``.
    segment_weight : (S,) float64
        Area share of each point of a segment.
    normals : (3, C) float64
        Normal of each column's facet in the grid frame (0 for unused columns).
    facing : bool
        True: columns turned away from ``L`` or ``V`` get 0. False: their value is
        unspecified (callers multiply by ``max(0, n·L) max(0, n·V)``).
    out : (R, C) float array
        Output.

    Notes
    -----
    All rows are located first; the entries of row ``r + 2``'s two cells are then prefetched
    while row ``r`` is computed, so that their cache misses overlap with work.
    """
    rows, columns = light.shape[0], out.shape[1]
    where = np.empty((rows, 2), np.int64)  # cells of L and V
    geometry = np.empty((rows, 12))  # L, V (grid frame), their corner weights
    for r in range(rows):
        lx, ly, lz = _rotate(light, r, rotation)
        vx, vy, vz = _rotate(view, r, rotation)
        cl, _, _, _, wa0, wa1, wa2 = _locate(lx, ly, lz, n, flat_index)
        cv, _, _, _, wb0, wb1, wb2 = _locate(vx, vy, vz, n, flat_index)
        where[r, 0], where[r, 1] = cl, cv
        g = geometry[r]
        g[0], g[1], g[2], g[3], g[4], g[5] = lx, ly, lz, vx, vy, vz
        g[6], g[7], g[8], g[9], g[10], g[11] = wa0, wa1, wa2, wb0, wb1, wb2
    values = entry_value.reshape(-1)
    words = cell_words.reshape(-1)
    for r in range(min(rows, _AHEAD)):
        _prefetch_cells(where[r], cell_start, cell_word_start, values, entry_word, words)
    stamp = np.full(columns, -1, np.int64)  # row in which the column got a V-side entry
    partner = np.zeros(columns, np.int64)  # that entry
    for r in range(rows):
        if r + _AHEAD < rows:
            _prefetch_cells(
                where[r + _AHEAD], cell_start, cell_word_start, values, entry_word, words
            )
        lx, ly, lz, vx, vy, vz, wa0, wa1, wa2, wb0, wb1, wb2 = (
            geometry[r, 0],
            geometry[r, 1],
            geometry[r, 2],
            geometry[r, 3],
            geometry[r, 4],
            geometry[r, 5],
            geometry[r, 6],
            geometry[r, 7],
            geometry[r, 8],
            geometry[r, 9],
            geometry[r, 10],
            geometry[r, 11],
        )
        cl, cv = where[r, 0], where[r, 1]
        for j in range(columns):
            out[r, j] = 1.0
        # one-sided entries: the blend of the corners' visible fractions
        for e in range(cell_start[cv], cell_start[cv + 1]):
            j = np.int64(entry_value[e, 3])
            out[r, j] = wb0 * entry_value[e, 0] + wb1 * entry_value[e, 1] + wb2 * entry_value[e, 2]
            stamp[j] = r
            partner[j] = e
        for e in range(cell_start[cl], cell_start[cl + 1]):
            j = np.int64(entry_value[e, 3])
            if stamp[j] != r:
                out[r, j] = (
                    wa0 * entry_value[e, 0] + wa1 * entry_value[e, 1] + wa2 * entry_value[e, 2]
                )
            elif _faces_both(normals, j, lx, ly, lz, vx, vy, vz):
                out[r, j] = _joint_words(
                    cell_words,
                    entry_word[e],
                    entry_word[partner[j]],
                    segment_start[entry_facet[e]],
                    segment_start[entry_facet[e] + 1],
                    segment_weight,
                    wa0,
                    wa1,
                    wa2,
                    wb0,
                    wb1,
                    wb2,
                )
        if facing:
            for j in range(columns):
                if not _faces_both(normals, j, lx, ly, lz, vx, vy, vz):
                    out[r, j] = 0.0


@njit(**_JIT)
def _prefetch_cells(cells, cell_start, cell_word_start, values, entry_word, words):
    """Prefetch the entries (values, word offsets, bits) of the two cells ``cells``, one
    64-byte cache line at a time."""
    for c in (cells[0], cells[1]):
        for i in range(4 * cell_start[c], 4 * cell_start[c + 1], 64 // values.itemsize):
            _prefetch(values, i)
        for i in range(cell_start[c], cell_start[c + 1], 64 // entry_word.itemsize):
            _prefetch(entry_word, i)
        for i in range(3 * cell_word_start[c], 3 * cell_word_start[c + 1], 8):
            _prefetch(words, i)


@njit(**_JIT)
def _faces_both(normals, k, lx, ly, lz, vx, vy, vz):
    """Column ``k``'s facet faces both ``L`` and ``V``."""
    nl = normals[0, k] * lx + normals[1, k] * ly + normals[2, k] * lz
    nv = normals[0, k] * vx + normals[1, k] * vy + normals[2, k] * vz
    return nl > 0.0 and nv > 0.0


@njit(**_JIT)
def _joint_words(cell_words, first_l, first_v, s0, s1, weight, wa0, wa1, wa2, wb0, wb1, wb2):
    """``Σ_s ω_s Σ_a Σ_b α_a β_b popcount(x_{a,s} & y_{b,s})`` of one facet, from the
    facet's word blocks in ``L``'s cell (rows from ``first_l``) and ``V``'s (``first_v``).

    A side whose three words are equal (the shadow does not move across the cell's points of
    that word) needs one word (``Σ α_a = 1``): three popcounts, or one when both sides are
    uniform, instead of nine; the result then differs from the nine-pair sum by rounding.
    """
    total = 0.0
    for i in range(s1 - s0):
        x0, x1, x2 = (
            cell_words[first_l + i, 0],
            cell_words[first_l + i, 1],
            cell_words[first_l + i, 2],
        )
        y0, y1, y2 = (
            cell_words[first_v + i, 0],
            cell_words[first_v + i, 1],
            cell_words[first_v + i, 2],
        )
        uniform_l = (x0 == x1) & (x1 == x2)
        uniform_v = (y0 == y1) & (y1 == y2)
        if uniform_l and uniform_v:
            value = float(_popcount(x0 & y0))
        elif uniform_l:
            value = (
                wb0 * float(_popcount(x0 & y0))
                + wb1 * float(_popcount(x0 & y1))
                + wb2 * float(_popcount(x0 & y2))
            )
        elif uniform_v:
            value = (
                wa0 * float(_popcount(x0 & y0))
                + wa1 * float(_popcount(x1 & y0))
                + wa2 * float(_popcount(x2 & y0))
            )
        else:
            p00, p01, p02, p10, p11, p12, p20, p21, p22 = _pairs(x0, x1, x2, y0, y1, y2)
            value = (
                wa0 * (wb0 * p00 + wb1 * p01 + wb2 * p02)
                + wa1 * (wb0 * p10 + wb1 * p11 + wb2 * p12)
                + wa2 * (wb0 * p20 + wb1 * p21 + wb2 * p22)
            )
        total += weight[s0 + i] * value
    return total


@njit(**_JIT)
def cell_fractions(cell_words, entry_word, entry_facet, segment_start, segment_weight, out):
    """Visible fraction of each entry's facet from its cell's three corners: ``out (E, 3)``."""
    for e in range(entry_word.shape[0]):
        k = entry_facet[e]
        s0 = segment_start[k]
        for a in range(3):
            total = 0.0
            for i in range(segment_start[k + 1] - s0):
                total += segment_weight[s0 + i] * float(_popcount(cell_words[entry_word[e] + i, a]))
            out[e, a] = total


@njit(**_JIT)
def pair_values(
    index_light,
    index_view,
    bits,
    full,
    segment_start,
    segment_word,
    segment_mask,
    segment_weight,
    out,
):
    """Joint fractions of every facet for the nine pairs of grid nodes around ``L`` and ``V``.

    ``out[r, a, b, k] = Σ_s ω_s popcount(x_{a,s} & x_{b,s})`` for nodes ``index_light[r, a]``
    and ``index_view[r, b]`` (1 for facets whose points are all visible from the six nodes):
    the caller blends them with its own (differentiable) barycentric weights.

    Parameters
    ----------
    index_light, index_view : (R, 3) int64
        Grid nodes around ``L`` and ``V``.
    bits, full, segment_start, segment_word, segment_mask, segment_weight :
        As :func:`joint_rows`.
    out : (R, 3, 3, K) float64
        Output.
    """
    n_facets = segment_start.shape[0] - 1
    for r in range(index_light.shape[0]):
        a0, a1, a2 = index_light[r, 0], index_light[r, 1], index_light[r, 2]
        b0, b1, b2 = index_view[r, 0], index_view[r, 1], index_view[r, 2]
        for k in range(n_facets):
            c, bit = k // 64, np.uint64(k % 64)
            every = full[a0, c] & full[a1, c] & full[a2, c] & full[b0, c] & full[b1, c]
            if (every & full[b2, c]) >> bit & np.uint64(1):
                for a in range(3):
                    for b in range(3):
                        out[r, a, b, k] = 1.0
                continue
            for a in range(3):
                for b in range(3):
                    out[r, a, b, k] = 0.0
            for s in range(segment_start[k], segment_start[k + 1]):
                w, m = segment_word[s], segment_mask[s]
                pairs = _pairs(
                    bits[a0, w] & m,
                    bits[a1, w] & m,
                    bits[a2, w] & m,
                    bits[b0, w],
                    bits[b1, w],
                    bits[b2, w],
                )
                for i in range(9):
                    out[r, i // 3, i % 3, k] += segment_weight[s] * pairs[i]


@njit(**_JIT)
def direction_fractions(bits, segment_start, segment_word, segment_mask, segment_weight, out):
    """Visible fraction of every facet at every grid direction: ``out (D, K)``.

    Facets without segments (never shadowed) get 1.
    """
    n_facets = segment_start.shape[0] - 1
    for d in range(bits.shape[0]):
        for k in range(n_facets):
            if segment_start[k] == segment_start[k + 1]:
                out[d, k] = 1.0
                continue
            total = 0.0
            for s in range(segment_start[k], segment_start[k + 1]):
                total += segment_weight[s] * float(
                    _popcount(bits[d, segment_word[s]] & segment_mask[s])
                )
            out[d, k] = total


@njit(**_JIT)
def full_flags(bits, segment_start, segment_word, segment_mask, full):
    """Per grid direction ``d``, bit ``k % 64`` of word ``k // 64`` of ``full[d]``: every
    point of facet ``k`` is visible from ``d`` (facets without segments and the padding bits
    are always set)."""
    n_facets = segment_start.shape[0] - 1
    for d in range(bits.shape[0]):
        for c in range(full.shape[1]):
            full[d, c] = ~np.uint64(0)
        for k in range(n_facets):
            flag = np.uint64(1) << np.uint64(k % 64)
            for s in range(segment_start[k], segment_start[k + 1]):
                if bits[d, segment_word[s]] & segment_mask[s] != segment_mask[s]:
                    full[d, k // 64] &= ~flag


def segment_layout(
    point_facet: np.ndarray, point_weight: np.ndarray, n_facets: int
) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Pack sample points into segments and 64-bit words.

    Runs of consecutive points of one facet with equal weight form segments of at most 64
    points; each segment lies inside one word (a segment that would straddle a word boundary
    starts the next word). The order of the points is the storage order: points of facets
    that face alike should be neighbours, so that a lookup reads few cache lines.

    Parameters
    ----------
    point_facet : (P,) int
        Effective facet of each point.
    point_weight : (P,) float
        Area share of each point in its facet (equal-weight points of a facet adjacent).
    n_facets : int
        Number of effective facets ``K``.

    Returns
    -------
    layout : dict
        ``segment_facet``, ``segment_word``, ``segment_shift``, ``segment_length`` (int
        arrays), ``segment_weight`` (float64) and ``n_words``.
    position : (P,) int64
        Bit position of each point in a direction's row (``64 · word + bit``).
    """
    facet = np.asarray(point_facet, dtype=np.int64)
    weight = np.asarray(point_weight, dtype=np.float64)
    starts = np.flatnonzero(
        np.concatenate([[True], (np.diff(facet) != 0) | (np.diff(weight) != 0)])
    )
    run_length = np.diff(np.append(starts, len(facet)))
    # split runs into segments of ≤ 64 points
    pieces = -(-run_length // 64)
    seg_first = np.repeat(starts, pieces) + 64 * (
        np.arange(pieces.sum()) - np.repeat(np.cumsum(pieces) - pieces, pieces)
    )
    seg_length = np.minimum(64, np.repeat(starts + run_length, pieces) - seg_first)
    seg_word = np.empty(len(seg_first), np.int64)
    seg_shift = np.empty(len(seg_first), np.int64)
    cursor = 0
    for i, length in enumerate(seg_length.tolist()):
        if cursor % 64 + length > 64:
            cursor += 64 - cursor % 64
        seg_word[i], seg_shift[i] = divmod(cursor, 64)
        cursor += length
    position = np.repeat(64 * seg_word + seg_shift - seg_first, seg_length) + np.arange(len(facet))
    layout = {
        "segment_facet": facet[seg_first] if len(facet) else np.zeros(0, np.int64),
        "segment_word": seg_word,
        "segment_shift": seg_shift,
        "segment_length": seg_length.astype(np.int64),
        "segment_weight": weight[seg_first] if len(facet) else np.zeros(0),
        "n_words": np.int64(-(-cursor // 64)),
    }
    if np.any(layout["segment_facet"] >= n_facets):
        raise ValueError("sample point of a facet beyond the facet count")
    return layout, position
