"""Earth orientation: rotations between the TEME, ITRS and GCRS frames at many epochs.

SGP4 gives positions in the TEME frame (true equator, mean equinox of date; Vallado et
al. 2006, "Revisiting Spacetrack Report #3", AIAA 2006-6753, appendix C); ground sites are
fixed in the ITRS; observation files are written in the GCRS. astropy's ``TEME``, ``ITRS``
and ``GCRS`` frames define the rotations (offline: the IERS tables bundled with
``astropy-iers-data``, automatic downloads switched off):

* ``r_ITRS = W · R3(θ) · r_TEME`` with ``θ`` the Greenwich mean sidereal time of 1982
  (IAU 1982 GMST, of UT1) and ``W`` the polar-motion matrix (IERS pole coordinates);
* ``r_GCRS = M_TG · r_TEME``, where ``M_TG`` (TEME → ITRS → CIRS → GCRS: IAU 2006/2000A
  precession–nutation, Earth rotation angle, polar motion) turns only slowly, because the
  two Earth rotations (GMST in TEME → ITRS and the Earth rotation angle in ITRS → CIRS)
  cancel up to the precession in right ascension;
* ``r_GCRS = M_TG · R3(θ)ᵀ · Wᵀ · r_ITRS``.

astropy evaluates these rotations at a cost of ~0.1 ms per epoch, which is most of the
budget for 10⁵ epochs. So astropy is asked only on a grid of nodes six hours apart, aligned
with 0 h UTC where the daily IERS values are, around the requested epochs: the slowly
varying ``M_TG`` is interpolated with the cubic Lagrange polynomial through the four nearest
nodes, ``W`` and ``UT1 − TAI`` linearly (astropy interpolates the daily IERS pole
coordinates and UT1 − UTC linearly, so this reproduces them), and the fast rotation ``θ`` is
computed at every epoch from UT1 (``erfa.gmst82``). The rotations agree with astropy's own
transformations at every epoch to a few 10⁻¹² rad (``tests/lightcurve/sky/test_frames.py``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = [
    "NODE_SPACING_DAYS",
    "FrameRotations",
    "astropy_offline",
    "frame_rotations",
    "interpolate_at_nodes",
    "rotation_z",
]

#: Spacing of the nodes at which astropy is evaluated (days).
NODE_SPACING_DAYS = 0.25
_SECONDS_PER_DAY = 86_400.0


def astropy_offline() -> Any:
    """Import astropy with IERS downloads switched off; returns ``astropy.units``."""
    from astropy.utils import iers

    iers.conf.auto_download = False
    iers.conf.auto_max_age = None
    import astropy.units as u

    return u


def rotation_z(angle: np.ndarray) -> np.ndarray:
    """Frame rotations about z, ``R3(α) = [[cos α, sin α, 0], [−sin α, cos α, 0], [0, 0, 1]]``.

    Parameters
    ----------
    angle : (n,) array
        Angles (rad).

    Returns
    -------
    (n, 3, 3) numpy.ndarray
        ``R3(α) v`` expresses ``v`` in axes turned by ``α`` about z.
    """
    c, s = np.cos(angle), np.sin(angle)
    zero, one = np.zeros_like(c), np.ones_like(c)
    return np.stack(
        [np.stack([c, s, zero], -1), np.stack([-s, c, zero], -1), np.stack([zero, zero, one], -1)],
        axis=-2,
    )


def _node_grid(mjd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Node times (MJD) and, per epoch, the index of the node at or before it.

    Every epoch gets the nodes ``k − 1, k, k + 1, k + 2`` (``k = ⌊mjd / h⌋``), so the
    cubic Lagrange interpolation is centred on the epoch's interval.
    """
    index = np.floor(mjd / NODE_SPACING_DAYS).astype(np.int64)
    nodes = np.unique(np.concatenate([index + shift for shift in (-1, 0, 1, 2)]))
    return nodes * NODE_SPACING_DAYS, np.searchsorted(nodes, index)


def _tai_days(mjd: np.ndarray) -> np.ndarray:
    """UTC MJDs → days of TAI since MJD 0."""
    astropy_offline()
    from astropy.time import Time

    tai = Time(mjd, format="mjd", scale="utc").tai
    return (tai.jd1 - 2_400_000.5) + tai.jd2


def interpolate_at_nodes(
    mjd: np.ndarray, evaluate: Any, linear: Sequence[bool] | bool = False
) -> np.ndarray | tuple[np.ndarray, ...]:
    """Evaluate slowly varying functions on the node grid and interpolate them.

    Parameters
    ----------
    mjd : (n,) array
        UTC epochs (MJD); the interpolation runs in TAI.
    evaluate : callable
        ``evaluate(node_mjd) -> array (m, ...)`` or a tuple of such arrays; called once,
        at the epochs themselves when they are fewer than the nodes.
    linear : bool or sequence of bool
        Per returned array: linear interpolation between the two bracketing nodes instead
        of the cubic Lagrange polynomial through four.

    Returns
    -------
    array (n, ...) or tuple of arrays
        The interpolated values, as ``evaluate`` returns them.
    """
    mjd = np.asarray(mjd, dtype=float)
    node_mjd, at = _node_grid(mjd)
    if node_mjd.size >= mjd.size:
        return evaluate(mjd)  # fewer epochs than nodes: evaluate exactly
    values = evaluate(node_mjd)
    single = not isinstance(values, tuple)
    values = (values,) if single else values
    linear = [linear] * len(values) if isinstance(linear, bool) else list(linear)
    # Weights in TAI, uniform even across a leap second (a UTC day can last 86 401 s).
    t, node_t = _tai_days(mjd), _tai_days(node_mjd)
    times = {shift: node_t[at + shift] for shift in (-1, 0, 1, 2)}

    def basis(shift: int, others: tuple[int, ...]) -> np.ndarray:
        weight = np.ones_like(t)
        for other in others:
            weight *= (t - times[other]) / (times[shift] - times[other])
        return weight

    cubic_weights = {
        shift: basis(shift, tuple(o for o in (-1, 0, 1, 2) if o != shift))
        for shift in (-1, 0, 1, 2)
    }
    linear_weights = {0: basis(0, (1,)), 1: basis(1, (0,))}
    out = []
    for value, is_linear in zip(values, linear, strict=True):
        total = np.zeros((mjd.size, *value.shape[1:]))
        for shift, weight in (linear_weights if is_linear else cubic_weights).items():
            total += weight.reshape(-1, *([1] * (value.ndim - 1))) * value[at + shift]
        out.append(total)
    return out[0] if single else tuple(out)


@dataclass(frozen=True)
class FrameRotations:
    """Rotation matrices at a set of epochs; ``r_to = M · r_from``.

    Attributes
    ----------
    teme_to_gcrs, teme_to_itrs, itrs_to_gcrs : (n, 3, 3) numpy.ndarray
    """

    teme_to_gcrs: np.ndarray
    teme_to_itrs: np.ndarray
    itrs_to_gcrs: np.ndarray


def _astropy_rotations(node_mjd: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """astropy's TEME → GCRS matrices, polar-motion matrices and UT1 − TAI (s) at nodes."""
    import erfa

    u = astropy_offline()
    from astropy.coordinates import GCRS, ITRS, TEME, CartesianRepresentation
    from astropy.time import Time

    n = node_mjd.size
    times = Time(np.repeat(node_mjd, 3), format="mjd", scale="utc")
    basis = CartesianRepresentation(np.tile(np.eye(3), (n, 1)).T * u.km)
    teme = TEME(basis, obstime=times)
    # Column j of a matrix is the image of the j-th TEME basis vector.
    to_gcrs = teme.transform_to(GCRS(obstime=times)).cartesian.xyz.to_value(u.km).T
    to_itrs = teme.transform_to(ITRS(obstime=times)).cartesian.xyz.to_value(u.km).T
    to_gcrs = to_gcrs.reshape(n, 3, 3).transpose(0, 2, 1)
    to_itrs = to_itrs.reshape(n, 3, 3).transpose(0, 2, 1)
    node_times = Time(node_mjd, format="mjd", scale="utc")
    ut1, tai = node_times.ut1, node_times.tai
    theta = erfa.gmst82(ut1.jd1, ut1.jd2)
    polar_motion = to_itrs @ rotation_z(theta).transpose(0, 2, 1)
    ut1_minus_tai = ((ut1.jd1 - tai.jd1) + (ut1.jd2 - tai.jd2)) * _SECONDS_PER_DAY
    return to_gcrs, polar_motion, ut1_minus_tai


def frame_rotations(mjd: np.ndarray) -> FrameRotations:
    """TEME, ITRS and GCRS rotation matrices at UTC epochs.

    Parameters
    ----------
    mjd : (n,) array
        UTC Modified Julian Dates.

    Returns
    -------
    FrameRotations

    Raises
    ------
    ValueError
        If an epoch is outside the bundled IERS tables (astropy's message).
    """
    import erfa

    astropy_offline()
    from astropy.time import Time

    mjd = np.atleast_1d(np.asarray(mjd, dtype=float))
    teme_to_gcrs, polar_motion, ut1_minus_tai = interpolate_at_nodes(
        mjd, _astropy_rotations, linear=(False, True, True)
    )
    tai = Time(mjd, format="mjd", scale="utc").tai
    jd1 = tai.jd1
    jd2 = tai.jd2 + ut1_minus_tai / _SECONDS_PER_DAY
    theta = erfa.gmst82(jd1, jd2)
    teme_to_itrs = polar_motion @ rotation_z(theta)
    itrs_to_gcrs = teme_to_gcrs @ teme_to_itrs.transpose(0, 2, 1)
    return FrameRotations(teme_to_gcrs, teme_to_itrs, itrs_to_gcrs)
