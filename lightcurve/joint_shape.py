"""The joint shape-and-attitude fit of ``lightcurve shape`` without ``--attitude``: the
rounds of :func:`lightcurve.analysis.egi.joint.fit_joint` with the project's attitude
inversion (:func:`lightcurve.inversion.invert`, UKF: global search of the initial state,
USQUE filter, whole-arc refit with the inertia and the albedo–area scale) as their attitude
step."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

import brdf
from lightcurve.analysis.egi.joint import JointFit, fit_joint, principal_start
from lightcurve.inversion import invert
from lightcurve.io.observations import Observations
from shapes import FacetModel

__all__ = ["fit_joint_shape", "inverted_states"]


def inverted_states(
    observations: Sequence[Observations], shape: FacetModel, seed: int
) -> tuple[list[tuple[np.ndarray, np.ndarray]], np.ndarray, float]:
    """Each file's first-epoch state from ``invert`` (UKF) on ``shape``, in the principal
    frame of its inertia; the inertia ratios of the shape; the mean rms residual (mag)
    (:data:`lightcurve.analysis.egi.joint.StateEstimator`)."""
    states, rms, ratios = [], [], np.ones(2)
    for obs in observations:
        result = invert(obs, shape, "ukf", seed=seed)
        first = result.estimates.iloc[0]
        q = first[["q1", "q2", "q3", "q4"]].to_numpy(dtype=float)
        w = first[["wx", "wy", "wz"]].to_numpy(dtype=float)
        attitude, omega, ratios = principal_start(shape, q, w)
        states.append((attitude, omega))
        rms.append(result.residual_rms_mag)
    return states, ratios, float(np.mean(rms))


def fit_joint_shape(
    observations: Sequence[Observations], material: brdf.BRDF, **options
) -> JointFit:
    """:func:`~lightcurve.analysis.egi.joint.fit_joint` with :func:`inverted_states`;
    ``options`` are its keywords (``normals``, ``start``, ``rounds``, ``seed``)."""
    return fit_joint(observations, material, estimate_states=inverted_states, **options)
