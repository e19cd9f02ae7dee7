"""The joint shape-and-attitude fit of ``lightcurve shape`` without ``--attitude``: the
rounds of :func:`lightcurve.analysis.egi.joint.fit_joint` with the project's attitude
inversion (:func:`lightcurve.inversion.invert`, UKF: global search of the initial state,
USQUE filter, whole-arc refit with the inertia and the albedo–area scale) as their attitude
step."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

import brdf
from filters.attitude import attitude_matrix, quaternion_from_matrix
from lightcurve.analysis.egi.joint import JointFit, fit_joint, principal_axes, principal_start
from lightcurve.inversion import invert
from lightcurve.io.observations import Observations
from shapes import FacetModel

__all__ = ["fit_joint_shape", "inverted_states"]


def inverted_states(
    observations: Sequence[Observations], shape: FacetModel, seed: int
) -> tuple[list[tuple[np.ndarray, np.ndarray]], np.ndarray, float, list[np.ndarray]]:
    """Each file's first-epoch state from ``invert`` (UKF) on ``shape``, in the principal
    frame of its inertia; the inertia ratios of the shape; the mean rms residual (mag); the
    per-epoch estimates in that frame
    (:data:`lightcurve.analysis.egi.joint.StateEstimator`)."""
    states, rms, ratios, attitudes = [], [], np.ones(2), []
    for obs in observations:
        result = invert(obs, shape, "ukf", seed=seed)
        q = result.estimates[["q1", "q2", "q3", "q4"]].to_numpy(dtype=float)
        w = result.estimates[["wx", "wy", "wz"]].to_numpy(dtype=float)[0]
        attitude, omega, ratios = principal_start(shape, q[0], w)
        axes = principal_axes(shape)
        attitudes.append(quaternion_from_matrix(np.einsum("ji,ejk->eik", axes, attitude_matrix(q))))
        states.append((attitude, omega))
        rms.append(result.residual_rms_mag)
    return states, ratios, float(np.mean(rms)), attitudes


def fit_joint_shape(
    observations: Sequence[Observations], material: brdf.BRDF, **options
) -> JointFit:
    """:func:`~lightcurve.analysis.egi.joint.fit_joint` with :func:`inverted_states`;
    ``options`` are its keywords (``normals``, ``start``, ``rounds``, ``seed``)."""
    return fit_joint(observations, material, estimate_states=inverted_states, **options)
