"""The near-uniform grid of unit normals of the EGI and its neighbour Laplacian.

The normals are the points of a Fibonacci (golden-angle) spiral on the sphere, the same
spread as :func:`lightcurve.analysis.convex.fibonacci_poles` (González 2010, "Measurement of
areas on a sphere using Fibonacci and latitude–longitude lattices", Math. Geosci. 42, 49):
each covers ``4π/N`` sr, with neighbours about ``√(4π/N)`` rad apart (4.5° for N = 2 000).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from lightcurve.analysis.convex.fit import fibonacci_poles

__all__ = ["normal_grid", "smoothness_operator"]

#: Neighbours of each normal in the Laplacian (a Fibonacci lattice is locally hexagonal).
NEIGHBOURS = 6


def normal_grid(count: int) -> np.ndarray:
    """``count`` unit normals spread evenly over the sphere (Fibonacci lattice).

    Parameters
    ----------
    count : int
        Number of normals (≥ 4).

    Returns
    -------
    (count, 3) float
        Unit vectors, body frame.
    """
    if count < 4:
        raise ValueError(f"the EGI needs at least 4 normals, got {count}")
    poles = np.array(fibonacci_poles(count))
    lam, beta = poles[:, 0], poles[:, 1]
    return np.column_stack([np.cos(beta) * np.cos(lam), np.cos(beta) * np.sin(lam), np.sin(beta)])


def smoothness_operator(normals: np.ndarray, neighbours: int = NEIGHBOURS) -> np.ndarray:
    """Graph Laplacian ``L = I − W`` of the normals' nearest neighbours.

    ``(L a)_i = a_i − mean_{j ∈ nb(i)} a_j``: the penalty ``‖L a‖²`` of the fit's Tikhonov
    term (Tikhonov & Arsenin 1977) is small for EGIs that vary slowly over the sphere.

    Parameters
    ----------
    normals : (N, 3) float
        Unit normals.
    neighbours : int
        Neighbours averaged per normal.

    Returns
    -------
    (N, N) float
    """
    _, index = cKDTree(normals).query(normals, neighbours + 1)
    count = len(normals)
    operator = np.eye(count)
    rows = np.repeat(np.arange(count), neighbours)
    np.add.at(operator, (rows, index[:, 1:].ravel()), -1.0 / neighbours)
    return operator
