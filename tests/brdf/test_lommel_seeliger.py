"""Lommel–Seeliger (DAMIT): hand-computed values, the phase function and its clamp."""

import math

import numpy as np
import pytest

import brdf

N = np.array([0.0, 0.0, 1.0])
PARAMS = {"w": 0.8, "c": 0.1, "a": 0.5, "d": 0.1, "k": -0.5}
SCALE = 0.8 / (4 * math.pi)  # w/(4π) = 0.0636620


def test_hand_computed_values(direction):
    # 1. L = V = n: α = 0, f = 0.5 + 0 + 1 = 1.5, ρ = 0.0636620·1.5·(1/2 + 0.1) = 0.0572958.
    value = brdf.lommel_seeliger(N, direction(0, 0), direction(0, 0), **PARAMS)
    assert value == pytest.approx(SCALE * 1.5 * 0.6, rel=1e-12)
    assert value == pytest.approx(0.0572958, rel=1e-6)
    # 2. L at 60°, V = n: α = π/3, f = 0.5 e^(−10.472) − 0.5·1.0471976 + 1 = 0.4764154,
    #    ρ = 0.0636620·0.4764154·(1/1.5 + 0.1) = 0.0232527.
    value = brdf.lommel_seeliger(N, direction(60, 0), direction(0, 0), **PARAMS)
    assert value == pytest.approx(0.0232527, rel=1e-5)
    # 3. L at 30°, V = n: α = π/6, f = 0.5 e^(−5.236) − 0.5·0.5235988 + 1 = 0.7408614,
    #    ρ = 0.0636620·0.7408614·(1/(cos 30° + 1) + 0.1) = 0.0299920.
    value = brdf.lommel_seeliger(N, direction(30, 0), direction(0, 0), **PARAMS)
    assert value == pytest.approx(0.0299920, rel=1e-5)


def test_phase_function_is_clamped_at_zero(direction):
    # L at 80°, V at 60° on the other side: α = 140°, a e^(−α/d) + k α + 1 = −0.2217 → 0.
    assert brdf.lommel_seeliger(N, direction(80, 0), direction(60, 180), **PARAMS) == 0.0
    alpha = np.radians([0.0, 30.0, 140.0])
    np.testing.assert_allclose(
        brdf.phase_function(np.cos(alpha), 0.5, 0.1, -0.5),
        np.maximum(0.5 * np.exp(-alpha / 0.1) - 0.5 * alpha + 1, 0),
        rtol=1e-12,
    )


def test_pure_lommel_seeliger_normalisation():
    # c = 0, f ≡ 1 (a = k = 0): the single-scattering albedo w gives the plane albedo at
    # normal incidence ∫ w/(4π(1 + μ)) μ dω = (w/2)(1 − ln 2).
    model = brdf.get("lommel-seeliger", w=0.6, c=0.0, a=0.0, d=0.1, k=0.0)
    value = brdf.albedo(model, [0.0], n=12, levels=4)[0]
    assert value == pytest.approx(0.3 * (1 - math.log(2)), rel=1e-10)
