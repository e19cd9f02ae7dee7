"""Lambert: hand-computed values, masking, albedo = rd."""

import math

import numpy as np
import pytest

import brdf

N = np.array([0.0, 0.0, 1.0])


def test_hand_computed_values(direction):
    rd = 0.7
    # Any visible geometry: ρ = rd/π = 0.7/3.14159265 = 0.2228169.
    geometries = [
        (direction(0, 0), direction(0, 0)),  # normal incidence, backscatter
        (direction(60, 0), direction(30, 180)),  # oblique, forward
        (direction(89, 10), direction(45, 250)),  # grazing Sun
    ]
    for light, view in geometries:
        assert brdf.lambert(N, light, view, rd) == pytest.approx(0.2228169, abs=1e-7)
    assert 0.7 / math.pi == pytest.approx(0.2228169, abs=1e-7)


def test_zero_below_horizon(direction):
    assert brdf.lambert(N, direction(100, 0), direction(0, 0), 0.7) == 0.0
    assert brdf.lambert(N, direction(0, 0), direction(90.0001, 0), 0.7) == 0.0


def test_albedo_equals_rd():
    angles = np.radians(np.arange(0.0, 86.0, 5.0))
    for rd in (0.05, 0.37, 1.0):
        values = brdf.albedo(brdf.get("lambert", rd=rd), angles, n=8, levels=6)
        np.testing.assert_allclose(values, rd, atol=1e-6, rtol=0)
