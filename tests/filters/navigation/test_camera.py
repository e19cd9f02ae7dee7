"""Pinhole camera."""

import numpy as np
import pytest
import torch
from torch.autograd.functional import jacobian

from filters.navigation.camera import PinholeCamera


def test_fov_and_projection():
    cam = PinholeCamera.from_fov(69.0, 1024)
    edge = np.array([np.tan(np.radians(34.5)), 0.0, 1.0])
    np.testing.assert_allclose(cam.project(edge), [1024.0, 512.0])
    assert cam.in_view(np.array([[0, 0, 5.0], [0, 0, -5.0], [10, 0, 1.0]])).tolist() == [
        True,
        False,
        False,
    ]
    pixels = cam.project(np.array([0.2, -0.1, 2.0]))
    np.testing.assert_allclose(
        cam.bearing(pixels), np.array([0.2, -0.1, 2.0]) / np.linalg.norm([0.2, -0.1, 2.0])
    )


def test_projection_jacobian_matches_autograd():
    cam = PinholeCamera(800.0, 810.0, 320.0, 240.0, 640, 480)
    p = np.array([0.3, -0.2, 4.0])
    auto = jacobian(cam.project, torch.tensor(p))
    np.testing.assert_allclose(cam.projection_jacobian(p), auto.numpy(), atol=1e-12)


def test_bad_camera_is_rejected():
    with pytest.raises(ValueError, match="fx"):
        PinholeCamera(0.0, 1.0, 0.0, 0.0, 10, 10)
    with pytest.raises(ValueError, match="field of view"):
        PinholeCamera.from_fov(190.0, 100)
