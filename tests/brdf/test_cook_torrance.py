"""Cook–Torrance: hand-computed values (including the masking branch) and the Lambert limit."""

import math

import numpy as np
import pytest

import brdf

N = np.array([0.0, 0.0, 1.0])
RD, RS, M, F0 = 0.2, 0.6, 0.3, 0.9


def test_hand_computed_values(direction):
    # 1. L = V = n: NH = VH = 1, D = 1/(π m²) = 1/(π·0.09) = 3.5367765, G = 1, F = f0 = 0.9,
    #    ρ = 0.2/π + 0.6·3.5367765·0.9/4 = 0.0636620 + 0.4774648 = 0.5411268.
    value = brdf.cook_torrance(N, direction(0, 0), direction(0, 0), rd=RD, rs=RS, m=M, f0=F0)
    assert value == pytest.approx(0.5411268, rel=1e-6)
    # 2. L at 30°, V = n: H at 15°, NH = VH = cos 15° = 0.9659258, tan²15° = 0.0717968,
    #    D = exp(−0.0717968/0.09)/(π·0.09·cos⁴15°) = 0.4503447/0.2461317 = 1.8296904,
    #    G = min(1, 2, 2 cos 30°) = 1, F = 0.9 + 0.1·(1 − cos 15°)⁵ = 0.9000000,
    #    ρ = 0.0636620 + 0.6·1.8296904·0.9/(4·cos 30°) = 0.0636620 + 0.2852205 = 0.3488825.
    c15 = math.cos(math.radians(15))
    d = math.exp(-(math.tan(math.radians(15)) ** 2) / M**2) / (math.pi * M**2 * c15**4)
    f = F0 + (1 - F0) * (1 - c15) ** 5
    value = brdf.cook_torrance(N, direction(30, 0), direction(0, 0), rd=RD, rs=RS, m=M, f0=F0)
    assert value == pytest.approx(RD / math.pi + RS * d * f / (4 * math.cos(math.radians(30))))
    assert value == pytest.approx(0.3488825, rel=1e-6)
    # 3. Retro-reflection at 70° with m = 1 (masking active): H = L = V, VH = 1, NH = cos 70°,
    #    D = exp(−tan²70°)/(π cos⁴70°) = 5.2683e-4/0.0429889 = 0.0122550,
    #    G = 2 NH NL/VH = 2 cos²70° = 0.2339556 < 1, F = f0,
    #    ρ = 0.0636620 + 0.6·0.0122550·0.2339556·0.9/(4 cos²70°) = 0.0636620 + 0.0033089.
    c70 = math.cos(math.radians(70))
    d = math.exp(-(math.tan(math.radians(70)) ** 2)) / (math.pi * c70**4)
    expected = RD / math.pi + RS * d * (2 * c70**2) * F0 / (4 * c70**2)
    value = brdf.cook_torrance(N, direction(70, 0), direction(70, 0), rd=RD, rs=RS, m=1.0, f0=F0)
    assert value == pytest.approx(expected, rel=1e-12)
    assert value == pytest.approx(0.0669708, rel=1e-6)


def test_rs_zero_is_lambert(random_geometry):
    normal, light, view, _ = random_geometry(np.random.default_rng(2), 2000)
    np.testing.assert_array_equal(
        brdf.cook_torrance(normal, light, view, rd=0.6, rs=0.0, m=0.2, f0=0.5),
        brdf.lambert(normal, light, view, 0.6),
    )
