"""Body-frame geometry of each row for the fused renderer (numba).

A *row* is one attitude with one Sun/observer geometry (an epoch, a particle, a sigma
point). :func:`body_geometry` turns ``(q, sun, observer)`` into the body-frame unit vectors
``L = A(q) ŝ``, ``V = A(q) ô`` and the distance factor ``(1 AU/r_sun)²/d²`` of each row,
in place on caller-provided outputs.
"""

from __future__ import annotations

import math

from numba import njit

__all__ = ["body_geometry"]

_JIT = {"error_model": "numpy", "nogil": True, "cache": True}


@njit(**_JIT)
def _rotate_unit(q1, q2, q3, q4, vectors, r, out):
    """``out[r] = A(q) v/|v|`` for ``v = vectors[r]`` (docs/conventions.md)."""
    x, y, z = vectors[r, 0], vectors[r, 1], vectors[r, 2]
    norm = math.sqrt(x * x + y * y + z * z)
    x, y, z = x / norm, y / norm, z / norm
    # A(q) v = (q4² − |qv|²) v + 2 qv (qv·v) − 2 q4 (qv × v), as filters.attitude.rotate.
    diagonal = q4 * q4 - (q1 * q1 + q2 * q2 + q3 * q3)
    dot = q1 * x + q2 * y + q3 * z
    out[r, 0] = diagonal * x + 2.0 * q1 * dot - 2.0 * q4 * (q2 * z - q3 * y)
    out[r, 1] = diagonal * y + 2.0 * q2 * dot - 2.0 * q4 * (q3 * x - q1 * z)
    out[r, 2] = diagonal * z + 2.0 * q3 * dot - 2.0 * q4 * (q1 * y - q2 * x)


@njit(**_JIT)
def body_geometry(q, sun, observer, au, light, view, scale):
    """Body-frame unit vectors and the distance factor of each row (float64).

    Parameters
    ----------
    q : (R, 4) float64 array
        Attitudes (inertial → body, scalar last), used as given (like
        :func:`filters.attitude.rotate`).
    sun, observer : (R, 3) float64 arrays
        Object → Sun and object → observer vectors, inertial frame, metres.
    au : float
        ``1 AU`` in metres to scale the solar flux by ``(1 AU/r_sun)²``, or 0 for no scaling.
    light, view : (R, 3) arrays
        Output ``A(q) ŝ`` and ``A(q) ô`` (any float dtype).
    scale : (R,) float64 array
        Output ``(1 AU/r_sun)²/d²`` (``1/d²`` when ``au`` is 0), m⁻².
    """
    for r in range(q.shape[0]):
        q1, q2, q3, q4 = q[r, 0], q[r, 1], q[r, 2], q[r, 3]
        _rotate_unit(q1, q2, q3, q4, sun, r, light)
        _rotate_unit(q1, q2, q3, q4, observer, r, view)
        sun_range2 = sun[r, 0] ** 2 + sun[r, 1] ** 2 + sun[r, 2] ** 2
        observer_range2 = observer[r, 0] ** 2 + observer[r, 1] ** 2 + observer[r, 2] ** 2
        scale[r] = (au * au / sun_range2 if au > 0.0 else 1.0) / observer_range2
