"""The renderer against closed forms, the numpy reference, ray casting and itself."""

import numpy as np
import pytest
import torch

from filters.attitude import random_quaternion
from lightcurve.photometry.reference import reference_flux
from lightcurve.photometry.render import Renderer, flux_to_magnitude, lambert_sphere_flux
from shapes import Material, get_library, primitives
from tests.lightcurve._geometry import AU, random_geometry


def test_lambert_sphere_phase_curve():
    """A Lambertian icosphere (20480 facets) matches the analytic phase curve within 0.2 %."""
    sphere = primitives.icosphere(2.0, subdivisions=5)
    sphere = sphere.with_materials(
        {g: Material("lambert", {"rd": 0.4}) for g in sphere.group_names}
    )
    assert len(sphere.areas) >= 5000
    alpha = np.deg2rad(np.arange(0.0, 151.0, 5.0))
    sun = np.array([AU, 0.0, 0.0])
    obs = 3.6e7 * np.stack([np.cos(alpha), np.sin(alpha), np.zeros_like(alpha)], axis=1)
    flux = Renderer(sphere).flux(random_quaternion(rng=3), sun, obs)
    expected = lambert_sphere_flux(0.4, 2.0, 3.6e7, alpha)
    assert np.max(np.abs(flux / expected - 1)) < 2e-3


@pytest.mark.parametrize("name", ["box", "cylinder", "rocket_body", "plate", "cube"])
def test_convex_shapes_agree_with_reference_and_ray_casting(name):
    shape = get_library().load(name)
    q, sun, obs = random_geometry(300, seed=4)
    fast = Renderer(shape).flux(q, sun, obs)
    np.testing.assert_allclose(fast, reference_flux(shape, q, sun, obs), rtol=1e-10, atol=0)
    exact = Renderer(shape, shadows="exact").flux(q[:100], sun[:100], obs[:100])
    np.testing.assert_allclose(exact, fast[:100], rtol=1e-9, atol=1e-30)


@pytest.mark.parametrize(("name", "rms_limit"), [("box_wing", 0.02), ("itokawa", 0.02)])
def test_visibility_table_close_to_exact(name, rms_limit):
    shape = get_library().load(name)
    q, sun, obs = random_geometry(400, seed=5)
    table = flux_to_magnitude(Renderer(shape, shadows="table").flux(q, sun, obs))
    exact = flux_to_magnitude(Renderer(shape, shadows="exact").flux(q, sun, obs))
    assert np.array_equal(np.isfinite(table), np.isfinite(exact))
    ok = np.isfinite(table)
    assert np.sqrt(np.mean((table[ok] - exact[ok]) ** 2)) < rms_limit


def test_torch_and_numpy_inputs_and_batching():
    shape = get_library().load("box_wing")
    renderer = Renderer(shape)
    q, sun, obs = random_geometry(64, seed=6)
    out_np = renderer.flux(q, sun, obs)
    out_t = renderer.flux(torch.tensor(q), torch.tensor(sun), torch.tensor(obs))
    assert isinstance(out_t, torch.Tensor)
    np.testing.assert_allclose(out_t.numpy(), out_np, rtol=1e-12)
    # particles × epochs broadcasting: (P, E, 4) attitudes against (E, 3) geometry.
    particles = np.stack([q, q[::-1]])
    grid = renderer.flux(particles, sun, obs)
    assert grid.shape == (2, 64)
    np.testing.assert_allclose(grid[0], out_np, rtol=1e-12)
    singles = np.array([renderer.flux(q[i], sun[i], obs[i]) for i in range(0, 64, 8)])
    np.testing.assert_allclose(singles, out_np[::8], rtol=1e-12)
    per_facet = renderer.facet_flux(q, sun, obs)
    assert per_facet.shape == (64, len(shape.compiled()))
    np.testing.assert_allclose(per_facet.sum(axis=-1), out_np, rtol=1e-12)


def test_dark_epochs_give_infinite_magnitude():
    plate = get_library().load("plate")
    renderer = Renderer(plate)
    normal = plate.compiled().normals[0]
    sun = AU * normal
    obs = -4e7 * normal  # observer behind a two-sided plate's lit side: sees the dark side
    magnitude = renderer.magnitude(np.array([0.0, 0.0, 0.0, 1.0]), sun, obs)
    assert magnitude == np.inf
    assert renderer.magnitude(np.array([0.0, 0.0, 0.0, 1.0]), sun, 4e7 * normal) < 30


def test_float32_close_to_float64():
    shape = get_library().load("box_wing")
    q, sun, obs = random_geometry(200, seed=7)
    m64 = Renderer(shape, dtype=torch.float64).magnitude(q, sun, obs)
    m32 = Renderer(shape, dtype=torch.float32).magnitude(q, sun, obs)
    ok = np.isfinite(m64)
    assert np.max(np.abs(m32[ok] - m64[ok])) < 1e-3


def test_bad_shadow_mode():
    with pytest.raises(ValueError, match="shadows must be one of"):
        Renderer(get_library().load("box"), shadows="raytrace")
