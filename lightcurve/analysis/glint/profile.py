"""Panel normals in the body frame of a stabilised satellite from its glints.

A flat panel flashes when its normal lies along the phase-angle bisector
``h = (ŝ + ô)/|ŝ + ô|`` of the Sun and observer directions from the object (Gou, Du & Liu
2016, "Advances in attitude inversion of space object based on photometric data", sec. 2.2;
:mod:`lightcurve.analysis.glint`).
When the object is held in a known attitude profile (:mod:`lightcurve.photometry.profiles`:
``inertial``, ``nadir`` with optional yaw steering, ``sun-pointing``, each with a fixed
offset), the attitude at a glint's epoch is known, and the glint's bisector turned into
the body frame, ``h_B = A(q(t_g)) h``, is the panel's normal in the body frame. Glints of the
same body-fixed panel give the same ``h_B``, glints of different facets (a bus face, the back
of an array) different ones: the glints are grouped into panels — taken brightest first, each
joins the panel whose mean direction is nearest if within ``tolerance_deg``, else starts a new
one — and each panel's glints are combined by the weighted mean on the sphere of
:func:`lightcurve.analysis.glint.panel_normal` (weights from each glint's timing error), with their
spread about it (the RMS angle).

The profile attitude is evaluated at the observation epochs from the file's object-position
and Sun columns (:func:`lightcurve.photometry.profiles.profile_states`) and interpolated to each
glint's epoch by spherical linear interpolation (exact for the ``nadir`` profile's uniform
turn about the orbit normal).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from filters.attitude import rotate
from lightcurve.analysis.glint import Glint, panel_normal
from lightcurve.io.observations import Observations
from lightcurve.photometry.profiles import offset_quaternion, profile_states

__all__ = ["BodyNormal", "body_normals", "group_panels", "profile_attitudes_at"]


@dataclass
class BodyNormal:
    """Body-frame panel normal from glints under a known attitude profile.

    Attributes
    ----------
    normal : (3,) numpy.ndarray
        Weighted mean of the glints' body-frame bisectors (unit vector, body frame).
    spread_deg : float
        RMS angle (deg) of the panel's glints' body-frame bisectors about ``normal`` (0 for
        one glint).
    sigma_deg : float
        1σ direction error of ``normal`` (deg; timing errors and scatter, as
        :class:`lightcurve.analysis.glint.PanelNormal`).
    cross_track_bound_deg : float
        Bound (deg) on how far the normal may lie off the bisector's track, which the
        glint epochs cannot see (:class:`lightcurve.analysis.glint.PanelNormal`).
    glints : (k,) numpy.ndarray of int
        Indices of the panel's glints in the list given.
    directions : (k, 3) numpy.ndarray
        Each glint's bisector in the body frame.
    attitudes : (k, 4) numpy.ndarray
        Profile attitude (inertial → body) at each glint's epoch.
    """

    normal: np.ndarray
    spread_deg: float
    sigma_deg: float
    cross_track_bound_deg: float
    glints: np.ndarray
    directions: np.ndarray
    attitudes: np.ndarray

    @property
    def n_glints(self) -> int:
        return len(self.directions)

    def summary(self) -> dict:
        """Keys ``normal_body``, ``spread_deg``, ``sigma_deg``, ``cross_track_bound_deg``,
        ``n_glints``, ``glints`` (indices)."""
        return {
            "normal_body": [float(v) for v in self.normal],
            "spread_deg": float(self.spread_deg),
            "sigma_deg": float(self.sigma_deg),
            "cross_track_bound_deg": float(self.cross_track_bound_deg),
            "n_glints": self.n_glints,
            "glints": [int(i) for i in self.glints],
        }


def profile_attitudes_at(
    observations: Observations,
    profile: str,
    times_s: Sequence[float] | np.ndarray,
    *,
    offset_deg: Sequence[float] | np.ndarray | None = None,
    yaw_steering: bool = False,
) -> np.ndarray:
    """Attitudes of a stabilised profile at given epochs of an observation file.

    Parameters
    ----------
    observations : Observations
        The file: Sun columns, and the object's position and velocity (``obj_*``, for the
        ``nadir`` profile).
    profile : {"inertial", "nadir", "sun-pointing"}
    times_s : (k,) array
        Epochs, s after the file's first epoch (``Observations.times``), within its span.
    offset_deg : (3,) array, optional
        ``[roll, pitch, yaw]`` offset from the profile frame (deg, 3-2-1; for ``inertial``
        the attitude's angles from the inertial axes); default none.
    yaw_steering : bool
        ``nadir`` only.

    Returns
    -------
    (k, 4) numpy.ndarray
        Quaternions inertial → body (scalar last).

    Raises
    ------
    ValueError
        An epoch outside the file's span, or the file lacks the columns the profile needs.
    """
    times = observations.times
    t = np.atleast_1d(np.asarray(times_s, dtype=float))
    outside = (t < times[0]) | (t > times[-1])
    if np.any(outside):
        where = observations.source or observations.name
        raise ValueError(
            f"{where}: epoch {t[np.argmax(outside)]:.6g} s is outside the file's span "
            f"[0, {times[-1]:.6g}] s"
        )
    q = profile_states(
        observations,
        profile,
        yaw_steering=yaw_steering,
        offset=offset_quaternion(offset_deg),
    )[:, :4]
    if len(times) == 1:
        return np.repeat(q, len(t), axis=0)
    # Rows at the same epoch (several light curves) carry the same attitude: keep one.
    unique, first = np.unique(times, return_index=True)
    return Slerp(unique, Rotation.from_quat(q[first]))(t).as_quat()


def group_panels(
    directions: np.ndarray, amplitudes: np.ndarray, tolerance_deg: float
) -> list[np.ndarray]:
    """Group body-frame glint directions into panels (see the module doc).

    Parameters
    ----------
    directions : (k, 3) array
        Unit vectors (body frame).
    amplitudes : (k,) array
        Brightening of each glint (mag): the brightest are placed first.
    tolerance_deg : float
        Largest angle (deg) between a glint and the mean direction of the panel it joins.

    Returns
    -------
    list of numpy.ndarray of int
        Indices of each panel's glints, the panel of the brightest glint first.
    """
    if not tolerance_deg > 0:
        raise ValueError(f"tolerance_deg must be positive, got {tolerance_deg}")
    limit = math.cos(math.radians(tolerance_deg))
    members: list[list[int]] = []
    means: list[np.ndarray] = []
    for i in np.argsort(-np.asarray(amplitudes, float), kind="stable"):
        cosines = np.array([m @ directions[i] for m in means])
        if len(cosines) and cosines.max() >= limit:
            j = int(np.argmax(cosines))
            members[j].append(int(i))
            total = directions[members[j]].sum(axis=0)
            means[j] = total / np.linalg.norm(total)
        else:
            members.append([int(i)])
            means.append(directions[i])
    return [np.array(m) for m in members]


def body_normals(
    observations: Observations,
    glints: Sequence[Glint],
    profile: str,
    *,
    offset_deg: Sequence[float] | np.ndarray | None = None,
    yaw_steering: bool = False,
    tolerance_deg: float = 5.0,
) -> list[BodyNormal]:
    """Panel normals in the body frame from glints of an object held in a known profile.

    Parameters
    ----------
    observations : Observations
        The light curve the glints were detected in (with the columns the profile needs).
    glints : sequence of Glint
        Detected flashes (:func:`lightcurve.analysis.glint.detect_glints`).
    profile, offset_deg, yaw_steering
        The attitude profile (:func:`profile_attitudes_at`).
    tolerance_deg : float
        Grouping of the glints into panels (:func:`group_panels`).

    Returns
    -------
    list of BodyNormal
        One per panel, the panel of the brightest glint first.

    Raises
    ------
    ValueError
        No glint, or the profile cannot be evaluated on the file.
    """
    if not glints:
        raise ValueError("no glint to estimate a panel normal from")
    attitudes = profile_attitudes_at(
        observations,
        profile,
        [g.time_s for g in glints],
        offset_deg=offset_deg,
        yaw_steering=yaw_steering,
    )
    directions = np.asarray(rotate(attitudes, np.array([g.pab for g in glints])))
    panels = []
    for rows in group_panels(directions, [g.amplitude_mag for g in glints], tolerance_deg):
        mean = panel_normal([glints[i] for i in rows], list(attitudes[rows]))
        angles = np.arccos(np.clip(directions[rows] @ mean.normal, -1.0, 1.0))
        panels.append(
            BodyNormal(
                normal=mean.normal,
                spread_deg=math.degrees(math.sqrt(float(np.mean(angles**2)))),
                sigma_deg=mean.sigma_deg,
                cross_track_bound_deg=mean.cross_track_deg,
                glints=rows,
                directions=directions[rows],
                attitudes=attitudes[rows],
            )
        )
    return panels
