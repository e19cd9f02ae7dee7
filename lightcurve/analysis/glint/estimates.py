"""Panel normals and spin periods from detected glints.

Gou et al. 2016, sec. 2.2: a flat panel flashes when its normal points along the phase-angle
bisector ``h``, so the PAB directions of a panel's flashes measure its normal, and the spacing
of a tumbler's flashes measures its spin period. The glints come from
:func:`lightcurve.analysis.glint.detect_glints` (re-exported there with these functions).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from filters.attitude import rotate
from lightcurve.sky.geometry import lon_lat_deg

if TYPE_CHECKING:
    from lightcurve.analysis.glint.detection import Glint

__all__ = ["PanelNormal", "glint_period", "panel_normal"]


@dataclass
class PanelNormal:
    """Least-squares panel normal from glints.

    Attributes
    ----------
    normal : (3,) float
        Unit normal (body frame when attitudes were given, else inertial).
    sigma_deg : float
        1σ direction error: the scatter of the glint directions about the mean over
        √(n − 1) for several glints, combined with each glint's timing error ``|ḣ| σ_t``.
    cross_track_deg : float
        Half the angle swept by the PAB while the brightest flash was above threshold: a
        bound on how far the normal may lie off the PAB track, which one track cannot see.
    n_glints : int
    """

    normal: np.ndarray
    sigma_deg: float
    cross_track_deg: float
    n_glints: int

    def summary(self) -> dict:
        lon, lat = lon_lat_deg(self.normal)
        return {
            "normal": self.normal.tolist(),
            "lon_deg": lon,
            "lat_deg": lat,
            "sigma_deg": self.sigma_deg,
            "cross_track_bound_deg": self.cross_track_deg,
            "n_glints": self.n_glints,
        }


def panel_normal(
    glints: Sequence[Glint],
    attitudes: Sequence[np.ndarray] | None = None,
) -> PanelNormal:
    """Least-squares normal of one flat panel from the PAB directions of its glints.

    Minimises ``Σ w_k |n − h_k|²`` over unit n (the weighted mean direction), with
    ``w_k = 1/σ_k²`` and ``σ_k = |ḣ_k| σ_t,k`` the direction error from the glint's timing.
    For a stabilised object the normal is fixed in the body frame: pass the attitude
    (inertial → body) at each glint and the PAB directions are rotated into the body frame,
    ``h_B = A(q_k) h_k``, before averaging.

    Parameters
    ----------
    glints : sequence of Glint
        Flashes of the same panel.
    attitudes : sequence of (4,) arrays, optional
        Quaternions at the glint epochs.

    Returns
    -------
    PanelNormal
    """
    if not glints:
        raise ValueError("no glint to estimate a panel normal from")
    directions = np.array([g.pab for g in glints])
    rates = np.array([np.linalg.norm(g.pab_rate) for g in glints])
    if attitudes is not None:
        if len(attitudes) != len(glints):
            raise ValueError(f"{len(attitudes)} attitudes for {len(glints)} glints")
        directions = np.asarray(rotate(np.asarray(attitudes, float), directions))
    sigma = np.maximum(rates * np.array([g.sigma_time_s for g in glints]), 1e-6)
    weights = 1.0 / sigma**2
    mean = weights @ directions
    normal = mean / np.linalg.norm(mean)
    timing = 1.0 / math.sqrt(weights.sum())
    if len(glints) > 1:
        angles = np.arccos(np.clip(directions @ normal, -1.0, 1.0))
        scatter = math.sqrt(np.sum(weights * angles**2) / weights.sum() / (len(glints) - 1))
    else:
        scatter = 0.0
    brightest = max(glints, key=lambda g: g.amplitude_mag)
    cross = 0.5 * float(np.linalg.norm(brightest.pab_rate)) * brightest.duration_s
    return PanelNormal(
        normal,
        math.degrees(math.hypot(timing, scatter)),
        math.degrees(cross),
        len(glints),
    )


def glint_period(glints: Sequence[Glint]) -> tuple[float, float] | None:
    """Spin period from glint-to-glint intervals (a tumbler flashing once per turn).

    Every interval is taken as an integer number of periods, ``Δ_i ≈ n_i P`` (missed flashes
    give ``n_i > 1``): ``n_i = round(Δ_i/Δ_min)`` and ``P = Σ n_i Δ_i / Σ n_i²`` (least
    squares), with the 1σ error from the residual scatter. Flashes of two panels per turn
    give P/2: read the result as "P or a fraction of it".

    Returns
    -------
    (period_s, sigma_s) or None
        None with fewer than three glints.
    """
    if len(glints) < 3:
        return None
    epochs = np.sort([g.time_s for g in glints])
    intervals = np.diff(epochs)
    base = float(np.min(intervals))
    counts = np.maximum(np.round(intervals / base), 1.0)
    period = float(np.sum(counts * intervals) / np.sum(counts**2))
    residual = intervals - counts * period
    dof = max(len(intervals) - 1, 1)
    sigma = math.sqrt(float(np.sum(residual**2)) / dof / float(np.sum(counts**2)))
    timing = math.sqrt(2.0) * float(np.median([g.sigma_time_s for g in glints]))
    return period, max(sigma, timing / math.sqrt(float(np.sum(counts**2))))
