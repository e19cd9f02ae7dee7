"""Fused rendering kernels compiled with numba: the renderer's fast path on the CPU.

:class:`FusedFlux` holds a shape's facets and material blocks in the kernels' layout and
evaluates ``Σ_i ρ_i A_i (n_i·L)(n_i·V) · shadow_i`` for any number of rows (attitude ×
geometry) in one pass over the facets per row: cosines, BRDF, clamps, shadow factor and the
facet sum are fused, so no (rows × facets) array is built. Kernels are compiled on first use
and cached on disk by numba (``cache=True``: in ``__pycache__`` beside this package, or in
numba's user cache folder when that is read-only, or ``NUMBA_CACHE_DIR``), so the
compilation is paid once per machine and installation, not per process.

Modules: :mod:`~lightcurve.photometry.kernels.fused` (:class:`FusedFlux`: the facet table,
material blocks and the dispatch of rows), :mod:`~lightcurve.photometry.kernels.elementary`
(vectorisable ``exp``/``log``), :mod:`~lightcurve.photometry.kernels.brdf_sums` (one row loop per
BRDF), :mod:`~lightcurve.photometry.kernels.tiles` (facets in tiles bounded by cones of normals),
:mod:`~lightcurve.photometry.kernels.rows` (body-frame geometry),
:mod:`~lightcurve.photometry.kernels.threads` (row ranges on a thread pool),
:mod:`~lightcurve.photometry.kernels.dynamics` (torque-free dynamics as a compiled right-hand
side for scipy's integrators).

This ``__init__`` only hands the public names on.
"""

from lightcurve.photometry.kernels.brdf_sums import KINDS
from lightcurve.photometry.kernels.fused import FusedFlux, block_parameters, facet_table
from lightcurve.photometry.kernels.threads import get_num_threads, set_num_threads

__all__ = [
    "KINDS",
    "FusedFlux",
    "block_parameters",
    "facet_table",
    "get_num_threads",
    "set_num_threads",
]
