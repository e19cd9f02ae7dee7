"""Light-curve simulation: torque-free truth, rendering, and measurement noise.

:func:`simulate` propagates the attitude from the first epoch of a geometry table with the
attitude core's DOP853 integrator, renders the magnitudes with
:class:`~lightcurve.render.Renderer`, adds noise, and returns an observation table with
``mag``, ``mag_err`` and the truth columns ``q1 q2 q3 q4 wx wy wz`` (rad/s). An articulated
shape (:class:`~shapes.articulation.ArticulatedModel`) is rendered by
:class:`~lightcurve.articulated.ArticulatedRenderer` (scheduled joints read their columns
from the geometry table) and every part's joint angle is written as ``joint_<part>_deg``.

The noise models (:class:`GaussianNoise`, :class:`CCDNoise`, :class:`ObservingNoise`) live
in :mod:`lightcurve.noise` and are re-exported here.

Epochs when the object is dark (no lit facet visible) and, with the photon-counting models,
non-detections (measured counts ≤ 0) cannot be measured: they are dropped and counted in
the metadata (``dropped_dark``, ``dropped_nondetections``), as are rows a noise model asks
to drop (``dropped_<reason>``, e.g. ``dropped_saturated``).
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

from filters.attitude import quaternion_normalize, validate_inertia
from lightcurve.noise import CCDNoise, GaussianNoise, Measurement, NoiseModel, ObservingNoise
from lightcurve.observations import TRUTH_COLUMNS, Observations, validate_table
from lightcurve.render import Renderer
from shapes import FacetModel
from shapes.articulation import ArticulatedModel

__all__ = [
    "CCDNoise",
    "GaussianNoise",
    "NoiseModel",
    "ObservingNoise",
    "simulate",
    "truth_states",
]


def truth_states(
    times: np.ndarray, q0: np.ndarray, omega0: np.ndarray, inertia: np.ndarray
) -> np.ndarray:
    """Torque-free states at ``times`` from ``[q0, ω0]`` at ``times[0]``.

    scipy's DOP853 at rtol = atol = 1e-12, as the attitude core's
    :func:`~filters.attitude.propagate`, with the compiled right-hand side
    :func:`lightcurve.kernels.dynamics.torque_free_rate` (one state: ~30× cheaper per call
    than the batched array-API form, which dominated long simulations). The output
    quaternions are renormalised.

    Parameters
    ----------
    times : (n,) array
        Seconds, strictly increasing.
    q0 : (4,) array
        Attitude at ``times[0]`` (inertial → body), normalised here.
    omega0 : (3,) array
        Body rates at ``times[0]`` (rad/s).
    inertia : (3, 3) array
        Body-frame inertia.

    Returns
    -------
    (n, 7) numpy.ndarray
        ``[q1..q4, ωx, ωy, ωz]`` with the quaternion sign continuous in time.
    """
    from lightcurve.kernels.dynamics import torque_free_rate

    j = validate_inertia(inertia)
    j_inv = np.linalg.inv(j)
    t = np.asarray(times, dtype=float)
    if t.ndim != 1 or t.size == 0 or not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise ValueError("times must be a non-empty, finite, strictly increasing 1-D sequence")
    x0 = np.concatenate([quaternion_normalize(np.asarray(q0, float)), np.asarray(omega0, float)])
    if not np.all(np.isfinite(x0)):
        raise ValueError(f"initial state must be finite, got {x0}")
    if t.size == 1:
        return x0[None]
    solution = solve_ivp(
        lambda _t, x: torque_free_rate(x, j, j_inv),
        (t[0], t[-1]),
        x0,
        method="DOP853",
        t_eval=t,
        rtol=1e-12,
        atol=1e-12,
    )
    if not solution.success:
        raise RuntimeError(f"attitude propagation failed: {solution.message}")
    states = solution.y.T
    states[:, :4] = quaternion_normalize(states[:, :4])
    return states


def simulate(
    geometry: Observations,
    shape: FacetModel | ArticulatedModel,
    q0: np.ndarray,
    omega0: np.ndarray,
    inertia: np.ndarray | None = None,
    noise: NoiseModel | None = None,
    shadows: str = "auto",
    seed: int | np.random.Generator | None = None,
) -> Observations:
    """Simulate a light curve over the epochs of a geometry table.

    Parameters
    ----------
    geometry : Observations
        Epochs and Sun/observer vectors (``mag`` columns, if any, are replaced).
    shape : FacetModel or ArticulatedModel
        Shape with materials (and parts).
    q0 : (4,) array
        Attitude at the first epoch (inertial → body).
    omega0 : (3,) array
        Body rates at the first epoch (rad/s, body frame).
    inertia : (3, 3) array, optional
        Body-frame inertia; defaults to the shape's.
    noise : NoiseModel, optional
        Measurement noise; without it ``mag`` is exact and ``mag_err`` is 1e-6.
    shadows : str
        Renderer shadow mode (``"auto"``, ``"none"``, ``"table"``, ``"exact"``).
    seed : int or numpy.random.Generator, optional
        Noise seed.

    Returns
    -------
    Observations
        With ``mag``, ``mag_err`` and the truth columns; metadata records the shape, the
        initial state, the inertia, the noise model and the seed.
    """
    rng = np.random.default_rng(seed)
    inertia = shape.inertia if inertia is None else np.asarray(inertia, float)
    states = truth_states(geometry.times, q0, omega0, inertia)
    joints = {}
    if isinstance(shape, ArticulatedModel):
        from lightcurve.articulated import ArticulatedRenderer

        renderer = ArticulatedRenderer(shape, shadows=shadows)
        columns = {
            p.joint.column: geometry.table[p.joint.column].to_numpy(float)
            for p in shape.articulation.parts
            if p.joint.column is not None and p.joint.column in geometry.table
        }
        args = (states[:, :4], geometry.sun_vectors, geometry.observer_vectors)
        magnitude = renderer.magnitude(*args, columns)
        angles = renderer.joint_angles(args[0], args[1], columns)
        joints = dict(zip(shape.articulation.names, angles, strict=True))
    else:
        renderer = Renderer(shape, shadows=shadows)
        magnitude = renderer.magnitude(
            states[:, :4], geometry.sun_vectors, geometry.observer_vectors
        )
    dark = ~np.isfinite(magnitude)
    if noise is None:
        measurement = Measurement(magnitude, np.full_like(magnitude, 1e-6))
    else:
        measurement = noise.measure(np.where(dark, 0.0, magnitude), geometry, rng)
    measured = measurement.magnitude
    nondetected = ~dark & ~np.isfinite(measured)
    keep = ~dark & ~nondetected
    dropped = {reason: mask & keep for reason, mask in measurement.drop.items()}
    for mask in dropped.values():
        keep &= ~mask
    table = geometry.table.loc[keep].drop(columns=["mag", "mag_err"], errors="ignore").copy()
    table["mag"] = measured[keep]
    table["mag_err"] = measurement.error[keep]
    for name, values in measurement.columns.items():
        table[name] = np.asarray(values)[keep]
    for k, column in enumerate(TRUTH_COLUMNS):
        table[column] = states[keep, k]
    for part, angle in joints.items():
        table[f"joint_{part}_deg"] = angle[keep]
    meta = dict(geometry.meta)
    meta.update(
        {
            "simulated": "true",
            "shape": shape.name,
            "q0": ",".join(f"{v:.12g}" for v in q0),
            "omega0_rad_s": ",".join(f"{v:.12g}" for v in omega0),
            "inertia": ",".join(f"{v:.12g}" for v in np.asarray(inertia).ravel()),
            "noise": noise.describe() if noise is not None else "none",
            "shadows": renderer.shadows,
            "seed": str(seed) if not isinstance(seed, np.random.Generator) else "generator",
        }
    )
    if dark.any():
        meta["dropped_dark"] = str(int(dark.sum()))
    if nondetected.any():
        meta["dropped_nondetections"] = str(int(nondetected.sum()))
    for reason, mask in dropped.items():
        if mask.any():
            meta[f"dropped_{reason}"] = str(int(mask.sum()))
    if not keep.any():
        raise ValueError(
            "the object is dark or undetected at every epoch"
            + (f" (or dropped as {', '.join(dropped)})" if dropped else "")
        )
    return Observations(validate_table(table, geometry.source, meta), meta, geometry.source)
