"""Pinhole camera model shared by the monocular, planning and stereo estimators.

Frames: points are given in the camera frame (x right, y down, z along the optical axis,
metres). Pixel coordinates ``(u, v)`` have their origin at the top-left image corner.
The intrinsic matrix is ``K = [[fx, 0, u0], [0, fy, v0], [0, 0, 1]]`` (Deng et al. 2024, eq. 1;
Li et al. 2024, eq. 12 with ``fx = fy = f`` and the principal point at the origin).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from filters.attitude.arrays import as_arrays

__all__ = ["PinholeCamera"]


@dataclass(frozen=True)
class PinholeCamera:
    """Ideal pinhole camera.

    Parameters
    ----------
    fx, fy : float
        Focal lengths in pixels.
    u0, v0 : float
        Principal point in pixels.
    width, height : int
        Image size in pixels (for field-of-view culling).
    """

    fx: float
    fy: float
    u0: float
    v0: float
    width: int
    height: int

    def __post_init__(self) -> None:
        for name in ("fx", "fy"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"camera {name} must be a positive focal length in pixels")
        if self.width <= 0 or self.height <= 0:
            raise ValueError("camera width and height must be positive pixel counts")

    @classmethod
    def from_fov(cls, fov_deg: float, width: int, height: int | None = None) -> PinholeCamera:
        """Square-pixel camera with horizontal field of view ``fov_deg`` (degrees).

        Parameters
        ----------
        fov_deg : float
            Full horizontal field of view in degrees (0 < fov < 180).
        width, height : int
            Image size in pixels (``height`` defaults to ``width``).
        """
        if not 0 < fov_deg < 180:
            raise ValueError(f"field of view must be in (0, 180) degrees, got {fov_deg}")
        height = width if height is None else height
        f = 0.5 * width / math.tan(math.radians(fov_deg) / 2)
        return cls(f, f, 0.5 * width, 0.5 * height, width, height)

    @property
    def intrinsic_matrix(self) -> np.ndarray:
        """The 3×3 intrinsic matrix ``K``."""
        return np.array([[self.fx, 0.0, self.u0], [0.0, self.fy, self.v0], [0.0, 0.0, 1.0]])

    def project(self, points: Any) -> Any:
        """Pixel coordinates of camera-frame points.

        Parameters
        ----------
        points : (..., 3) array
            Points in the camera frame (m), ``z > 0`` in front of the camera.

        Returns
        -------
        (..., 2) array
            ``[fx x/z + u0, fy y/z + v0]`` in pixels.
        """
        xp, (p,) = as_arrays(points)
        z = p[..., 2]
        return xp.stack([self.fx * p[..., 0] / z + self.u0, self.fy * p[..., 1] / z + self.v0], -1)

    def projection_jacobian(self, points: Any) -> Any:
        """Jacobian ``∂(u, v)/∂(x, y, z)`` of :meth:`project`.

        Parameters
        ----------
        points : (..., 3) array
            Camera-frame points (m).

        Returns
        -------
        (..., 2, 3) array
            Pixels per metre.
        """
        xp, (p,) = as_arrays(points)
        x, y, z = p[..., 0], p[..., 1], p[..., 2]
        zero = xp.zeros_like(z)
        row_u = xp.stack([self.fx / z, zero, -self.fx * x / (z * z)], axis=-1)
        row_v = xp.stack([zero, self.fy / z, -self.fy * y / (z * z)], axis=-1)
        return xp.stack([row_u, row_v], axis=-2)

    def in_view(self, points: Any, margin: float = 0.0) -> Any:
        """Whether points are in front of the camera and inside the image.

        Parameters
        ----------
        points : (..., 3) array
            Camera-frame points (m).
        margin : float
            Pixels to keep away from the image border.

        Returns
        -------
        (...) bool array
        """
        xp, (p,) = as_arrays(points)
        front = p[..., 2] > 0
        z = xp.where(front, p[..., 2], xp.ones_like(p[..., 2]))
        uv = self.project(xp.stack([p[..., 0], p[..., 1], z], axis=-1))
        inside = (
            (uv[..., 0] >= margin)
            & (uv[..., 0] <= self.width - margin)
            & (uv[..., 1] >= margin)
            & (uv[..., 1] <= self.height - margin)
        )
        return front & inside

    def normalized(self, pixels: Any) -> Any:
        """Normalised image coordinates ``[(u − u0)/fx, (v − v0)/fy]`` (= ``[x/z, y/z]``).

        Parameters
        ----------
        pixels : (..., 2) array

        Returns
        -------
        (..., 2) array
        """
        xp, (uv,) = as_arrays(pixels)
        return xp.stack([(uv[..., 0] - self.u0) / self.fx, (uv[..., 1] - self.v0) / self.fy], -1)

    def bearing(self, pixels: Any) -> Any:
        """Unit line-of-sight vectors (camera frame) through pixels.

        Parameters
        ----------
        pixels : (..., 2) array

        Returns
        -------
        (..., 3) array
        """
        xp, (uv,) = as_arrays(pixels)
        n = self.normalized(uv)
        rays = xp.concat([n, xp.ones_like(n[..., :1])], axis=-1)
        return rays / xp.linalg.vector_norm(rays, axis=-1, keepdims=True)
