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

Speed: per-direction bit sets of the facets whose points are *all* visible (``full``) and
of those none of whose points is (``empty``), reduced over the three corners of every grid
cell, settle 64 facets at a time with a few ANDs: 1 when all points see the six corners, 0
when none sees the three corners of ``L``'s or of ``V``'s cell. Only facets that are partly
shadowed around ``L`` or ``V`` and face both are looked up point by point, and within them
a word of points that is all ones at the three nodes of one side needs only the other
side's three words (none when all ones on both sides).
"""

from __future__ import annotations

import math

import llvmlite.ir as llvm_ir
import numpy as np
from numba import njit, types
from numba.extending import intrinsic

__all__ = [
    "direction_fractions",
    "full_flags",
    "joint_rows",
    "pair_values",
    "segment_layout",
]

_JIT = {"nogil": True, "cache": True, "error_model": "numpy"}


@intrinsic
def _popcount(typingctx, x):
    """Number of set bits of a uint64 (LLVM ``ctpop``: one instruction where the CPU has it)."""
    if not isinstance(x, types.Integer):
        return None

    def codegen(context, builder, signature, args):
        return builder.ctpop(args[0])

    return types.uint64(types.uint64), codegen


@intrinsic
def _trailing_zeros(typingctx, x):
    """Index of the lowest set bit of a non-zero uint64 (LLVM ``cttz``)."""
    if not isinstance(x, types.Integer):
        return None

    def codegen(context, builder, signature, args):
        return builder.cttz(args[0], llvm_ir.Constant(llvm_ir.IntType(1), 1))

    return types.uint64(types.uint64), codegen


@njit(**_JIT)
def _locate(x, y, z, n, flat_index):
    """Cell, corner nodes and barycentric weights of a direction on the cube-sphere grid.

    The same arithmetic as :meth:`shapes.directions.CubeSphereGrid.locate`. The cell of
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
def _word(row_words, row_rank, compact, d, w):
    """Word ``w`` of grid direction ``d`` from the sparse rows: all ones unless stored.

    ``row_words[d]`` flags the words of row ``d`` with a point that does not see the
    direction; they are stored in ``compact`` in row order, ``row_rank[d, c]`` being the
    index of the first stored word of chunk ``c`` (64 words) of row ``d``.
    """
    c = w >> 6
    flags = row_words[d, c]
    bit = np.uint64(w & 63)
    below = flags & ((np.uint64(1) << bit) - np.uint64(1))
    value = compact[row_rank[d, c] + np.int64(_popcount(below))]
    return value if (flags >> bit) & np.uint64(1) else ~np.uint64(0)


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
    row_words,
    row_rank,
    compact,
    cell_partial,
    cell_front,
    cell_hidden,
    normals,
    segment_start,
    segment_word,
    segment_mask,
    segment_weight,
    facing,
    out,
):
    """Interpolated joint (lit and seen) fractions of every facet for rows of ``(L, V)``.

    Parameters
    ----------
    light, view : (R, 3) float arrays
        Body-frame directions to the Sun and the observer (need not be unit).
    rotation : (3, 3) float64
        Grid frame → body frame.
    n : int
        Grid resolution; ``flat_index`` its ``(6 (n+1)²,)`` node lookup.
    row_words, row_rank, compact :
        The per-direction bit rows, stored sparsely (see :func:`_word`).
    cell_partial, cell_front, cell_hidden : (cells, C) uint64
        Per grid cell, bit ``k % 64`` of word ``k // 64``: facet ``k`` has a point that
        does not see one of the cell's corners; facet ``k`` faces one of them; no point of
        facet ``k`` sees any of them. A facet facing ``L`` faces a corner of ``L``'s cell
        (``L`` is their positive blend); a facet all of whose points see the six corners
        has joint fraction 1, one hidden from the three corners of ``L``'s or ``V``'s cell
        has 0.
    normals : (3, K) float64
        Facet normals in the grid frame.
    segment_start : (K + 1,) int64
        Segments of facet ``k``: ``segment_start[k]:segment_start[k+1]``.
    segment_word, segment_mask, segment_weight : (S,) arrays
        Word, bit mask within it, and area share of each of its points.
    facing : bool
        True: facets turned away from ``L`` or ``V`` get 0. False: they get 1 or their
        table value (cheaper; for callers that multiply by ``max(0, n·L) max(0, n·V)``).
    out : (R, K) float array
        Output.
    """
    n_facets = normals.shape[1]
    chunks = cell_partial.shape[1]
    stored_l = np.empty(row_words.shape[1], np.uint64)
    stored_v = np.empty(row_words.shape[1], np.uint64)
    nothing = np.zeros(row_words.shape[1], np.uint64)
    for r in range(light.shape[0]):
        lx, ly, lz = _rotate(light, r, rotation)
        vx, vy, vz = _rotate(view, r, rotation)
        if facing:
            for k in range(n_facets):
                nl = normals[0, k] * lx + normals[1, k] * ly + normals[2, k] * lz
                nv = normals[0, k] * vx + normals[1, k] * vy + normals[2, k] * vz
                out[r, k] = 1.0 if (nl > 0.0) & (nv > 0.0) else 0.0
        else:
            for k in range(n_facets):
                out[r, k] = 1.0
        cl, a0, a1, a2, wa0, wa1, wa2 = _locate(lx, ly, lz, n, flat_index)
        cv, b0, b1, b2, wb0, wb1, wb2 = _locate(vx, vy, vz, n, flat_index)
        # words with a point that does not see one of L's (V's) nodes; all others are ones
        for c in range(row_words.shape[1]):
            stored_l[c] = row_words[a0, c] | row_words[a1, c] | row_words[a2, c]
            stored_v[c] = row_words[b0, c] | row_words[b1, c] | row_words[b2, c]
        light_nodes = (a0, a1, a2, wa0, wa1, wa2)
        view_nodes = (b0, b1, b2, wb0, wb1, wb2)
        for c in range(chunks):
            front = cell_front[cl, c] & cell_front[cv, c]
            hidden = (cell_hidden[cl, c] | cell_hidden[cv, c]) & front
            partial_l = cell_partial[cl, c] & front & ~hidden
            partial_v = cell_partial[cv, c] & front & ~hidden
            while hidden != 0:  # every popcount is 0
                k = c * 64 + np.int64(_trailing_zeros(hidden))
                hidden &= hidden - np.uint64(1)
                out[r, k] = 0.0
            todo = partial_l | partial_v
            while todo != 0:
                bit = _trailing_zeros(todo)
                todo &= todo - np.uint64(1)
                k = c * 64 + np.int64(bit)
                if not _faces_both(normals, k, lx, ly, lz, vx, vy, vz):
                    continue  # 0 (facing) or unspecified: no lookup
                # a side where the facet is not partly shadowed has all its words ones
                out[r, k] = _joint_facet(
                    k,
                    light_nodes,
                    view_nodes,
                    stored_l if (partial_l >> bit) & np.uint64(1) else nothing,
                    stored_v if (partial_v >> bit) & np.uint64(1) else nothing,
                    row_words,
                    row_rank,
                    compact,
                    segment_start,
                    segment_word,
                    segment_mask,
                    segment_weight,
                )


@njit(**_JIT)
def _faces_both(normals, k, lx, ly, lz, vx, vy, vz):
    """Facet ``k`` faces both ``L`` and ``V``."""
    nl = normals[0, k] * lx + normals[1, k] * ly + normals[2, k] * lz
    nv = normals[0, k] * vx + normals[1, k] * vy + normals[2, k] * vz
    return nl > 0.0 and nv > 0.0


@njit(**_JIT)
def _blend(nodes, row_words, row_rank, compact, w, m):
    """``Σ_a α_a popcount(x_a & m)`` over the three nodes ``(d0, d1, d2, α0, α1, α2)``."""
    d0, d1, d2, w0, w1, w2 = nodes
    return (
        w0 * float(_popcount(_word(row_words, row_rank, compact, d0, w) & m))
        + w1 * float(_popcount(_word(row_words, row_rank, compact, d1, w) & m))
        + w2 * float(_popcount(_word(row_words, row_rank, compact, d2, w) & m))
    )


@njit(**_JIT)
def _joint_facet(
    k,
    light_nodes,
    view_nodes,
    stored_l,
    stored_v,
    row_words,
    row_rank,
    compact,
    segment_start,
    segment_word,
    segment_mask,
    segment_weight,
):
    """``J_k = Σ_s ω_s Σ_a Σ_b α_a β_b popcount(x_{a,s} & y_{b,s})`` of one facet.

    A segment whose word is all ones at the three nodes of one side (not stored, see
    ``stored_l``/``stored_v``) needs only the other side's three words (``Σ_a α_a = 1``), and
    none when both are: the result then differs from the nine-pair sum by rounding only.
    """
    a0, a1, a2, wa0, wa1, wa2 = light_nodes
    b0, b1, b2, wb0, wb1, wb2 = view_nodes
    total = 0.0
    for s in range(segment_start[k], segment_start[k + 1]):
        w, m = segment_word[s], segment_mask[s]
        bit = np.uint64(w & 63)
        shadowed_l = (stored_l[w >> 6] >> bit) & np.uint64(1)
        shadowed_v = (stored_v[w >> 6] >> bit) & np.uint64(1)
        if shadowed_l == 0 and shadowed_v == 0:
            total += segment_weight[s] * float(_popcount(m))
        elif shadowed_l == 0:
            total += segment_weight[s] * _blend(view_nodes, row_words, row_rank, compact, w, m)
        elif shadowed_v == 0:
            total += segment_weight[s] * _blend(light_nodes, row_words, row_rank, compact, w, m)
        else:
            p00, p01, p02, p10, p11, p12, p20, p21, p22 = _pairs(
                _word(row_words, row_rank, compact, a0, w) & m,
                _word(row_words, row_rank, compact, a1, w) & m,
                _word(row_words, row_rank, compact, a2, w) & m,
                _word(row_words, row_rank, compact, b0, w),
                _word(row_words, row_rank, compact, b1, w),
                _word(row_words, row_rank, compact, b2, w),
            )
            total += segment_weight[s] * (
                wa0 * (wb0 * p00 + wb1 * p01 + wb2 * p02)
                + wa1 * (wb0 * p10 + wb1 * p11 + wb2 * p12)
                + wa2 * (wb0 * p20 + wb1 * p21 + wb2 * p22)
            )
    return total


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
def full_flags(bits, segment_start, segment_word, segment_mask, full, empty):
    """Per grid direction ``d``, bit ``k % 64`` of word ``k // 64``: every point of facet
    ``k`` is visible from ``d`` (``full[d]``; facets without segments and the padding bits
    are always set) / no point of facet ``k`` is (``empty[d]``; never set for facets
    without segments)."""
    n_facets = segment_start.shape[0] - 1
    for d in range(bits.shape[0]):
        for c in range(full.shape[1]):
            full[d, c] = ~np.uint64(0)
            empty[d, c] = np.uint64(0)
        for k in range(n_facets):
            flag = np.uint64(1) << np.uint64(k % 64)
            seen = False
            for s in range(segment_start[k], segment_start[k + 1]):
                word = bits[d, segment_word[s]] & segment_mask[s]
                if word != segment_mask[s]:
                    full[d, k // 64] &= ~flag
                if word != 0:
                    seen = True
            if not seen and segment_start[k] < segment_start[k + 1]:
                empty[d, k // 64] |= flag


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
