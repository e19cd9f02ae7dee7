"""Building a visibility table: the bit of every sample point toward every grid direction.

Coarse to fine (``refine=True``, an even grid resolution): the nodes of the half-resolution
grid (a quarter of the directions) are ray-cast for every sample point; then, level by level
(:meth:`~shapes.visibility.directions.CubeSphereGrid.refinement_levels`), a facet whose points
are all visible — or all hidden — from every nearby node of the levels before (six or eight
nodes, 2.4°–8.4° away at the default resolution) takes that value at the new node, and only
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

__all__ = ["build_visibility_table", "describe_build", "stored_build_options"]

logger = logging.getLogger(__name__)

_BATCH_POINTS = 1 << 22  # (directions × points) of one batch of level 0: its rays
_REFINED_BATCH = 8  # finer levels: that many times more directions a batch (fewer rays)
_RAYS_PER_SECOND = 4e6  # per thread, Embree and bookkeeping (measured, for the estimate)
_REFINED_SHARE = 0.33  # rays a refined build casts, share of every ray (Itokawa: 0.33)


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
        Threads casting rays (default: ``OMP_NUM_THREADS``, which ``lightcurve --threads``
        sets, else the CPUs the process may use).

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
            rows *= 1 if neighbours is None else _REFINED_BATCH
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


def describe_build(
    model: FacetModel | CompiledFacets,
    *,
    resolution: int = DEFAULT_RESOLUTION,
    samples: int = DEFAULT_SAMPLES,
    spacing: float = DEFAULT_SPACING,
    workers: int | None = None,
) -> str:
    """One line: the table :func:`build_visibility_table` (refined) builds and its rough wall
    time — the sample points times the directions, the share of those rays a refined build
    casts on smooth natural shapes (≈ 1/3), at ``_RAYS_PER_SECOND`` per thread."""
    compiled = _compiled(model)
    points = len(_caster(compiled, int(samples), float(spacing), "auto").sampling)
    directions = 6 * resolution**2 + 2
    share = _REFINED_SHARE if resolution % 2 == 0 else 1.0
    threads = _workers(workers)
    seconds = directions * points * share / (_RAYS_PER_SECOND * threads)
    return (
        f"visibility table (joint lit and seen) of {len(compiled)} effective facets: "
        f"{directions} directions × {points} sample points, about {_duration(seconds)} "
        f"on {threads} thread{'s' if threads > 1 else ''}"
    )


def stored_build_options(path: str | os.PathLike[str] | None) -> dict[str, Any]:
    """``resolution``, ``samples`` and ``spacing`` of the table file at ``path`` (those
    it lacks, or all when it is missing or unreadable: the defaults), to rebuild it alike."""
    options: dict[str, Any] = {
        "resolution": DEFAULT_RESOLUTION,
        "samples": DEFAULT_SAMPLES,
        "spacing": DEFAULT_SPACING,
    }
    if path is not None and os.path.isfile(path):
        try:
            with np.load(path, allow_pickle=False) as data:
                for key, value in options.items():
                    if key in data.files:
                        options[key] = type(value)(data[key])
        except (OSError, ValueError):
            pass  # an unreadable old table: the defaults
    return options


def _duration(seconds: float) -> str:
    """``12 s``, ``3 min``, ``1.5 h``."""
    if seconds < 90.0:
        return f"{max(1.0, seconds):.0f} s"
    if seconds < 5400.0:
        return f"{seconds / 60.0:.0f} min"
    return f"{seconds / 3600.0:.1f} h"


def _workers(workers: int | None) -> int:
    """``workers``, else ``OMP_NUM_THREADS`` (what ``lightcurve --threads N`` sets), else the
    CPUs this process may use."""
    if workers is not None:
        return max(1, int(workers))
    try:
        return max(1, int(os.environ["OMP_NUM_THREADS"]))
    except (KeyError, ValueError):
        return (
            len(os.sched_getaffinity(0))
            if hasattr(os, "sched_getaffinity")
            else os.cpu_count() or 1
        )


class _LevelFiller:
    """Fills the rows of a table's bits, node by node, ray-casting what cannot be inferred;
    the work of a batch of nodes is split into row ranges of about equal rays, one per
    thread (the compiled kernels and Embree release the GIL)."""

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
        facet = caster.sampling.facet
        self.count = np.bincount(facet, minlength=table.n_facets).astype(np.int64)
        self.first = np.zeros(table.n_facets, np.int64)
        starts = np.flatnonzero(np.diff(facet, prepend=-1))  # points are grouped by facet
        self.first[facet[starts]] = starts
        self.directions = table.grid.directions.astype(np.float32)
        self.rays = 0

    def fill(self, nodes: np.ndarray, neighbours: np.ndarray | None) -> None:
        """Set ``bits[nodes]``; ``neighbours (len(nodes), m)``: nodes already filled whose
        agreement on a facet decides it without rays (None: cast every point)."""
        from shapes.visibility import build_kernels as kernels  # numba, on first use

        out = np.zeros((len(nodes), self.table.bits.shape[1]), dtype=np.uint64)
        needed = np.zeros((len(nodes), self.table.n_facets), dtype=bool)
        if neighbours is None:
            needed[:] = self.count > 0
        else:
            segments = self.table._segments()

            def decide(part: slice) -> None:
                kernels.agreeing_facets(
                    self.table.bits,
                    neighbours[part],
                    segments["segment_start"],
                    segments["segment_word"],
                    segments["segment_mask"],
                    out[part],
                    needed[part],
                )

            self._split(decide, np.full(len(nodes), 1.0))
        per_row = needed @ self.count
        self.rays += int(per_row.sum())

        def cast(part: slice) -> None:
            rays = int(per_row[part].sum())
            origins = np.empty((rays, 3), dtype=np.float32)
            directions = np.empty((rays, 3), dtype=np.float32)
            args = (needed[part], self.first, self.count)
            kernels.facet_rays(
                self.directions[nodes[part]],
                self.caster.normals32,
                self.caster.scene_origins,
                *args,
                origins,
                directions,
            )
            escapes = ~self.caster.occluder.query(origins, directions)
            kernels.set_escaping(*args, self.position, escapes, out[part])

        self._split(cast, per_row)
        self.table.bits[nodes] = out

    def _split(self, work: Any, cost: np.ndarray) -> None:
        """Run ``work(rows)`` on row ranges of about equal total ``cost``, one per thread."""
        total = np.cumsum(cost)
        if not len(total) or total[-1] == 0:
            return
        cuts = np.searchsorted(total, np.linspace(0, total[-1], self.workers + 1)[1:-1])
        bounds = np.unique(np.concatenate([[0], cuts, [len(cost)]]))
        list(self.pool.map(work, [slice(a, b) for a, b in itertools.pairwise(bounds)]))


@contextmanager
def _bar(show: bool, total: int) -> Iterator[Any]:
    """A callable advancing a tqdm bar of ``total`` directions (a no-op when not shown)."""
    if not show:
        yield lambda n: None
        return
    from tqdm import tqdm

    with tqdm(total=total, desc="visibility table", unit="direction", leave=False) as bar:
        yield bar.update
