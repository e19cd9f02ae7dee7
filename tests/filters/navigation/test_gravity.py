"""Spherical-harmonic gravity: potential against an independent Legendre evaluation,
acceleration against the numerical gradient , point-mass limit."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.special import lpmv

from filters.navigation.gravity import (
    EROS_DEGREE2,
    EROS_MU,
    EROS_REFERENCE_RADIUS,
    SphericalHarmonicGravity,
    normalization_factor,
)

EROS = SphericalHarmonicGravity.from_coefficients(EROS_MU, EROS_REFERENCE_RADIUS, EROS_DEGREE2)


def random_field(degree: int, seed: int) -> SphericalHarmonicGravity:
    rng = np.random.default_rng(seed)
    c = rng.normal(0.0, 0.05, (degree + 1, degree + 1))
    s = rng.normal(0.0, 0.05, (degree + 1, degree + 1))
    c[0, 0] = 1.0
    return SphericalHarmonicGravity(EROS_MU, EROS_REFERENCE_RADIUS, c, s)


def outside_points(count: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    direction = rng.normal(size=(count, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    return direction * rng.uniform(1.05, 3.0, (count, 1)) * EROS_REFERENCE_RADIUS


def legendre_potential(field: SphericalHarmonicGravity, r: np.ndarray) -> float:
    """Li et al. 2024, eq. 3 evaluated term by term with scipy's associated Legendre functions."""
    x, y, z = r
    rn = math.sqrt(x * x + y * y + z * z)
    lat, lon = math.asin(z / rn), math.atan2(y, x)
    total = 0.0
    for n in range(field.degree + 1):
        for m in range(n + 1):
            # scipy includes the Condon-Shortley phase (-1)^m; geodesy does not.
            p_nm = (-1) ** m * lpmv(m, n, math.sin(lat)) * normalization_factor(n, m)
            trig = field.c[n, m] * math.cos(m * lon) + field.s[n, m] * math.sin(m * lon)
            total += (field.radius / rn) ** (n + 1) * p_nm * trig
    return field.mu / field.radius * total


def numerical_gradient(field: SphericalHarmonicGravity, r: np.ndarray) -> np.ndarray:
    """Five-point central differences of the potential (O(h⁴))."""
    h = 1e-3 * np.linalg.norm(r)
    grad = np.empty(3)
    for j in range(3):
        e = np.zeros(3)
        e[j] = h
        v = [field.potential(r + k * e) for k in (-2, -1, 1, 2)]
        grad[j] = (v[0] - 8 * v[1] + 8 * v[2] - v[3]) / (12 * h)
    return grad


@pytest.mark.parametrize("field", [EROS, random_field(8, 3)], ids=["eros-degree2", "degree8"])
def test_acceleration_is_numerical_gradient_of_potential(field):
    for r in outside_points(12, seed=1):
        acc = field.acceleration(r)
        np.testing.assert_allclose(
            acc, numerical_gradient(field, r), rtol=0, atol=1e-8 * np.linalg.norm(acc)
        )


@pytest.mark.parametrize("field", [EROS, random_field(6, 5)], ids=["eros-degree2", "degree6"])
def test_potential_matches_term_by_term_legendre_sum(field):
    points = outside_points(10, seed=2)
    expected = np.array([legendre_potential(field, r) for r in points])
    np.testing.assert_allclose(field.potential(points), expected, rtol=1e-12)


def test_degree_zero_is_the_point_mass():
    # The recursion (complex products, divisions) and the closed form round differently:
    # they agree to 3 ulps here, and vectorised complex arithmetic (FMA or not) moves that.
    points = outside_points(50, seed=3)
    rn = np.linalg.norm(points, axis=1, keepdims=True)
    for field in (EROS.truncated(0), SphericalHarmonicGravity.point_mass(EROS_MU, 1600.0)):
        np.testing.assert_allclose(
            field.acceleration(points), -EROS_MU * points / rn**3, rtol=1e-13
        )
        np.testing.assert_allclose(field.potential(points), EROS_MU / rn[:, 0], rtol=1e-13)


def test_torch_autograd_of_potential_equals_numpy_acceleration():
    field = random_field(5, 7)
    points = outside_points(8, seed=4)
    tensor = torch.tensor(points, requires_grad=True)
    field.potential(tensor).sum().backward()
    acc = field.acceleration(points)
    np.testing.assert_allclose(tensor.grad.numpy(), acc, rtol=0, atol=1e-13 * np.abs(acc).max())


def test_gradient_is_symmetric_and_traceless_outside_the_body():
    for r in outside_points(5, seed=6):
        g = EROS.gradient(r)
        scale = np.abs(g).max()
        np.testing.assert_allclose(g, g.T, atol=1e-7 * scale)
        assert abs(np.trace(g)) < 1e-7 * scale  # Laplace's equation


@settings(max_examples=40, deadline=None)
@given(
    st.floats(0.0, 2 * math.pi),
    st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3),
)
def test_zonal_field_commutes_with_rotation_about_the_spin_axis(angle, direction):
    v = np.array(direction)
    if np.linalg.norm(v) < 1e-3:
        v = np.array([1.0, 0.0, 0.0])
    r = 1.5 * EROS_REFERENCE_RADIUS * v / np.linalg.norm(v)
    zonal = SphericalHarmonicGravity.from_coefficients(
        EROS_MU, EROS_REFERENCE_RADIUS, [(2, 0, -0.05, 0.0), (3, 0, 0.01, 0.0), (4, 0, 0.02, 0.0)]
    )
    c, s = math.cos(angle), math.sin(angle)
    rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(
        zonal.acceleration(rz @ r), rz @ zonal.acceleration(r), rtol=1e-12, atol=1e-18
    )


def test_eros_degree2_flattening_weakens_polar_gravity():
    # C̄20 < 0 (J2 > 0): on the spin axis |U| = μ/r² (1 − 3 J2 a²/r²) < μ/r².
    pole = np.array([0.0, 0.0, 2 * EROS_REFERENCE_RADIUS])
    point_mass = EROS_MU / np.linalg.norm(pole) ** 2
    assert np.linalg.norm(EROS.acceleration(pole)) < point_mass


def test_bad_coefficients_are_rejected_with_the_row():
    with pytest.raises(ValueError, match="row 1"):
        SphericalHarmonicGravity.from_coefficients(
            EROS_MU, 1.0, [(2, 0, 0.1, 0.0), (1, 2, 0.0, 0.0)]
        )
    with pytest.raises(ValueError, match="mu"):
        SphericalHarmonicGravity.point_mass(-1.0)
    with pytest.raises(ValueError, match="degree"):
        EROS.truncated(3)
