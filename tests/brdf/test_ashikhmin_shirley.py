"""Ashikhmin–Shirley: hand-computed values (isotropic and anisotropic), tangent-frame invariance."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import brdf

N = np.array([0.0, 0.0, 1.0])
RD, RS = 0.3, 0.1
DIFFUSE = 28 * RD / (23 * math.pi) * (1 - RS)  # 28·0.3/(23π)·0.9 = 0.1046271


def test_hand_computed_values_isotropic(direction):
    # 1. L = V = n, nu = nv = 50: NH = VH = 1, F = rs = 0.1,
    #    ρ_d = 0.1046271·(1 − 0.5⁵)² = 0.1046271·0.9384766 = 0.0981901,
    #    ρ_s = √(51·51)/(8π)·1/(1·1)·0.1 = 0.2029226 → ρ = 0.3011126.
    value = brdf.ashikhmin_shirley(
        N, direction(0, 0), direction(0, 0), rd=RD, rs=RS, nu=50.0, nv=50.0
    )
    assert value == pytest.approx(DIFFUSE * (1 - 0.5**5) ** 2 + 51 / (8 * math.pi) * 0.1)
    assert value == pytest.approx(0.3011126, rel=1e-6)
    # 2. L at 30°, V = n: NH = VH = cos 15°, max(NL, NV) = 1, F = 0.1 + 0.9 (1 − cos 15°)⁵,
    #    ρ_d = 0.1046271·(1 − (1 − cos 30°/2)⁵)·(1 − 0.5⁵) = 0.1046271·0.9414042·0.96875
    #        = 0.0954184,
    #    ρ_s = 51/(8π)·cos¹⁵15°^(50)/cos 15°·F = 2.0292255·0.1766806/0.9659258·0.1000000
    #        = 0.0371172 → ρ = 0.1325356.
    value = brdf.ashikhmin_shirley(
        N, direction(30, 0), direction(0, 0), rd=RD, rs=RS, nu=50.0, nv=50.0
    )
    assert value == pytest.approx(0.1325356, rel=1e-6)


def test_hand_computed_values_anisotropic(direction):
    # 3. nu = 10, nv = 100, tangent u = x; L at 40°, V = n so H lies at 20° from n.
    #    L in the x–z plane: H·u = sin 20°, H·v = 0 → exponent nu = 10;
    #    L in the y–z plane: H·u = 0, H·v = sin 20° → exponent nv = 100.
    #    ρ_d = 0.1046271·(1 − (1 − cos 40°/2)⁵)·0.96875 = 0.1046271·0.9105979·0.96875 = 0.0922959,
    #    ρ_s = √(11·101)/(8π)·cos 20°^e/cos 20°·F, √1111/(8π) = 1.3262249,
    #    F = 0.1 + 0.9 (1 − cos 20°)⁵ = 0.1000007:
    #    e = 10:  1.3262249·0.5368564/0.9396926·0.1000007 = 0.0757692 → ρ = 0.1680651,
    #    e = 100: 1.3262249·0.0019888/0.9396926·0.1000007 = 0.0002807 → ρ = 0.0925766.
    tangent = np.array([1.0, 0.0, 0.0])
    along_u = brdf.ashikhmin_shirley(
        N, direction(40, 0), direction(0, 0), rd=RD, rs=RS, nu=10.0, nv=100.0, tangent=tangent
    )
    along_v = brdf.ashikhmin_shirley(
        N, direction(40, 90), direction(0, 0), rd=RD, rs=RS, nu=10.0, nv=100.0, tangent=tangent
    )
    assert along_u == pytest.approx(0.1680651, rel=1e-6)
    assert along_v == pytest.approx(0.0925766, rel=1e-6)


@settings(max_examples=40, deadline=None)
@given(
    angle=st.floats(0.0, 2 * math.pi),
    exponent=st.floats(0.0, 5000.0),
    seed=st.integers(0, 2**31 - 1),
)
def test_isotropic_is_invariant_to_the_tangent_frame(random_geometry, angle, exponent, seed):
    normal, light, view, tangent = random_geometry(np.random.default_rng(seed), 64, True)
    # A second tangent: the first one turned by `angle` about the normal (Rodrigues).
    u = tangent - np.sum(tangent * normal, -1, keepdims=True) * normal
    turned = u * math.cos(angle) + np.cross(normal, u) * math.sin(angle)
    args = {"rd": 0.4, "rs": 0.3, "nu": exponent, "nv": exponent}
    first = brdf.ashikhmin_shirley(normal, light, view, **args, tangent=tangent)
    second = brdf.ashikhmin_shirley(normal, light, view, **args, tangent=turned)
    untangled = brdf.ashikhmin_shirley(normal, light, view, **args)
    np.testing.assert_allclose(first, second, rtol=1e-10, atol=1e-300)
    np.testing.assert_allclose(first, untangled, rtol=1e-10, atol=1e-300)


def test_anisotropy_depends_on_the_tangent(direction):
    light, view = direction(40, 30), direction(0, 0)
    values = [
        brdf.ashikhmin_shirley(N, light, view, rd=0.3, rs=0.3, nu=10.0, nv=100.0, tangent=t)
        for t in (np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]))
    ]
    assert abs(values[0] - values[1]) > 0.2 * max(values)
