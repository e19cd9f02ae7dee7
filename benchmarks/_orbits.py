"""Random low orbits shared by the benchmarks' low-orbit scenarios."""

from __future__ import annotations

import numpy as np

from lightcurve.sky.ephemeris import EARTH_RADIUS_KM, CircularOrbit

#: Ranges of the drawn circular low orbits: altitude (km) and inclination (deg).
LEO_ALTITUDE_KM = (500.0, 1200.0)
LEO_INCLINATION_DEG = (45.0, 100.0)


def random_low_orbit(rng: np.random.Generator, epoch_mjd: float) -> CircularOrbit:
    """A circular low orbit: altitude uniform in ``LEO_ALTITUDE_KM``, inclination uniform in
    ``LEO_INCLINATION_DEG``, node and argument of latitude at ``epoch_mjd`` uniform in
    [0°, 360°), drawn from ``rng`` in that order."""
    return CircularOrbit(
        EARTH_RADIUS_KM + float(rng.uniform(*LEO_ALTITUDE_KM)),
        float(rng.uniform(*LEO_INCLINATION_DEG)),
        float(rng.uniform(0.0, 360.0)),
        float(rng.uniform(0.0, 360.0)),
        epoch_mjd,
    )
