"""Running a row kernel on several threads without spin-waiting.

The numba kernels release the GIL, so disjoint row ranges run in parallel on a pool of
plain Python threads. Idle workers block on a queue (no spinning), so a process that
shares the cores with others burns no CPU between calls. The thread count follows
``torch.get_num_threads()`` (without torch loaded: ``OMP_NUM_THREADS``, else the CPUs the
process may use) unless :func:`set_num_threads` fixes it; work below
:data:`MIN_ELEMENTS_PER_THREAD` facet-rows per thread runs on the calling thread, where a
small call (a UKF's sigma points) pays no hand-over.
"""

from __future__ import annotations

import atexit
import os
import sys
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

__all__ = ["MIN_ELEMENTS_PER_THREAD", "get_num_threads", "run_rows", "set_num_threads"]

#: Facet-rows below which one more thread is not worth its hand-over (~20 µs): ≈ 0.5 ms.
MIN_ELEMENTS_PER_THREAD = 1 << 17

_state: dict[str, object] = {"threads": None, "pool": None, "workers": 0}


def set_num_threads(count: int | None) -> None:
    """Fix the kernels' thread count (``None``: follow ``torch.get_num_threads()``)."""
    if count is not None and int(count) < 1:
        raise ValueError(f"the thread count must be at least 1, got {count}")
    _state["threads"] = None if count is None else int(count)


def get_num_threads() -> int:
    """The kernels' thread count: :func:`set_num_threads`, else torch's intra-op threads
    (``OMP_NUM_THREADS`` or the process's CPUs when torch is not loaded)."""
    if _state["threads"] is not None:
        return int(_state["threads"])
    torch = sys.modules.get("torch")
    if torch is not None:
        return max(1, torch.get_num_threads())
    try:  # torch's own default without importing it: OMP_NUM_THREADS, else the usable CPUs
        return max(1, int(os.environ["OMP_NUM_THREADS"]))
    except (KeyError, ValueError):
        return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()


def _pool(workers: int) -> ThreadPoolExecutor:
    if _state["pool"] is None or _state["workers"] < workers:
        if _state["pool"] is not None:
            _state["pool"].shutdown(wait=False)
        _state["pool"] = ThreadPoolExecutor(workers, thread_name_prefix="lightcurve-render")
        _state["workers"] = workers
    return _state["pool"]


@atexit.register
def _shutdown() -> None:
    if _state["pool"] is not None:
        _state["pool"].shutdown(wait=True)


def run_rows(kernel: Callable[[int, int], None], rows: int, work_per_row: int) -> None:
    """Call ``kernel(start, stop)`` on disjoint row ranges covering ``0:rows``.

    Parameters
    ----------
    kernel : callable
        Processes rows ``start:stop`` (a GIL-releasing kernel writing its own outputs).
    rows : int
        Number of rows.
    work_per_row : int
        Elements per row (facets), to decide how many threads pay off.
    """
    threads = min(get_num_threads(), max(1, rows * work_per_row // MIN_ELEMENTS_PER_THREAD), rows)
    if threads <= 1:
        kernel(0, rows)
        return
    bounds = [rows * k // threads for k in range(threads + 1)]
    pool = _pool(threads - 1)
    futures = [pool.submit(kernel, bounds[k], bounds[k + 1]) for k in range(1, threads)]
    kernel(bounds[0], bounds[1])
    for future in futures:
        future.result()
