"""Shared helpers for the BRDF tests: directions and an independent reference implementation.

The reference evaluates the formulas of ``docs/brdf.md`` literally for ONE geometry at a time
with explicit vectors (mirror vector R, half vector H, tangent frame u, v = n × u, exponent
with ``1 − NH²``), in plain Python floats: no code is shared with the package kernels.
"""

from __future__ import annotations

import math

import numpy as np
import pytest


def _direction(zenith_deg: float, azimuth_deg: float) -> np.ndarray:
    """Unit vector at the given zenith and azimuth (deg) in the frame normal z, tangent x."""
    z, a = math.radians(zenith_deg), math.radians(azimuth_deg)
    return np.array([math.sin(z) * math.cos(a), math.sin(z) * math.sin(a), math.cos(z)])


def _reference(name, normal, light, view, params, tangent=None):
    n, L, V = (np.asarray(x, dtype=float) for x in (normal, light, view))
    NL, NV = float(n @ L), float(n @ V)
    if NL <= 0 or NV <= 0:
        return 0.0
    H = (L + V) / np.linalg.norm(L + V)
    NH, VH = float(n @ H), float(V @ H)
    p = params
    if name == "lambert":
        return p["rd"] / math.pi
    if name == "phong":
        R = 2 * NL * n - L
        return (
            p["rd"] / math.pi
            + p["rs"] * (p["n"] + 2) / (2 * math.pi) * max(0.0, float(R @ V)) ** p["n"]
        )
    if name == "cook-torrance":
        m = p["m"]
        D = math.exp(-(1 - NH**2) / (NH**2 * m**2)) / (math.pi * m**2 * NH**4)
        G = min(1.0, 2 * NH * NV / VH, 2 * NH * NL / VH)
        F = p["f0"] + (1 - p["f0"]) * (1 - VH) ** 5
        return p["rd"] / math.pi + p["rs"] * D * G * F / (4 * NL * NV)
    if name == "ashikhmin-shirley":
        rd, rs, nu, nv = p["rd"], p["rs"], p["nu"], p["nv"]
        diffuse = (
            28 * rd / (23 * math.pi) * (1 - rs) * (1 - (1 - NL / 2) ** 5) * (1 - (1 - NV / 2) ** 5)
        )
        if tangent is None:
            exponent = nu
        else:
            t = np.asarray(tangent, dtype=float)
            u = t - (t @ n) * n
            u /= np.linalg.norm(u)
            v = np.cross(n, u)
            exponent = (nu * float(H @ u) ** 2 + nv * float(H @ v) ** 2) / (1 - NH**2)
        F = rs + (1 - rs) * (1 - VH) ** 5
        specular = (
            math.sqrt((nu + 1) * (nv + 1)) / (8 * math.pi) * NH**exponent / (VH * max(NL, NV)) * F
        )
        return diffuse + specular
    if name == "two-lobe":
        G = min(1.0, 2 * NH * NV / VH, 2 * NH * NL / VH)
        tan2 = (1 - NH**2) / NH**2
        a2, m2 = p["ab"] ** 2, p["mn"] ** 2
        ggx = a2 / (math.pi * NH**4 * (a2 + tan2) ** 2)  # Walter et al. 2007, eq. 33
        beckmann = math.exp(-tan2 / m2) / (math.pi * m2 * NH**4)
        fresnel_b = p["fb"] + (1 - p["fb"]) * (1 - VH) ** 5
        fresnel_n = p["fn"] + (1 - p["fn"]) * (1 - VH) ** 5
        lobes = p["rb"] * fresnel_b * ggx + p["rn"] * fresnel_n * beckmann
        return p["rd"] / math.pi + lobes * G / (4 * NL * NV)
    if name == "lommel-seeliger":
        alpha = math.acos(max(-1.0, min(1.0, float(L @ V))))
        f = max(0.0, p["a"] * math.exp(-alpha / p["d"]) + p["k"] * alpha + 1)
        return p["w"] / (4 * math.pi) * f * (1 / (NL + NV) + p["c"])
    raise KeyError(name)


@pytest.fixture(scope="session")
def direction():
    """``direction(zenith_deg, azimuth_deg) -> (3,)`` unit vector (normal z, tangent x)."""
    return _direction


@pytest.fixture(scope="session")
def reference():
    """``reference(name, normal, light, view, params, tangent=None) -> float`` (sr⁻¹)."""
    return _reference


# Parameter sets used across the property tests (inside each model's valid ranges).
PARAMETER_SETS = {
    "lambert": [{"rd": 0.7}],
    "phong": [{"rd": 0.4, "rs": 0.5, "n": 20.0}, {"rd": 0.0, "rs": 1.0, "n": 2000.0}],
    "cook-torrance": [
        {"rd": 0.2, "rs": 0.6, "m": 0.3, "f0": 0.9},
        {"rd": 0.1, "rs": 0.9, "m": 0.05, "f0": 0.04},
    ],
    "ashikhmin-shirley": [
        {"rd": 0.3, "rs": 0.1, "nu": 50.0, "nv": 50.0},
        {"rd": 0.5, "rs": 0.4, "nu": 10.0, "nv": 1000.0},
    ],
    "lommel-seeliger": [{"w": 0.8, "c": 0.1, "a": 0.5, "d": 0.1, "k": -0.5}],
    "two-lobe": [
        {"rd": 0.1, "rb": 0.3, "ab": 0.2, "fb": 0.9, "rn": 0.5, "mn": 0.05, "fn": 0.04},
        {"rd": 0.007, "rb": 0.02, "ab": 0.09, "fb": 1.0, "rn": 0.97, "mn": 0.04, "fn": 0.02},
    ],
}


@pytest.fixture(scope="session")
def parameter_sets():
    """Model name → list of valid parameter dicts."""
    return PARAMETER_SETS


def _random_geometry(rng: np.random.Generator, count: int, hemisphere: bool = False):
    """Random unit (normal, light, view, tangent) arrays of shape (count, 3)."""

    def unit(size):
        x = rng.normal(size=size)
        return x / np.linalg.norm(x, axis=-1, keepdims=True)

    normal, light, view, tangent = (unit((count, 3)) for _ in range(4))
    if hemisphere:
        light = np.where((np.sum(normal * light, -1) < 0)[:, None], -light, light)
        view = np.where((np.sum(normal * view, -1) < 0)[:, None], -view, view)
    return normal, light, view, tangent


@pytest.fixture(scope="session")
def random_geometry():
    """``random_geometry(rng, count, hemisphere=False)`` → (normal, light, view, tangent)."""
    return _random_geometry
