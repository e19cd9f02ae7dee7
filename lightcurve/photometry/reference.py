"""Reference renderer: the measurement model written out plainly in numpy.

Evaluates ``F_obs/F_sun = (1 AU/r_sun)² Σ ρ(n, L, V) A (n·L)(n·V) / d²`` with the *vector*
form of each BRDF (explicit unit vectors, half vectors and tangents for every facet × epoch),
without chunking, torch or coplanar merging of materials. It is slow and exists to validate
the fast :class:`lightcurve.photometry.render.Renderer` (an independent code path through the BRDF
vector forms) and as the "straightforward numpy" baseline of ``benchmarks/render.py``.
Convex shapes only (no shadowing).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

import brdf
from filters.attitude import attitude_matrix
from lightcurve.sky.geometry import AU_M
from shapes import CompiledFacets, FacetModel

__all__ = ["facet_flux_sum", "reference_flux"]


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
    models = [brdf.get(m.brdf, **m.params) for m in compiled.materials]
    total = facet_flux_sum(
        compiled.normals.astype(dtype),
        compiled.areas.astype(dtype),
        compiled.tangents.astype(dtype),
        compiled.material_index,
        models,
        light=light,
        view=view,
    )
    return total * (AU_M / r_sun) ** 2 / d**2


def facet_flux_sum(
    normals: np.ndarray,
    areas: np.ndarray,
    tangents: np.ndarray,
    material_index: np.ndarray,
    models: Sequence[brdf.BRDF],
    *,
    light: np.ndarray,
    view: np.ndarray,
    shadow: np.ndarray | None = None,
) -> np.ndarray:
    """``Σ ρ(n, L, V) A (n·L)⁺(n·V)⁺ · shadow`` over facets, by the BRDF vector forms.

    Parameters
    ----------
    normals, tangents : (K, 3) float
        Unit normals and tangents (body frame).
    areas : (K,) float
        m².
    material_index : (K,) int
        Entry of ``models`` of each facet.
    models : sequence of brdf.BRDF
    light, view : (R, 3) float
        Body-frame unit vectors to the Sun and to the observer.
    shadow : (R, K) float, optional
        Joint lit-and-seen fraction of every facet.

    Returns
    -------
    (R,) numpy.ndarray
        m² (flux ratio at unit distances).
    """
    total = np.zeros(len(light), dtype=light.dtype)
    for index, model in enumerate(models):
        rows = material_index == index
        if not rows.any():
            continue
        n = normals[rows][None, :, :]
        rho = model(
            n,
            light[:, None, :],
            view[:, None, :],
            tangent=tangents[rows][None, :, :] if model.anisotropic else None,
        )
        nl = np.clip(np.sum(n * light[:, None, :], axis=-1), 0, None)
        nv = np.clip(np.sum(n * view[:, None, :], axis=-1), 0, None)
        terms = rho * areas[rows] * nl * nv
        if shadow is not None:
            terms = terms * shadow[:, rows]
        total += np.sum(terms, axis=-1)
    return total
