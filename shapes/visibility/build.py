"""Building a visibility table: the bit of every sample point toward every grid direction.

Coarse to fine (``refine=True``, an even grid resolution): the nodes of the half-resolution
grid (a quarter of the directions) are ray-cast for every sample point; then, level by level
(:meth:`~shapes.visibility.directions.CubeSphereGrid.refinement_levels`), a facet whose points
are all visible — or all hidden — from every nearest node of the levels before (two or four
nodes, 2.4°–3.5° away at the default resolution) takes that value at the new node, and only
the other facets (those a shadow boundary crosses near that direction) are ray-cast. A shadow
that appears between nodes 7° apart and covers none of them is missed; the benchmarks
measure the resulting error against exact ray casting. ``refine=False`` casts every ray.

The rays of each batch are cast on a pool of threads (Embree releases the GIL while it
traces). The table's type, files and lookups are :mod:`shapes.visibility.table`; the sample
points and the exact ray-cast fractions, :mod:`shapes.visibility.sampling`.
"""

from __future__ import annotations

import itertools
import logging
import os
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any

import numpy as np

from shapes.compiled import CompiledFacets
from shapes.visibility.directions import CubeSphereGrid
from shapes.visibility.sampling import (
    DEFAULT_SAMPLES,
    DEFAULT_SPACING,
    _Caster,
    _caster,
    _compiled,
)
from shapes.visibility.table import (
    DEFAULT_RESOLUTION,
    VisibilityTable,
    _kernels,
)

if TYPE_CHECKING:
    from shapes.model import FacetModel

__all__ = ["build_visibility_table", "expected_build_seconds"]

logger = logging.getLogger(__name__)

_BATCH_POINTS = 1 << 22  # (directions × points) of one batch: its bool arrays and rays
_RAYS_PER_SECOND = 5e6  # one loaded core, Embree, bookkeeping included (for the estimate)
_REFINED_SHARE = 0.45  # rays cast by a refined build, share of every ray (measured)


def build_visibility_table(
    model: FacetModel | CompiledFacets,
    *,
    resolution: int = DEFAULT_RESOLUTION,
    samples: int = DEFAULT_SAMPLES,
    spacing: float = DEFAULT_SPACING,
    backend: str = "auto",
    progress: bool = False,
    refine: bool = True,
    workers: int | None = None,
) -> VisibilityTable:
    """Ray-cast the visibility table of a model's effective facets.

    Parameters
    ----------
    model : FacetModel or CompiledFacets
    resolution : int
        Cube-sphere resolution (``6 n² + 2`` directions).
    samples : int
        Target ray origins per effective facet.
    spacing : float
        Largest sample spacing, fraction of the bounding-box diagonal (0: none).
    backend : {"auto", "embree", "trimesh"}
    progress : bool
        Show a tqdm progress bar (directions done).
    refine : bool
        Coarse-to-fine build (module docstring): ray-cast only the facets a shadow boundary
        crosses near each direction of the finer levels. False: every point, every direction.
    workers : int, optional
        Threads casting rays (default: the CPU count).

    Returns
    -------
    VisibilityTable
        Cost: at most ``(6 n² + 2) × points`` rays (points ≈ ``samples × K_shadowable``),
        about 0.3–0.5 of that refined; Embree casts 6–7 million rays per second and core.
        Memory: one bit per direction and point, plus a batch of ≈ 4 million rays.
    """
    compiled = _compiled(model)
    grid = CubeSphereGrid(resolution)
    start_time = time.perf_counter()
    caster = _caster(compiled, int(samples), float(spacing), backend)
    sampling = caster.sampling
    layout, position = _kernels().segment_layout(sampling.facet, sampling.weight, len(compiled))
    n_words = int(layout.pop("n_words"))
    table = VisibilityTable(
        np.zeros((len(grid), n_words), dtype=np.uint64),
        layout,
        resolution=resolution,
        structure=compiled.structure,
        areas=compiled.areas,
        normals=compiled.normals,
        samples=sampling.samples,
        spacing=sampling.spacing,
    )
    levels = grid.refinement_levels() if refine else [(np.arange(len(grid)), None)]
    logger.info(
        "visibility table: %d directions × %d sample points on %d facets, %d level(s)",
        len(grid),
        len(sampling),
        int(np.count_nonzero(np.bincount(sampling.facet, minlength=len(compiled)))),
        len(levels),
    )
    cast = 0
    with _bar(progress, len(grid)) as bar, ThreadPoolExecutor(_workers(workers)) as pool:
        filler = _LevelFiller(table, caster, position, pool, _workers(workers))
        for level, (nodes, neighbours) in enumerate(levels):
            level_start, level_rays = time.perf_counter(), filler.rays
            rows = max(1, _BATCH_POINTS // max(1, len(sampling)))
            for first in range(0, len(nodes), rows):
                part = slice(first, first + rows)
                filler.fill(nodes[part], None if neighbours is None else neighbours[part])
                bar(len(nodes[part]))
            logger.info(
                "visibility table: level %d, %d directions, %.3g rays (%.0f %% of all) in %.1f s",
                level,
                len(nodes),
                filler.rays - level_rays,
                100.0 * (filler.rays - level_rays) / max(1, len(nodes) * len(sampling)),
                time.perf_counter() - level_start,
            )
        cast = filler.rays
    logger.info(
        "visibility table: %.3g rays (%.0f %% of every point toward every direction) in %.1f s",
        cast,
        100.0 * cast / max(1, len(grid) * len(sampling)),
        time.perf_counter() - start_time,
    )
    return table


def expected_build_seconds(
    model: FacetModel | CompiledFacets,
    *,
    resolution: int = DEFAULT_RESOLUTION,
    samples: int = DEFAULT_SAMPLES,
    spacing: float = DEFAULT_SPACING,
    workers: int | None = None,
) -> float:
    """Rough wall time of :func:`build_visibility_table` (refined), s: the sample points
    times the directions, the measured share of rays a refined build casts, and
    ``_RAYS_PER_SECOND`` per worker (Embree)."""
    compiled = _compiled(model)
    points = len(_caster(compiled, int(samples), float(spacing), "auto").sampling)
    rays = (6 * resolution**2 + 2) * points * (_REFINED_SHARE if resolution % 2 == 0 else 1.0)
    return rays / (_RAYS_PER_SECOND * _workers(workers))


def _workers(workers: int | None) -> int:
    return max(1, int(workers) if workers is not None else (os.cpu_count() or 1))


class _LevelFiller:
    """Fills the rows of a table's bits, node by node, ray-casting what cannot be inferred."""

    def __init__(
        self,
        table: VisibilityTable,
        caster: _Caster,
        position: np.ndarray,
        pool: ThreadPoolExecutor,
        workers: int,
    ) -> None:
        self.table, self.caster, self.position = table, caster, position
        self.pool, self.workers = pool, workers
        self.point_facet = caster.sampling.facet
        self.n_facets = table.n_facets
        self.directions = table.grid.directions.astype(np.float32)
        self.rays = 0

    def fill(self, nodes: np.ndarray, neighbours: np.ndarray | None) -> None:
        """Set ``bits[nodes]``; ``neighbours (len(nodes), m)``: nodes already filled whose
        agreement on a facet decides it without rays (None: cast every point)."""
        if neighbours is None:
            visible = np.zeros((len(nodes), len(self.point_facet)), dtype=bool)
            needed = np.ones_like(visible)
        else:
            every = self._agreeing(neighbours, visible=True)
            none = self._agreeing(neighbours, visible=False)
            visible = every[:, self.point_facet]
            needed = ~(every | none)[:, self.point_facet]
        count = np.cumsum(needed.sum(axis=1))
        self.rays += int(count[-1]) if len(count) else 0
        # row ranges of about equal rays, one per thread
        cuts = np.searchsorted(count, np.linspace(0, count[-1], self.workers + 1)[1:-1])
        bounds = np.unique(np.concatenate([[0], cuts, [len(nodes)]]))

        def work(part: slice) -> None:
            rays = int(needed[part].sum())
            origins = np.empty((rays, 3), dtype=np.float32)
            directions = np.empty((rays, 3), dtype=np.float32)
            kernels = _kernels()
            caster = self.caster
            kernels.mirrored_rays(
                self.directions[nodes[part]],
                caster.normals32,
                caster.scene_origins,
                needed[part],
                origins,
                directions,
            )
            kernels.scatter_rays(
                needed[part], ~caster.occluder.query(origins, directions), visible[part]
            )
            stream = np.zeros((len(visible[part]), 64 * self.table.bits.shape[1]), dtype=bool)
            stream[:, self.position] = visible[part]
            packed = np.packbits(stream, axis=1, bitorder="little")
            self.table.bits[nodes[part]] = packed.view("<u8").astype(np.uint64, copy=False)

        parts = [slice(a, b) for a, b in itertools.pairwise(bounds)]
        list(self.pool.map(work, parts))

    def _agreeing(self, neighbours: np.ndarray, *, visible: bool) -> np.ndarray:
        """``(M, K)`` bool: every point of the facet is visible (``visible``) or hidden from
        every one of a node's ``neighbours``."""
        segments = self.table._segments()
        bits = self.table.bits[neighbours.ravel()]
        flags = np.empty((len(bits), -(-self.n_facets // 64)), dtype=np.uint64)
        _kernels().full_flags(
            bits if visible else ~bits,
            segments["segment_start"],
            segments["segment_word"],
            segments["segment_mask"],
            flags,
        )
        flags = np.bitwise_and.reduce(flags.reshape(*neighbours.shape, -1), axis=1)
        return np.unpackbits(flags.view(np.uint8), axis=1, bitorder="little")[
            :, : self.n_facets
        ].astype(bool)


@contextmanager
def _bar(show: bool, total: int) -> Iterator[Any]:
    """A callable advancing a tqdm bar of ``total`` directions (a no-op when not shown)."""
    if not show:
        yield lambda n: None
        return
    from tqdm import tqdm

    with tqdm(total=total, desc="visibility table", unit="direction", leave=False) as bar:
        yield bar.update
