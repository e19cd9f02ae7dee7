"""Two-lobe model: hand-computed values, its one-lobe and Lambert limits, the energy bound."""

import numpy as np
import pytest

import brdf

N = np.array([0.0, 0.0, 1.0])
PARAMS = {"rd": 0.1, "rb": 0.3, "ab": 0.2, "fb": 0.9, "rn": 0.5, "mn": 0.01, "fn": 0.04}


def test_hand_computed_values(direction):
    p = PARAMS
    # 1. L = V = n: NH = VH = 1, D_TR = 1/(π ab²), D_B = 1/(π mn²), G = 1, F = f per lobe:
    #    ρ = 0.1/π + (0.3·0.9/(π·0.04) + 0.5·0.04/(π·1e-4))/4
    #      = 0.0318310 + (2.1485917 + 63.6619772)/4 = 16.4844732.
    value = brdf.two_lobe(N, direction(0, 0), direction(0, 0), **p)
    assert value == pytest.approx(16.4844732, rel=1e-7)
    # 2. L at 30°, V = n: H at 15°, NH = VH = cos 15°, tan²15° = 0.0717968; the narrow lobe is
    #    exp(−717.968)-small, the broad one D_TR = ab²/(π cos⁴15° (ab² + tan²15°)²):
    #    0.04/(π·0.8705127·0.1117968²) = 1.1702442; F = 0.9 + 0.1 (1 − cos 15°)⁵ = 0.9000000;
    #    ρ = 0.0318310 + 0.3·0.9·1.1702442/(4 cos 30°) = 0.0318310 + 0.0912115 = 0.1230425.
    value = brdf.two_lobe(N, direction(30, 0), direction(0, 0), **p)
    assert value == pytest.approx(0.1230425, rel=1e-6)


def test_one_lobe_and_lambert_limits(random_geometry):
    normal, light, view, _ = random_geometry(np.random.default_rng(21), 3000)
    narrow_only = brdf.two_lobe(
        normal, light, view, rd=0.2, rb=0.0, ab=0.3, fb=1.0, rn=0.7, mn=0.1, fn=0.5
    )
    cook_torrance = brdf.cook_torrance(normal, light, view, rd=0.2, rs=0.7, m=0.1, f0=0.5)
    np.testing.assert_allclose(narrow_only, cook_torrance, rtol=1e-12, atol=1e-300)
    no_lobes = brdf.two_lobe(
        normal, light, view, rd=0.6, rb=0.0, ab=0.3, fb=1.0, rn=0.0, mn=0.1, fn=0.5
    )
    np.testing.assert_allclose(no_lobes, brdf.lambert(normal, light, view, 0.6), rtol=1e-15)


def test_broad_lobe_has_power_law_tails(direction):
    """Far from the mirror direction GGX falls as tan⁻⁴θ_H, Beckmann as a Gaussian."""
    ggx = brdf.get("two-lobe", rd=0.0, rb=1.0, ab=0.05, fb=1.0, rn=0.0)
    beckmann = brdf.get("cook-torrance", rd=0.0, rs=1.0, m=0.05, f0=1.0)
    light = direction(20, 180)
    near, far = direction(26, 0), direction(50, 0)  # H 3° and 15° from n
    assert ggx(N, light, far) / ggx(N, light, near) > 1e-3
    assert beckmann(N, light, far) / beckmann(N, light, near) < 1e-10


def test_weights_above_one_are_rejected():
    with pytest.raises(brdf.BRDFParameterError, match=r"rd \+ rb \+ rn = 1.1 exceeds 1"):
        brdf.get("two-lobe", rd=0.1, rb=0.5, rn=0.5)
    assert "rd + rb + rn ≤ 1" in str(brdf.describe("two-lobe"))
