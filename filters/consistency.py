"""Filter consistency over a sliding window of normalised innovations squared.

A consistent filter's normalised innovations squared ``ν²/S`` of a scalar measurement are
χ²(1)-distributed, so their mean over a window of ``W`` measurements follows ``χ²(W)/W``
(Bar-Shalom, Li & Kirubarajan 2001, *Estimation with Applications to Tracking and
Navigation*, sec. 5.4). A window whose mean exceeds the upper quantile of that distribution
flags a filter (or a model) that does not fit. Each value is capped so that one outlier
(a glint) does not dominate the window.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from filters.gaussian import chi2_band

__all__ = ["NISWindow"]


class NISWindow:
    """Sliding-window mean of normalised innovations squared against its χ² bound.

    Parameters
    ----------
    size : int
        Measurements in the window ``W``.
    level : float
        Quantile of ``χ²(W)/W`` above which the window is inconsistent (the upper bound of
        the two-sided band of probability ``1 − 2(1 − level)``).
    cap : float
        Each value is capped at this before it enters the window.

    Attributes
    ----------
    bound : float
        The ``level`` quantile of ``χ²(W)/W``.
    """

    def __init__(self, size: int, level: float, cap: float = 25.0) -> None:
        if size < 1 or not 0.5 < level < 1.0:
            raise ValueError(f"window size must be ≥ 1 and level in (0.5, 1), got {size}, {level}")
        self.size = int(size)
        self.cap = float(cap)
        self.bound = chi2_band(1, self.size, 1.0 - 2.0 * (1.0 - level))[1]
        self._values: deque[float] = deque(maxlen=self.size)

    def __len__(self) -> int:
        return len(self._values)

    def add(self, value: float) -> None:
        """Add one value (capped at :attr:`cap`), dropping the oldest from a full window."""
        self._values.append(min(float(value), self.cap))

    @property
    def full(self) -> bool:
        """The window holds ``size`` values."""
        return len(self._values) == self.size

    @property
    def mean(self) -> float:
        """Mean of the values in the window (NaN when empty)."""
        return float(np.mean(self._values)) if self._values else math.nan

    @property
    def inconsistent(self) -> bool:
        """The window is full and its mean exceeds :attr:`bound`."""
        return self.full and self.mean > self.bound
