"""Random viewing geometries for the renderer and kernel tests."""

from __future__ import annotations

import numpy as np

from filters.attitude import random_quaternion

AU = 1.495978707e11


def random_geometry(n: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``n`` uniform attitudes with Sun and observer vectors (m, inertial) in uniform directions.

    The Sun is at 1 AU, the observer at 400–40 000 km (uniform in range).

    Returns
    -------
    q : (n, 4) array
        Scalar-last attitude quaternions (inertial → body).
    sun, obs : (n, 3) arrays
        Object → Sun and object → observer vectors, m.
    """
    rng = np.random.default_rng(seed)
    sun = rng.normal(size=(n, 3))
    sun *= AU / np.linalg.norm(sun, axis=1, keepdims=True)
    obs = rng.normal(size=(n, 3))
    obs *= rng.uniform(4e5, 4e7, (n, 1)) / np.linalg.norm(obs, axis=1, keepdims=True)
    return random_quaternion(n, rng), sun, obs
