"""Feature tracks of a tumbling target seen by a fixed pinhole camera.

Body-fixed feature points (e.g. the vertices of a library shape) are rotated with the
target's attitude, placed at the target's position in the camera frame and projected into
pixels with noise (Deng et al. 2024, eqs. 1–7). A point is tracked in a frame when it is in front of
the camera and inside the image, faces the camera (back-facing points are culled: exact
self-occlusion for a convex body) and, when an occlusion test is given, no part of the body
lies between it and the camera (non-convex bodies).

Frames: the camera frame is the inertial reference (x right, y down, z along the optical
axis); the attitude ``q`` maps it into the body frame, ``v_B = A(q) v_C``, so a body point
``p`` sits at ``P_C = A(q)ᵀ p + T`` with ``T`` the target centre in the camera frame.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from filters.attitude import attitude_matrix
from filters.navigation.camera import PinholeCamera

__all__ = ["FeatureTracks", "camera_points", "simulate_tracks"]

Occlusion = Callable[[np.ndarray, np.ndarray], np.ndarray]


@dataclass
class FeatureTracks:
    """Pixel tracks of feature points over a sequence of frames.

    Attributes
    ----------
    times : (K,) numpy.ndarray
        Frame times (s).
    pixels : (K, N, 2) numpy.ndarray
        Measured pixel coordinates ``(u, v)``; NaN where the point is not tracked.
    visible : (K, N) numpy.ndarray of bool
        Whether point ``n`` is tracked in frame ``k``.
    outlier : (K, N) numpy.ndarray of bool
        Mismatched measurements injected on purpose (for robustness studies).
    """

    times: np.ndarray
    pixels: np.ndarray
    visible: np.ndarray
    outlier: np.ndarray

    def __len__(self) -> int:
        return self.times.size

    def matches(self, first: int, second: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Points tracked in both frames.

        Parameters
        ----------
        first, second : int
            Frame indices.

        Returns
        -------
        index : (M,) numpy.ndarray of int
            Point indices.
        uv1, uv2 : (M, 2) numpy.ndarray
            Their pixels in the two frames.
        """
        index = np.flatnonzero(self.visible[first] & self.visible[second])
        return index, self.pixels[first, index], self.pixels[second, index]


def camera_points(points: np.ndarray, attitudes: np.ndarray, position: np.ndarray) -> np.ndarray:
    """Camera-frame positions ``A(q)ᵀ p + T`` of body points over a sequence of attitudes.

    Parameters
    ----------
    points : (N, 3) array_like
        Body-frame points (m).
    attitudes : (K, 4) array_like
        Camera → body quaternions.
    position : (3,) array_like
        Target centre in the camera frame (m).

    Returns
    -------
    (K, N, 3) numpy.ndarray
    """
    a = np.asarray(attitude_matrix(np.asarray(attitudes, dtype=float)))
    p = np.asarray(points, dtype=float)
    return np.einsum("kji,nj->kni", a, p) + np.asarray(position, dtype=float)


def simulate_tracks(
    points: np.ndarray,
    normals: np.ndarray,
    attitudes: np.ndarray,
    times: np.ndarray,
    camera: PinholeCamera,
    *,
    position: np.ndarray,
    pixel_sigma: float,
    rng: np.random.Generator,
    occluded: Occlusion | None = None,
    outlier_fraction: float = 0.0,
    margin: float = 0.0,
) -> FeatureTracks:
    """Simulate noisy pixel tracks of body-fixed points.

    Parameters
    ----------
    points : (N, 3) array_like
        Feature points in the body frame (m).
    normals : (N, 3) array_like
        Outward surface normals at the points (body frame) for back-face culling.
    attitudes : (K, 4) array_like
        Camera → body quaternions at the frame times.
    times : (K,) array_like
        Frame times (s).
    camera : PinholeCamera
    position : (3,) array_like
        Target centre in the camera frame (m), e.g. ``[0, 0, range]``.
    pixel_sigma : float
        One-sigma pixel noise per coordinate.
    rng : numpy.random.Generator
    occluded : callable, optional
        ``(origins (M, 3), directions (M, 3)) → (M,) bool`` in the body frame: whether a ray
        from a point toward the camera hits the body (e.g. ``shapes.visibility.raycast.Occluder``).
    outlier_fraction : float
        Fraction of tracked measurements replaced by uniformly random pixels (mismatches).
    margin : float
        Pixels kept free at the image border.

    Returns
    -------
    FeatureTracks
    """
    if pixel_sigma < 0 or not 0 <= outlier_fraction < 1:
        raise ValueError("pixel_sigma must be >= 0 and outlier_fraction in [0, 1)")
    q = np.asarray(attitudes, dtype=float)
    p_c = camera_points(points, q, position)
    a = np.asarray(attitude_matrix(q))
    n_c = np.einsum("kji,nj->kni", a, np.asarray(normals, dtype=float))
    # Facing the camera: the normal points toward the camera centre (the origin).
    visible = np.asarray(camera.in_view(p_c, margin)) & (np.sum(n_c * p_c, axis=-1) < 0)
    if occluded is not None and np.any(visible):
        k, n = np.nonzero(visible)
        # Ray from the point (nudged off the surface) toward the camera, in the body frame.
        camera_body = np.einsum("kij,j->ki", a, -np.asarray(position, dtype=float))[k]
        p_b = np.asarray(points, dtype=float)[n]
        direction = camera_body - p_b
        direction /= np.linalg.norm(direction, axis=-1, keepdims=True)
        size = float(np.ptp(np.asarray(points, dtype=float), axis=0).max())
        blocked = np.asarray(occluded(p_b + 1e-6 * size * direction, direction), dtype=bool)
        visible[k[blocked], n[blocked]] = False
    uv = np.asarray(camera.project(p_c)) + pixel_sigma * rng.standard_normal((*p_c.shape[:-1], 2))
    outlier = visible & (rng.random(visible.shape) < outlier_fraction)
    count = int(outlier.sum())
    uv[outlier] = rng.random((count, 2)) * [camera.width, camera.height]
    uv[~visible] = np.nan
    return FeatureTracks(np.asarray(times, dtype=float), uv, visible, outlier)
