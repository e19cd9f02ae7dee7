"""Best-of-repeats timing shared by the benchmarks (the machine is shared: the best run is the
least disturbed one)."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any


def best_time(func: Callable[[], Any], repeats: int) -> float:
    """Smallest wall-clock time of ``repeats`` calls of ``func()`` (s).

    Parameters
    ----------
    func : callable
        Called without arguments; its result is discarded.
    repeats : int
        Number of timed calls (no warm-up call).

    Returns
    -------
    float
        Seconds of the fastest call (``inf`` when ``repeats`` is 0).
    """
    seconds = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        func()
        seconds = min(seconds, time.perf_counter() - start)
    return seconds
