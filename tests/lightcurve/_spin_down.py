"""Nightly light curves of a double-peaked rotator whose period grows 1 % per night."""

import numpy as np

from benchmarks.glint_power import fixed_geometry_curve
from lightcurve.io.observations import Observations


def spin_down_nights(count: int, period_s: float = 600.0) -> list[Observations]:
    """``count`` 2-h nights (20 s cadence, 0.01 mag, seeded by the night), one day apart;
    night n has the period ``period_s · (1 + 0.01 n)``: Ṗ = 0.01 · period_s per day."""
    nights = []
    for night in range(count):
        period = period_s * (1 + 0.01 * night)
        t = np.arange(0.0, 7200.0, 20.0)
        mag = 0.3 * np.cos(4 * np.pi * t / period) + 0.1 * np.cos(2 * np.pi * t / period)
        noise = np.random.default_rng(night).normal(0, 0.01, len(t))
        nights.append(fixed_geometry_curve(t + night * 86400.0, mag + noise, 0.01, f"n{night}"))
    return nights
