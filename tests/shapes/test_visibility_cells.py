"""The packed per-facet flags of the grid against the plain boolean computation."""

import numpy as np

from shapes.visibility.cells import facing_flags, partial_cells


def test_packed_flags_give_the_boolean_answer():
    rng = np.random.default_rng(11)
    n_dirs, n_facets = 1200, 130  # more rows than a block, facets not a multiple of 64
    directions = rng.normal(size=(n_dirs, 3))
    normals = rng.normal(size=(n_facets, 3))
    front = directions @ normals.T > 0.0
    packed_front = facing_flags(directions, normals)
    unpacked = np.unpackbits(packed_front, axis=1, bitorder="little")[:, :n_facets]
    assert np.array_equal(unpacked.astype(bool), front)
    full = rng.random((n_dirs, n_facets)) < 0.7
    packed_full = np.zeros_like(packed_front)
    bits = np.packbits(full, axis=1, bitorder="little")
    packed_full[:, : bits.shape[1]] = bits
    corners = rng.integers(0, n_dirs, size=(1500, 3))
    cell, facet = partial_cells(packed_full, packed_front, corners, n_facets)
    expected = ~(full[corners[:, 0]] & full[corners[:, 1]] & full[corners[:, 2]])
    expected &= front[corners[:, 0]] | front[corners[:, 1]] | front[corners[:, 2]]
    want_cell, want_facet = np.nonzero(expected)
    assert np.array_equal(cell, want_cell) and np.array_equal(facet, want_facet)
