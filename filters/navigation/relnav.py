"""Multi-mode relative navigation with IMU control input and robust position fixes.

The navigator of Shi, Zhang, Li, Lang & Zheng (*Relative navigation architecture for aerospace
vehicles based on multimodal measurement*): the chaser's position and velocity relative to the
target, ``X = [x, y, z, ẋ, ẏ, ż]`` in the target's Hill frame (:mod:`filters.navigation.hill`), are
estimated by one Kalman filter (eqs. 1–5):

* **Propagation** with the accelerometer output as control input every IMU period
  (160 ms in the paper): ``X⁻ = Φ(Δt) X + Γ(Δt) u``, ``P⁻ = Φ P Φᵀ + σ_u² Γ Γᵀ``, with the
  exact Clohessy–Wiltshire ``Φ`` and zero-order-hold ``Γ`` and ``σ_u`` the accelerometer
  noise (m/s², per sample).
* **Updates** with relative-position fixes ``z = [x, y, z] + v`` from whichever sensors the
  *mode* selects — lidar (Tridar, σ = 0.05 m), its binocular-camera backup, relative GNSS —
  at their own rates; between fixes the filter only propagates. Covariances use the Joseph
  form.
* **Robustness** against gross optical errors by Huber M-estimation
  (:func:`filters.robust.huber_kalman_update`), or the plain update for comparison.

:class:`RelativeNavigationFilter` is the filter; the scenario of the paper (sensors, modes,
closed-loop approach and station keeping) is the study :mod:`lightcurve.studies.relnav`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from filters.gaussian import joseph_update, kalman_gain
from filters.navigation.hill import (
    cw_input_matrix,
    cw_transition,
)
from filters.robust import HUBER_THRESHOLD, huber_kalman_update

__all__ = [
    "RelativeNavigationFilter",
]


_H = np.hstack([np.eye(3), np.zeros((3, 3))])


class RelativeNavigationFilter:
    """Kalman filter on the relative position and velocity with IMU control input.

    Parameters
    ----------
    x : (6,) array_like
        Initial ``[x, y, z, ẋ, ẏ, ż]`` (m, m/s, Hill frame).
    covariance : (6, 6) array_like
        Initial covariance.
    mean_motion : float
        Mean motion of the target's circular orbit (rad/s).
    accelerometer_noise : float
        1σ noise of each accelerometer sample (m/s²); the process noise over a step is
        ``σ² Γ Γᵀ``.
    robust : {"huber", "none"}
        Measurement update: Huber M-estimation by IRLS, or the ordinary update.
    huber_threshold : float
        Huber constant in standard deviations.

    Examples
    --------
    >>> kf = RelativeNavigationFilter(x0, p0, n, 1e-3, robust="huber")
    >>> kf.predict(u, 0.16)                       # IMU specific force (m/s², Hill frame)
    >>> weights = kf.update(z, 0.05)              # lidar fix (m) with its sigma
    """

    def __init__(
        self,
        x: Any,
        covariance: Any,
        mean_motion: float,
        accelerometer_noise: float,
        robust: str = "huber",
        huber_threshold: float = HUBER_THRESHOLD,
    ) -> None:
        if robust not in ("huber", "none"):
            raise ValueError(f"robust must be 'huber' or 'none', got {robust!r}")
        self.x = np.array(x, dtype=float)
        self.P = np.array(covariance, dtype=float)
        self.mean_motion = float(mean_motion)
        self.accelerometer_noise = float(accelerometer_noise)
        self.robust = robust
        self.huber_threshold = float(huber_threshold)
        self._cache: dict[float, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}

    def _matrices(self, dt: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        key = round(dt, 12)
        if key not in self._cache:
            phi = cw_transition(self.mean_motion, dt)
            gam = cw_input_matrix(self.mean_motion, dt)
            self._cache[key] = (phi, gam, self.accelerometer_noise**2 * gam @ gam.T)
        return self._cache[key]

    def predict(self, u: Any, dt: float) -> None:
        """Propagate over ``dt`` seconds with the accelerometer output ``u`` held constant.

        Parameters
        ----------
        u : (3,) array_like
            Measured non-gravitational acceleration of the chaser (m/s², Hill frame).
        dt : float
            Step (s), ``≥ 0``.
        """
        if dt <= 0:
            return
        phi, gam, q = self._matrices(dt)
        self.x = phi @ self.x + gam @ np.asarray(u, dtype=float)
        self.P = phi @ self.P @ phi.T + q

    def update(self, z: Any, noise: Any) -> np.ndarray:
        """Update with a relative-position fix.

        Parameters
        ----------
        z : (3,) array_like
            Measured position (m, Hill frame).
        noise : float or (3, 3) array_like
            1σ noise of each component (m), or the fix's full covariance (m²) — relative
            GNSS solutions have correlated components.

        Returns
        -------
        (3,) numpy.ndarray
            Huber weights of the three whitened components (ones for the plain update).
        """
        r = np.asarray(noise, dtype=float)
        r = r**2 * np.eye(3) if r.ndim == 0 else r
        z = np.asarray(z, dtype=float)
        if self.robust == "huber":
            result = huber_kalman_update(self.x, self.P, z, _H, r, threshold=self.huber_threshold)
            self.x, self.P = result.x, result.P
            return result.weights
        gain, _ = kalman_gain(self.P, _H, r)
        self.x = self.x + gain @ (z - _H @ self.x)
        self.P = joseph_update(self.P, gain, _H, r)
        return np.ones(3)
