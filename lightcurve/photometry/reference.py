"""Reference renderer: the measurement model written out plainly in numpy.

Evaluates ``F_obs/F_sun = (1 AU/r_sun)² Σ ρ(n, L, V) A (n·L)(n·V) / d²`` with the *vector*
form of each BRDF (explicit unit vectors, half vectors and tangents for every facet × epoch),
without chunking, torch or coplanar merging of materials. It is slow and exists to validate
the fast :class:`lightcurve.photometry.render.Renderer` (an independent code path through the BRDF
vector forms) and as the "straightforward numpy" baseline of ``benchmarks/render.py``.
Convex shapes only (no shadowing).
"""

from __future__ import annotations

import numpy as np

import brdf
from filters.attitude import attitude_matrix
from lightcurve.sky.geometry import AU_M
from shapes import CompiledFacets, FacetModel

__all__ = ["reference_flux"]


def reference_flux(
    shape: FacetModel | CompiledFacets,
    q: np.ndarray,
    sun: np.ndarray,
    observer: np.ndarray,
    dtype: type = np.float64,
) -> np.ndarray:
    """Flux ratio of a convex shape, straightforward numpy (see module docstring).

    Parameters
    ----------
    shape : FacetModel or CompiledFacets
    q : (E, 4) array
        Attitudes (inertial → body).
    sun, observer : (E, 3) array
        Object → Sun and object → observer vectors, inertial, metres.
    dtype : numpy dtype
        Working precision.

    Returns
    -------
    (E,) numpy.ndarray
    """
    compiled = shape.compiled() if isinstance(shape, FacetModel) else shape
    q, sun, observer = (np.asarray(v, dtype=dtype) for v in (q, sun, observer))
    a = attitude_matrix(q).astype(dtype)
    r_sun = np.linalg.norm(sun, axis=-1)
    d = np.linalg.norm(observer, axis=-1)
    light = np.einsum("eij,ej->ei", a, sun / r_sun[:, None])
    view = np.einsum("eij,ej->ei", a, observer / d[:, None])
    total = np.zeros(len(q), dtype=dtype)
    for index, material in enumerate(compiled.materials):
        rows = compiled.material_index == index
        model = brdf.get(material.brdf, **material.params)
        normals = compiled.normals[rows].astype(dtype)
        tangents = compiled.tangents[rows].astype(dtype) if model.anisotropic else None
        n = normals[None, :, :]
        rho = model(
            n,
            light[:, None, :],
            view[:, None, :],
            tangent=None if tangents is None else tangents[None, :, :],
        )
        nl = np.clip(np.sum(n * light[:, None, :], axis=-1), 0, None)
        nv = np.clip(np.sum(n * view[:, None, :], axis=-1), 0, None)
        total += np.sum(rho * compiled.areas[rows].astype(dtype) * nl * nv, axis=-1)
    return total * (AU_M / r_sun) ** 2 / d**2
