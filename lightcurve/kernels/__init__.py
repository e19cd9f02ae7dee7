"""Fused rendering kernels compiled with numba: the renderer's fast path on the CPU.

:class:`FusedFlux` holds a shape's facets and material blocks in the kernels' layout and
evaluates ``Σ_i ρ_i A_i (n_i·L)(n_i·V) · shadow_i`` for any number of rows (attitude ×
geometry) in one pass over the facets per row: cosines, BRDF, clamps, shadow factor and the
facet sum are fused, so no (rows × facets) array is built. Kernels are compiled on first use
and cached on disk by numba (``cache=True``: in ``__pycache__`` beside this package, or in
numba's user cache folder when that is read-only, or ``NUMBA_CACHE_DIR``), so the
compilation is paid once per machine and installation, not per process.

Modules: :mod:`~lightcurve.kernels.elementary` (vectorisable ``exp``/``log``),
:mod:`~lightcurve.kernels.brdf_sums` (one row loop per BRDF),
:mod:`~lightcurve.kernels.rows` (body-frame geometry),
:mod:`~lightcurve.kernels.threads` (row ranges on a thread pool).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from lightcurve.kernels.brdf_sums import ANISOTROPIC, KINDS, LOMMEL_SEELIGER, ROW_KERNELS
from lightcurve.kernels.rows import body_geometry
from lightcurve.kernels.threads import get_num_threads, run_rows, set_num_threads

__all__ = [
    "FusedFlux",
    "block_parameters",
    "facet_table",
    "get_num_threads",
    "set_num_threads",
]

_INV_PI = 1.0 / math.pi


def facet_table(
    normals: np.ndarray, areas: np.ndarray, tangents: np.ndarray, dtype: type
) -> np.ndarray:
    """The (10, K) facet layout of the kernels: ``n``, ``A``, ``u``, ``v = n × u``.

    Parameters
    ----------
    normals, tangents : (K, 3) arrays
        Unit normals and unit tangents ``u`` (body frame).
    areas : (K,) array
        Facet areas (m²).
    dtype : numpy dtype
        Compute precision.
    """
    bitangents = np.cross(normals, tangents)
    table = np.concatenate([normals.T, areas[None, :], tangents.T, bitangents.T], axis=0)
    return np.ascontiguousarray(table, dtype=dtype)


def block_parameters(name: str, params: dict[str, float], anisotropic: bool) -> tuple[int, list]:
    """Kernel code and parameter row (six numbers) of a BRDF material.

    The row holds the factors of the formula that are constant over the material (see
    :mod:`lightcurve.kernels.brdf_sums`).

    Parameters
    ----------
    name : str
        BRDF registry name.
    params : dict
        Validated scalar parameters (:func:`brdf.get`).
    anisotropic : bool
        Ashikhmin–Shirley with ``nu ≠ nv``.
    """
    kind = KINDS[name]
    p = {k: float(v) for k, v in params.items()}
    if name == "lambert":
        row = [p["rd"] * _INV_PI]
    elif name == "phong":
        row = [p["rd"] * _INV_PI, p["rs"] * (p["n"] + 2.0) * (0.5 * _INV_PI), p["n"]]
    elif name == "cook-torrance":
        inv_m2 = 1.0 / (p["m"] * p["m"])
        row = [p["rd"] * _INV_PI, (p["rs"] * 0.25 * _INV_PI) * inv_m2, inv_m2, p["f0"]]
    elif name == "ashikhmin-shirley":
        kind = ANISOTROPIC if anisotropic else kind
        row = [
            28.0 / (23.0 * math.pi) * p["rd"] * (1.0 - p["rs"]),
            ((p["nu"] + 1.0) * (p["nv"] + 1.0)) ** 0.5 * (1.0 / (8.0 * math.pi)),
            p["rs"],
            p["nu"],
            p["nv"],
        ]
    else:
        kind = LOMMEL_SEELIGER
        row = [p["w"] * (0.25 * _INV_PI), p["c"], p["a"], p["d"], p["k"]]
    return kind, row + [0.0] * (6 - len(row))


class FusedFlux:
    """A shape's facets and material blocks, evaluated by the fused numba kernels.

    Parameters
    ----------
    facets : (10, K) array
        :func:`facet_table` of facets sorted by material block.
    blocks : sequence of (kind, start, stop, parameter row)
        One entry per material block (:func:`block_parameters`).
    dtype : numpy dtype
        Compute precision (float32 or float64).
    """

    def __init__(
        self, facets: np.ndarray, blocks: Sequence[tuple[int, int, int, list]], dtype: type
    ) -> None:
        self.dtype = np.dtype(dtype)
        self.facets = np.ascontiguousarray(facets, dtype=self.dtype)
        self.kinds = np.array([b[0] for b in blocks], dtype=np.int64)
        self.starts = np.array([b[1] for b in blocks], dtype=np.int64)
        self.stops = np.array([b[2] for b in blocks], dtype=np.int64)
        self.params = np.array([b[3] for b in blocks], dtype=self.dtype).reshape(-1, 6)
        self._no_shadow = np.ones((1, self.facets.shape[1]), dtype=self.dtype)
        self._row_kernels = [
            (ROW_KERNELS[kind], start, stop, row)
            for kind, start, stop, row in zip(
                self.kinds.tolist(),
                self.starts.tolist(),
                self.stops.tolist(),
                self.params,
                strict=True,
            )
        ]

    @property
    def n_facets(self) -> int:
        return self.facets.shape[1]

    def geometry(
        self, q: np.ndarray, sun: np.ndarray, observer: np.ndarray, au: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Body-frame ``L``, ``V`` (compute dtype) and the distance factor (float64) per row.

        Parameters are (R, 4), (R, 3), (R, 3) float64 arrays and ``1 AU`` in metres (0: no
        solar-distance scaling); see :func:`lightcurve.kernels.rows.body_geometry`.
        """
        rows = q.shape[0]
        light = np.empty((rows, 3), dtype=self.dtype)
        view = np.empty((rows, 3), dtype=self.dtype)
        scale = np.empty(rows, dtype=np.float64)
        body_geometry(q, sun, observer, au, light, view, scale)
        return light, view, scale

    def sums(
        self, light: np.ndarray, view: np.ndarray, shadow: np.ndarray | None = None
    ) -> np.ndarray:
        """``Σ_i ρ_i A_i (n_i·L)(n_i·V) · shadow_i`` per row (compute dtype).

        Parameters
        ----------
        light, view : (R, 3) arrays
            Body-frame unit vectors (compute dtype, C order).
        shadow : (R, K) array, optional
            Shadow factor per row and facet (compute dtype); ``None`` for none.
        """
        out = np.zeros(light.shape[0], dtype=self.dtype)
        factor = self._no_shadow if shadow is None else shadow
        blocks = self._row_kernels

        def kernel(start: int, stop: int) -> None:
            rows = slice(start, stop)
            shadow_rows = factor if shadow is None else factor[rows]
            for row_kernel, first, last, p in blocks:
                row_kernel(
                    light[rows], view[rows], self.facets, first, last, p, shadow_rows, out[rows]
                )

        run_rows(kernel, light.shape[0], self.n_facets)
        return out
