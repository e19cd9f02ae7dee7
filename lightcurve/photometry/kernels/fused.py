"""The fused flux sum of a facet model: the facet table, material blocks and :class:`FusedFlux`.

:class:`FusedFlux` evaluates ``Σ_i ρ_i A_i (n_i·L)(n_i·V) · shadow_i`` for any number of rows
(attitude × geometry) in one pass over the facets per row, dispatching to the row kernels of
:mod:`~lightcurve.photometry.kernels.brdf_sums` on the thread pool of
:mod:`~lightcurve.photometry.kernels.threads`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from lightcurve.photometry.kernels.brdf_sums import ANISOTROPIC, KINDS, LOMMEL_SEELIGER, ROW_KERNELS
from lightcurve.photometry.kernels.rows import body_geometry
from lightcurve.photometry.kernels.threads import run_rows
from lightcurve.photometry.kernels.tiles import tile_layout

__all__ = [
    "FusedFlux",
    "block_parameters",
    "facet_table",
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
    """Kernel code and parameter row (eight numbers) of a BRDF material.

    The row holds the factors of the formula that are constant over the material (see
    :mod:`lightcurve.photometry.kernels.brdf_sums`).

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
    elif name == "two-lobe":  # the narrow lobe as Cook–Torrance's, then the broad one
        inv_m2 = 1.0 / (p["mn"] * p["mn"])
        alpha2 = p["ab"] * p["ab"]
        row = [
            p["rd"] * _INV_PI,
            (p["rn"] * 0.25 * _INV_PI) * inv_m2,
            inv_m2,
            p["fn"],
            (p["rb"] * 0.25 * _INV_PI) * alpha2,
            alpha2,
            p["fb"],
        ]
    else:
        kind = LOMMEL_SEELIGER
        row = [p["w"] * (0.25 * _INV_PI), p["c"], p["a"], p["d"], p["k"]]
    return kind, row + [0.0] * (8 - len(row))


class FusedFlux:
    """A shape's facets and material blocks, evaluated by the fused numba kernels.

    Parameters
    ----------
    facets : (10, K) array
        :func:`facet_table` of the facets, sorted by material block.
    blocks : sequence of (kind, start, stop, parameter row)
        One entry per material block ``facets[:, start:stop]`` (:func:`block_parameters`).
    dtype : numpy dtype
        Compute precision (float32 or float64).

    Notes
    -----
    The kernels see the facets in tile layout (:mod:`lightcurve.photometry.kernels.tiles`): each
    block rearranged into tiles of facets with similar normals, padded with zero-area slots.
    :attr:`source` gives the input facet of every slot (:attr:`padding` flags the padding
    slots, whose shadow factor is never used); callers keep the input order.
    """

    def __init__(
        self, facets: np.ndarray, blocks: Sequence[tuple[int, int, int, list]], dtype: type
    ) -> None:
        self.dtype = np.dtype(dtype)
        table = np.asarray(facets, dtype=self.dtype)
        # The cones bound the normals the kernels use (rounded to the compute dtype).
        layout = tile_layout(
            table[:3].T.astype(np.float64), [np.arange(b[1], b[2]) for b in blocks]
        )
        self.source = layout.source
        self.padding = layout.padding
        self.facets = np.ascontiguousarray(table[:, layout.source])
        self.facets[3, layout.padding] = 0.0
        self.cones = np.ascontiguousarray(layout.cones, dtype=self.dtype)
        self._blocks = [
            (ROW_KERNELS[kind], int(first), int(last), np.asarray(row, dtype=np.float64))
            for (kind, _, _, row), (first, last) in zip(blocks, layout.block_tiles, strict=True)
        ]

    @property
    def n_slots(self) -> int:
        """Facet slots of the tile layout (facets and padding)."""
        return self.facets.shape[1]

    def geometry(
        self, q: np.ndarray, sun: np.ndarray, observer: np.ndarray, au: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Body-frame ``L``, ``V`` and the distance factor per row (float64).

        Parameters are (R, 4), (R, 3), (R, 3) float64 arrays and ``1 AU`` in metres (0: no
        solar-distance scaling); see :func:`lightcurve.photometry.kernels.rows.body_geometry`.
        """
        rows = q.shape[0]
        light = np.empty((rows, 3))
        view = np.empty((rows, 3))
        scale = np.empty(rows)
        body_geometry(q, sun, observer, au, light, view, scale)
        return light, view, scale

    def sums(
        self,
        light: np.ndarray,
        view: np.ndarray,
        shadow: np.ndarray | None = None,
        *,
        per_slot: bool = False,
    ) -> np.ndarray:
        """``Σ_i ρ_i A_i (n_i·L)(n_i·V) · shadow_i`` per row (float64).

        Parameters
        ----------
        light, view : (R, 3) float64 arrays
            Body-frame unit vectors (C order).
        shadow : (R, K) array, optional
            Shadow factor per row and facet (input order); ``None`` for none.
        per_slot : bool
            ``shadow`` is already given per slot, ``(R, S)`` in the compute dtype and C
            order (column ``j`` for facet ``source[j]``): it is used without a copy.
        """
        out = np.zeros(light.shape[0])
        if per_slot:
            if shadow.shape != (light.shape[0], self.n_slots) or shadow.dtype != self.dtype:
                raise ValueError(
                    f"a per-slot shadow factor must be ({light.shape[0]}, {self.n_slots}) "
                    f"{self.dtype}, got {shadow.shape} {shadow.dtype}"
                )
            shadow = np.ascontiguousarray(shadow)
        elif shadow is not None:  # the factor of every slot, in the compute dtype
            shadow = np.ascontiguousarray(np.take(shadow, self.source, axis=1), dtype=self.dtype)
        facets, cones, blocks = self.facets, self.cones, self._blocks

        def kernel(start: int, stop: int) -> None:
            for row_kernel, first, last, p in blocks:
                row_kernel(light, view, facets, cones, first, last, p, shadow, out, start, stop)

        run_rows(kernel, light.shape[0], self.n_slots)
        return out
