"""Phong: hand-computed values and the Lambert limit."""

import math

import numpy as np
import pytest

import brdf

N = np.array([0.0, 0.0, 1.0])
RD, RS, EXPONENT = 0.4, 0.5, 20.0


def test_hand_computed_values(direction):
    lobe = RS * (EXPONENT + 2) / (2 * math.pi)  # 0.5·22/(2π) = 1.7507044
    # 1. L = V = n: R = n, R·V = 1 → ρ = 0.4/π + 1.7507044 = 0.1273240 + 1.7507044 = 1.8780284.
    value = brdf.phong(N, direction(0, 0), direction(0, 0), RD, RS, EXPONENT)
    assert value == pytest.approx(0.4 / math.pi + lobe, rel=1e-12)
    assert value == pytest.approx(1.8780284, rel=1e-7)
    # 2. L at 60°, V at 30° opposite azimuth: NL = 0.5, NV = cos 30°, L·V = 0,
    #    R·V = 2·0.5·cos 30° − 0 = cos 30°, (cos 30°)^20 = (3/4)^10 = 0.0563135
    #    → ρ = 0.1273240 + 1.7507044·0.0563135 = 0.1273240 + 0.0985883 = 0.2259123.
    value = brdf.phong(N, direction(60, 0), direction(30, 180), RD, RS, EXPONENT)
    assert value == pytest.approx(0.4 / math.pi + lobe * 0.75**10, rel=1e-12)
    assert value == pytest.approx(0.2259123, rel=1e-6)
    # 3. L and V at 45°, azimuths 90° apart: L·V = 0.5, R·V = 2·0.5 − 0.5 = 0.5,
    #    0.5^20 = 9.5367e-7 → ρ = 0.1273240 + 1.7507044·9.5367e-7 = 0.1273256.
    value = brdf.phong(N, direction(45, 0), direction(45, 90), RD, RS, EXPONENT)
    assert value == pytest.approx(0.4 / math.pi + lobe * 0.5**20, rel=1e-12)
    assert value == pytest.approx(0.1273256, rel=1e-6)


def test_no_lobe_behind_the_mirror_direction(direction):
    # R·V < 0 (V on the Sun's side, far from the mirror direction): only the diffuse term.
    light, view = direction(80, 0), direction(80, 0)  # R·V = 2 cos²80° − 1 < 0
    assert brdf.phong(N, light, view, RD, RS, EXPONENT) == pytest.approx(RD / math.pi)


def test_rs_zero_is_lambert(random_geometry):
    normal, light, view, _ = random_geometry(np.random.default_rng(1), 2000)
    for exponent in (0.0, 1.0, 75.0):
        np.testing.assert_array_equal(
            brdf.phong(normal, light, view, 0.6, 0.0, exponent),
            brdf.lambert(normal, light, view, 0.6),
        )
