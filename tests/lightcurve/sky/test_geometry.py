"""Geometry helpers."""

import numpy as np
import pytest
import torch

from filters.attitude import (
    attitude_angle,
    attitude_matrix,
    axis_angle_to_quaternion,
    propagate_torque_free,
    random_quaternion,
)
from lightcurve.photometry.render import Renderer
from lightcurve.sky.geometry import (
    AU_M,
    body_directions,
    phase_angle,
    phase_angle_bisector,
    reciprocity_twin,
    solar_flux_scale,
)
from shapes import get_library


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


def test_reciprocity_twin_swaps_sun_and_observer():
    rng = np.random.default_rng(3)
    q = random_quaternion((50,), rng)
    sun, obs = rng.standard_normal(3) * 1.5e11, rng.standard_normal(3) * 4e7
    twin = reciprocity_twin(q, sun, obs)
    light, view = body_directions(q, sun, obs)
    light_twin, view_twin = body_directions(twin, sun, obs)
    np.testing.assert_allclose(light_twin, view, atol=1e-14)
    np.testing.assert_allclose(view_twin, light, atol=1e-14)
    # A half-turn: applying it twice returns the attitude (up to the quaternion's sign).
    np.testing.assert_allclose(
        attitude_matrix(reciprocity_twin(twin, sun, obs)), attitude_matrix(q), atol=1e-14
    )
    torch_twin = reciprocity_twin(torch.tensor(q), torch.tensor(sun), torch.tensor(obs))
    np.testing.assert_allclose(torch_twin.numpy(), twin, atol=1e-15)


@pytest.mark.parametrize(
    ("name", "shadows"),
    [("box_wing", "exact"), ("itokawa", "exact"), ("itokawa", "table"), ("rocket_body", "none")],
)
def test_reciprocity_twin_renders_the_same_brightness(name, shadows):
    """Reciprocal BRDFs and symmetric shadowing: the twin's flux is the same, for
    non-convex shapes with shadows and for anisotropic Ashikhmin–Shirley materials."""
    rng = np.random.default_rng(4)
    renderer = Renderer(get_library().load(name), shadows=shadows)
    q = random_quaternion((200,), rng)
    sun, obs = np.array([1.5e11, 0.0, 0.0]), np.array([2.0e7, 3.0e7, -1.0e7])
    flux = renderer.flux(q, sun, obs)
    twin_flux = renderer.flux(reciprocity_twin(q, sun, obs), sun, obs)
    assert np.count_nonzero(flux > 0) > 100
    np.testing.assert_allclose(twin_flux, flux, rtol=1e-10, atol=1e-14 * flux.max())
    # ... from an attitude half a turn away
    np.testing.assert_allclose(attitude_angle(q, reciprocity_twin(q, sun, obs)), np.pi)


def test_reciprocity_twin_keeps_the_body_rates():
    """The half-turn is fixed in inertial space: the twin follows the same torque-free
    body rates, so at fixed geometry the whole light curve is the same."""
    rng = np.random.default_rng(5)
    q0, omega0 = random_quaternion((), rng), np.radians([2.0, -1.0, 3.0])
    sun, obs = np.array([1.5e11, 0.0, 0.0]), np.array([2.0e7, 3.0e7, -1.0e7])
    inertia = np.diag([1.0, 2.0, 2.6])
    q, omega = propagate_torque_free(q0, omega0, inertia, 100.0, max_step=0.5)
    q_twin, omega_twin = propagate_torque_free(
        reciprocity_twin(q0, sun, obs), omega0, inertia, 100.0, max_step=0.5
    )
    np.testing.assert_allclose(omega_twin, omega, atol=1e-15)
    np.testing.assert_allclose(
        attitude_matrix(q_twin), attitude_matrix(reciprocity_twin(q, sun, obs)), atol=1e-12
    )
