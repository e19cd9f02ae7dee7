"""Geometry helpers."""

import numpy as np
import pytest
import torch

from filters.attitude import axis_angle_to_quaternion
from lightcurve.geometry import (
    AU_M,
    body_directions,
    phase_angle,
    phase_angle_bisector,
    solar_flux_scale,
)


def test_phase_angle_and_bisector():
    sun = np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0]]) * 1.5e11
    obs = np.array([[0.0, 2.0, 0.0], [1.0, 1e-9, 0.0], [-1.0, 1e-12, 0.0]]) * 4e7
    np.testing.assert_allclose(phase_angle(sun, obs), [np.pi / 2, 1e-9, np.pi], rtol=1e-6)
    h = phase_angle_bisector(sun[0], obs[0])
    np.testing.assert_allclose(h, [np.sqrt(0.5), np.sqrt(0.5), 0.0])
    assert isinstance(phase_angle(torch.tensor(sun), torch.tensor(obs)), torch.Tensor)


def test_body_directions_and_flux_scale():
    q = axis_angle_to_quaternion([0.0, 0.0, 1.0], np.pi / 2)
    light, view = body_directions(q, [2.0, 0.0, 0.0], [0.0, 0.0, 3.0])
    np.testing.assert_allclose(light, [0.0, -1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(view, [0.0, 0.0, 1.0], atol=1e-15)
    assert solar_flux_scale(2 * AU_M) == pytest.approx(0.25)
