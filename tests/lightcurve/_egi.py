"""Light curves of a convex object with known attitudes at random geometries, as files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from lightcurve import io
from lightcurve.io.observations import Observations, validate_table
from lightcurve.photometry.render import Renderer
from shapes import FacetModel

from ._geometry import random_geometry


def known_attitude_file(
    shape: FacetModel, path: Path, *, epochs: int, seed: int, noise_mag: float = 0.02
) -> Path:
    """An observation file of ``shape`` at ``epochs`` random attitudes and Sun/observer
    directions (phase angles below 120°, lit and seen), Gaussian noise ``noise_mag``
    (seeded), with the truth columns; written to ``path``."""
    q, sun, obs = random_geometry(3 * epochs, seed)
    phase = np.arccos(
        np.sum(sun * obs, 1) / np.linalg.norm(sun, axis=1) / np.linalg.norm(obs, axis=1)
    )
    mag = Renderer(shape).magnitude(q, sun, obs)
    keep = np.flatnonzero((phase < np.radians(120.0)) & np.isfinite(mag))[:epochs]
    q, sun, obs, mag = q[keep], sun[keep], obs[keep], mag[keep]
    rng = np.random.default_rng(seed + 1)
    table = pd.DataFrame(
        {
            "mjd": 60000.0 + np.arange(len(keep)) * 10.0 / 86400.0,
            "mag": mag + noise_mag * rng.standard_normal(len(keep)),
            "mag_err": noise_mag,
            **{f"sun_{a}": sun[:, i] / 1e3 for i, a in enumerate("xyz")},
            **{f"obs_{a}": obs[:, i] / 1e3 for i, a in enumerate("xyz")},
            **{f"q{i + 1}": q[:, i] for i in range(4)},
            **{f"w{a}": 0.0 for a in "xyz"},
        }
    )
    io.write(Observations(validate_table(table, str(path)), {}), path)
    return path
