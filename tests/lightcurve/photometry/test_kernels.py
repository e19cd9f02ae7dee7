"""The fused numba kernels against numpy, the torch path, the numpy reference and autograd."""

import copy

import numpy as np
import pytest
import torch
from numba import njit

from lightcurve.photometry.kernels import (
    FusedFlux,
    block_parameters,
    elementary,
    facet_table,
    get_num_threads,
    set_num_threads,
)
from lightcurve.photometry.reference import reference_flux
from lightcurve.photometry.render import Renderer
from shapes import Material, get_library, primitives
from tests.lightcurve._geometry import random_geometry

MATERIALS = {
    "lambert": ("lambert", {"rd": 0.5}),
    "phong": ("phong", {"rd": 0.3, "rs": 0.4, "n": 50.0}),
    "phong-flat": ("phong", {"rd": 0.3, "rs": 0.4, "n": 0.0}),
    "cook-torrance": ("cook-torrance", {"rd": 0.3, "rs": 0.5, "m": 0.2, "f0": 0.9}),
    "ashikhmin-shirley": ("ashikhmin-shirley", {"rd": 0.3, "rs": 0.4, "nu": 100.0, "nv": 100.0}),
    "anisotropic": ("ashikhmin-shirley", {"rd": 0.3, "rs": 0.4, "nu": 10.0, "nv": 1000.0}),
    "lommel-seeliger": ("lommel-seeliger", {"w": 0.2, "c": 0.1, "a": 0.5, "d": 0.1, "k": -0.5}),
    "two-lobe": (
        "two-lobe",
        {"rd": 0.2, "rb": 0.3, "ab": 0.3, "fb": 0.9, "rn": 0.3, "mn": 0.1, "fn": 0.04},
    ),
}


@njit(cache=True)
def _log_exp(x, y, log_out, exp_out):
    for i in range(x.size):
        log_out[i] = elementary.log(x[i])
        exp_out[i] = elementary.exp(y[i])


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_vectorised_log_and_exp_match_numpy(dtype):
    rng = np.random.default_rng(11)
    tiny = np.finfo(dtype).smallest_subnormal
    x = np.concatenate([rng.uniform(1e-7, 2.0, 5000), [tiny, 1e-40, 1.0, 0.5, 1e30]]).astype(dtype)
    y = np.concatenate([rng.uniform(-80.0, 80.0, 5000), [0.0, -1e-9, -86.5, -1e4, 1e-3]])
    y = y.astype(dtype)
    log_out, exp_out = np.empty_like(x), np.empty_like(y)
    _log_exp(x, y, log_out, exp_out)
    ulp = np.finfo(dtype).eps
    exact_log = np.log(x.astype(np.float64))
    assert np.all(np.abs(log_out - exact_log) <= 2 * ulp * np.maximum(np.abs(exact_log), 1.0))
    exact_exp = np.exp(y.astype(np.float64))
    normal = exact_exp > np.finfo(dtype).tiny
    assert np.all(np.abs(exp_out[normal] - exact_exp[normal]) <= 2 * ulp * exact_exp[normal])
    assert np.all(exp_out[~normal] <= np.finfo(dtype).tiny)


@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
@pytest.mark.parametrize("material", list(MATERIALS))
def test_fused_matches_torch_path_and_reference(material, dtype):
    name, params = MATERIALS[material]
    sphere = primitives.icosphere(1.0, subdivisions=2)
    shape = sphere.with_materials({g: Material(name, params) for g in sphere.group_names})
    q, sun, obs = random_geometry(200, seed=12)
    fused = Renderer(shape, dtype=dtype).flux(q, sun, obs)
    eager = Renderer(shape, dtype=dtype, backend="torch").flux(q, sun, obs)
    assert fused.dtype == (np.float32 if dtype == torch.float32 else np.float64)
    reference = reference_flux(shape, q, sun, obs)
    scale = np.max(reference)
    rtol = 1e-11 if dtype == torch.float64 else 2e-5
    assert np.max(np.abs(fused - reference)) < rtol * scale
    assert np.max(np.abs(fused - eager)) < (1e-11 if dtype == torch.float64 else 5e-4) * scale


@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
def test_fused_with_shadow_table_and_several_materials(dtype):
    for name, mode in (("box_wing", "table"), ("itokawa", "table"), ("box_wing", "exact")):
        shape = get_library().load(name)
        q, sun, obs = random_geometry(60, seed=13)
        fused = Renderer(shape, shadows=mode, dtype=dtype).flux(q, sun, obs)
        eager = Renderer(shape, shadows=mode, dtype=dtype, backend="torch").flux(q, sun, obs)
        tol = 1e-11 if dtype == torch.float64 else 2e-4
        if mode == "table" and dtype == torch.float64:
            tol = 2e-7  # the fused lookup keeps the corners' visible fractions as float32
        np.testing.assert_allclose(fused, eager, rtol=tol, atol=tol * np.max(eager))


def test_kinds_of_input_and_output():
    renderer = Renderer(get_library().load("box_wing"), dtype=torch.float32)
    q, sun, obs = random_geometry(32, seed=14)
    out_np = renderer.flux(q, sun, obs)
    assert isinstance(out_np, np.ndarray) and out_np.dtype == np.float32
    out_t = renderer.flux(torch.tensor(q), torch.tensor(sun), torch.tensor(obs))
    assert isinstance(out_t, torch.Tensor) and out_t.dtype == torch.float32
    np.testing.assert_array_equal(out_t.numpy(), out_np)
    # (P, E) broadcasting, one attitude against many geometries, and empty batches.
    grid = renderer.flux(np.stack([q, q[::-1]]), sun, obs)
    np.testing.assert_array_equal(grid[0], out_np)
    assert renderer.flux(q[0], sun, obs).shape == (32,)
    assert renderer.flux(q[:0], sun[:0], obs[:0]).shape == (0,)
    with pytest.raises(ValueError, match="q must have shape"):
        renderer.flux(q[:, :3], sun, obs)


def test_thread_count_does_not_change_results():
    sphere = primitives.icosphere(1.0, subdivisions=3)
    shape = sphere.with_materials(
        {g: Material(*MATERIALS["ashikhmin-shirley"]) for g in sphere.group_names}
    )
    q, sun, obs = random_geometry(400, seed=15)
    renderer = Renderer(shape)
    before = get_num_threads()
    try:
        set_num_threads(1)
        one = renderer.flux(q, sun, obs)
        set_num_threads(2)
        two = renderer.flux(q, sun, obs)
    finally:
        set_num_threads(None)
    np.testing.assert_array_equal(one, two)
    assert get_num_threads() == before
    with pytest.raises(ValueError, match="at least 1"):
        set_num_threads(0)


def test_gradients_take_the_torch_path_and_match_differences_of_the_fused_path():
    """∂flux/∂q by autograd (torch path) against central differences of the fused kernels."""
    shape = get_library().load("box_wing")
    renderer = Renderer(shape)
    q, sun, obs = random_geometry(8, seed=16)
    qt = torch.tensor(q, requires_grad=True)
    flux = renderer.flux(qt, torch.tensor(sun), torch.tensor(obs))
    assert flux.requires_grad
    np.testing.assert_allclose(flux.detach().numpy(), renderer.flux(q, sun, obs), rtol=1e-12)
    (gradient,) = torch.autograd.grad(flux.sum(), qt)
    step = 1e-6
    for k in range(4):
        dq = np.zeros(4)
        dq[k] = step
        central = (renderer.flux(q + dq, sun, obs) - renderer.flux(q - dq, sun, obs)) / (2 * step)
        np.testing.assert_allclose(
            gradient[:, k].numpy(), central, rtol=1e-5, atol=1e-8 * np.max(np.abs(central))
        )


@njit(cache=True)
def _base_two(x, y, normal_x, normal_y, out):
    for i in range(x.size):
        out[0, i] = elementary.log2(x[i])
        out[1, i] = elementary.exp2(y[i])
        out[2, i] = elementary.log2_normal(normal_x[i])
        out[3, i] = elementary.exp2_normal(normal_y[i])


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_base_two_log_and_exp_over_the_whole_range(dtype):
    """log₂ and 2^y over every binade, subnormals, underflow and overflow included."""
    info = np.finfo(dtype)
    rng = np.random.default_rng(17)
    low, high = float(np.log2(info.smallest_subnormal)), float(np.log2(info.max))
    edges = [info.smallest_subnormal, info.tiny, np.sqrt(0.5), 1.0, info.max]
    x = np.concatenate([np.exp2(rng.uniform(low, high, 20000)), edges]).astype(dtype)
    x = np.concatenate([x, np.nextafter(dtype(1.0), dtype([0.0, 2.0]))])
    y = np.concatenate([rng.uniform(low - 3.0, high + 3.0, x.size - 4), [0.0, -0.5, 0.5, 1e-30]])
    y = y.astype(dtype)
    normal_x = np.where(x >= info.tiny, x, info.tiny).astype(dtype)
    normal_y = np.minimum(y, dtype(info.maxexp - 1))
    out = np.empty((4, x.size), dtype=dtype)
    _base_two(x, y, normal_x, normal_y, out)
    wide = np.longdouble
    # Reference in extended precision where the platform has it, else one more ulp of slack.
    slack = 2.0 if np.finfo(wide).eps < np.finfo(np.float64).eps else 3.0

    def ulps(value, exact):
        return np.abs(value.astype(wide) - exact) / np.spacing(np.abs(exact).astype(dtype))

    assert np.max(ulps(out[0], np.log2(x.astype(wide)))) <= slack
    assert np.max(ulps(out[2], np.log2(normal_x.astype(wide)))) <= slack
    exact = np.exp2(y.astype(wide))
    normal = (exact >= info.tiny) & (exact <= info.max)
    subnormal = (exact < info.tiny) & (exact >= info.smallest_subnormal)
    assert np.max(ulps(out[1][normal], exact[normal])) <= slack
    assert np.all(np.abs(out[1][subnormal] - exact[subnormal]) <= info.smallest_subnormal)
    assert np.all(out[1][exact < 0.5 * info.smallest_subnormal] == 0.0)
    assert np.all(np.isposinf(out[1][exact > info.max]))
    exact = np.exp2(normal_y.astype(wide))
    normal = exact >= info.tiny
    assert np.max(ulps(out[3][normal], exact[normal])) <= slack
    assert np.all(out[3][~normal] == 0.0)


def _several_materials(dtype, seed=18):
    """A FusedFlux of random facets in one block per kernel (every BRDF, anisotropic too)."""
    rng = np.random.default_rng(seed)
    names = ["lambert", "phong", "cook-torrance", "ashikhmin-shirley", "anisotropic"]
    names += ["lommel-seeliger", "two-lobe"]
    per_block = 101  # not a multiple of the tile size: padding slots
    normals = rng.normal(size=(per_block * len(names), 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    tangents = np.cross(normals, rng.normal(size=normals.shape))
    tangents /= np.linalg.norm(tangents, axis=1, keepdims=True)
    areas = rng.uniform(0.5, 2.0, len(normals))
    blocks = []
    for k, material in enumerate(names):
        name, params = MATERIALS[material]
        kind, row = block_parameters(name, params, material == "anisotropic")
        blocks.append((kind, k * per_block, (k + 1) * per_block, row))
    return FusedFlux(facet_table(normals, areas, tangents, dtype), blocks, dtype), normals


def _never_skipping(fused):
    """``fused`` with cones that never skip a tile (the plain loops)."""
    plain = copy.copy(fused)
    plain.cones = fused.cones.copy()
    plain.cones[3] = 2.0
    return plain


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_tile_culling_gives_the_sums_of_the_plain_loops(dtype):
    """Skipping tiles by their cones of normals changes no sum (up to summation order):
    random geometries, every facet both lit and seen, none, and boundary sets."""
    fused, normals = _several_materials(dtype)
    plain = _never_skipping(fused)
    rng = np.random.default_rng(19)
    light = rng.normal(size=(40, 3))
    view = rng.normal(size=(40, 3))
    # L = V (opposition), L = −V (no facet lit and seen), L ⊥ V, and L on a facet's
    # tangent plane (that facet on the boundary of the lit set).
    light[:4], view[:4] = light[4:8], light[4:8]
    light[8:12], view[8:12] = light[12:16], -light[12:16]
    view[16] = np.cross(light[16], view[16])
    light[17] = np.cross(normals[0], rng.normal(size=3))
    light /= np.linalg.norm(light, axis=1, keepdims=True)
    view /= np.linalg.norm(view, axis=1, keepdims=True)
    shadow = rng.uniform(0.0, 1.0, (40, len(normals)))
    tol = 1e-13 if dtype == np.float64 else 1e-5
    for factor in (None, shadow):
        culled = fused.sums(light, view, factor)
        reference = plain.sums(light, view, factor)
        assert np.max(np.abs(culled - reference)) <= tol * np.max(reference)
        np.testing.assert_array_equal(culled[8:12], 0.0)
    # Every facet lit and seen: a cap of normals around the direction of L = V.
    cap = normals[:, 2] > 0.6
    table = facet_table(normals[cap], np.ones(cap.sum()), np.roll(normals[cap], 1, axis=1), dtype)
    kind, row = block_parameters(*MATERIALS["ashikhmin-shirley"], False)
    fused_cap = FusedFlux(table, [(kind, 0, int(cap.sum()), row)], dtype)
    plain_cap = _never_skipping(fused_cap)
    up = np.array([[0.0, 0.0, 1.0]])
    np.testing.assert_allclose(fused_cap.sums(up, up), plain_cap.sums(up, up), rtol=tol)
    np.testing.assert_array_equal(plain_cap.sums(-up, up), 0.0)
