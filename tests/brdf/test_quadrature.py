"""Physical checks: non-negativity, Helmholtz reciprocity and directional albedo ≤ 1."""

import math

import numpy as np
import pytest

import brdf

ANGLES = np.radians([0.0, 20.0, 40.0, 60.0, 75.0, 85.0])


def _all_models(parameter_sets):
    return [(name, params) for name, sets in parameter_sets.items() for params in sets]


def test_reciprocity_on_random_geometries(parameter_sets):
    for name, params in _all_models(parameter_sets):
        model = brdf.get(name, **params)
        assert brdf.reciprocity_error(model, n_samples=10_000, seed=3) <= 1e-12, (name, params)


def test_reciprocity_check_detects_a_non_reciprocal_model():
    class Skewed:
        """ρ = NL/π: not symmetric in L and V."""

        def __call__(self, normal, light, view, tangent=None):
            return np.clip(np.sum(normal * light, -1), 0, None) / math.pi

    assert brdf.reciprocity_error(Skewed(), n_samples=1000, seed=0) > 0.5


def test_non_negative_and_zero_below_the_horizon(parameter_sets, random_geometry):
    normal, light, view, tangent = random_geometry(np.random.default_rng(4), 10_000)
    hidden = (np.sum(normal * light, -1) <= 0) | (np.sum(normal * view, -1) <= 0)
    for name, params in _all_models(parameter_sets):
        rho = brdf.get(name, **params)(normal, light, view, tangent=tangent)
        assert np.all(np.isfinite(rho)) and np.all(rho >= 0), name
        assert np.all(rho[hidden] == 0), name
        if params.get("rd", 1.0) > 0:  # a diffuse part (or f(α) > 0 for α < 90°)
            assert np.all(rho[~hidden & (np.sum(light * view, -1) > 0)] > 0), name


ENERGY_CONSERVING = [
    ("phong", {"rd": 0.0, "rs": 1.0, "n": 0.0}),
    ("phong", {"rd": 0.8, "rs": 0.2, "n": 1.0}),
    ("phong", {"rd": 0.0, "rs": 1.0, "n": 10.0}),
    ("phong", {"rd": 0.5, "rs": 0.5, "n": 1e3}),
    ("phong", {"rd": 0.0, "rs": 1.0, "n": 1e5}),
    ("cook-torrance", {"rd": 0.0, "rs": 1.0, "m": 0.01, "f0": 1.0}),
    ("cook-torrance", {"rd": 0.0, "rs": 1.0, "m": 0.1, "f0": 1.0}),
    ("cook-torrance", {"rd": 0.3, "rs": 0.7, "m": 0.5, "f0": 1.0}),
    ("cook-torrance", {"rd": 0.0, "rs": 1.0, "m": 1.0, "f0": 0.04}),
    ("ashikhmin-shirley", {"rd": 1.0, "rs": 0.0, "nu": 1.0, "nv": 1.0}),
    ("ashikhmin-shirley", {"rd": 1.0, "rs": 0.5, "nu": 100.0, "nv": 100.0}),
    ("ashikhmin-shirley", {"rd": 1.0, "rs": 1.0, "nu": 1e4, "nv": 1e4}),
    ("ashikhmin-shirley", {"rd": 1.0, "rs": 0.05, "nu": 10.0, "nv": 1000.0}),
    ("two-lobe", {"rd": 0.0, "rb": 1.0, "ab": 0.01, "fb": 1.0, "rn": 0.0}),
    ("two-lobe", {"rd": 0.0, "rb": 1.0, "ab": 3.0, "fb": 1.0, "rn": 0.0}),
    ("two-lobe", {"rd": 0.0, "rb": 0.0, "rn": 1.0, "mn": 0.002, "fn": 1.0}),
    ("two-lobe", {"rd": 0.2, "rb": 0.4, "ab": 0.3, "fb": 1.0, "rn": 0.4, "mn": 0.02, "fn": 1.0}),
]


@pytest.mark.parametrize(("name", "params"), ENERGY_CONSERVING)
def test_directional_albedo_at_most_one(name, params):
    model = brdf.get(name, **params)
    for azimuth in (0.0, 0.8) if model.anisotropic else (0.0,):
        values = brdf.albedo(model, ANGLES, n=10, levels=12, azimuth=azimuth)
        assert np.all(values > 0)
        assert values.max() <= 1.0 + 1e-6, values


def test_albedo_of_sharp_lobes_against_closed_forms():
    # Phong at normal incidence: R = n and (n+2)/(2π) ∫ cosⁿθ cosθ dω = 1, so the albedo is
    # rd + rs for every exponent; a lobe of exponent 10⁶ is 0.06° wide.
    for exponent in (0.0, 30.0, 1e6):
        model = brdf.get("phong", rd=0.2, rs=0.7, n=exponent)
        assert brdf.albedo(model, [0.0])[0] == pytest.approx(0.9, abs=1e-9)
    # Cook–Torrance, f0 = 1, narrow lobe at normal incidence: G = 1 where D matters and
    # ∫ D NH dω_H = 1, so the albedo is rd + rs.
    model = brdf.get("cook-torrance", rd=0.1, rs=0.9, m=0.01, f0=1.0)
    assert brdf.albedo(model, [0.0])[0] == pytest.approx(1.0, abs=1e-9)


def test_quadrature_converges():
    model = brdf.get("ashikhmin-shirley", rd=0.5, rs=0.3, nu=200.0, nv=200.0)
    coarse = brdf.albedo(model, ANGLES, n=8, levels=10)
    fine = brdf.albedo(model, ANGLES, n=16, levels=14)
    np.testing.assert_allclose(coarse, fine, atol=1e-6)
