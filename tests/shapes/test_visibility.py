"""Self-shadowing: the direction grid, exact ray casting, visibility tables."""

import dataclasses

import numpy as np
import pytest
import torch
from scipy.spatial import cKDTree

import shapes
from shapes import primitives
from shapes.library import ShapeLibrary, builtin_library_path
from shapes.visibility.directions import CubeSphereGrid
from shapes.visibility.raycast import has_embree


def _random_directions(n, seed):
    d = np.random.default_rng(seed).normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def _step(height=0.5):
    """Unit floor (normal +z) with a two-sided wall of ``height`` along its x = 0 edge."""
    floor = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]
    wall = [[0, 0, 0], [0, 1, 0], [0, 1, height], [0, 0, height]]
    vertices = np.array(floor + wall + wall, float)
    faces = [[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7], [8, 10, 9], [8, 11, 10]]
    return shapes.FacetModel(
        vertices, faces, group_index=[0, 0, 1, 1, 2, 2], group_names=["floor", "front", "back"]
    )


@pytest.fixture(scope="module")
def builtin():
    return ShapeLibrary(builtin_library_path(), read_only=True)


# --------------------------------------------------------------------------- grid
def test_cube_sphere_grid_nodes():
    grid = CubeSphereGrid(26)
    assert len(grid) == 6 * 26**2 + 2 == 4058
    np.testing.assert_allclose(np.linalg.norm(grid.directions, axis=1), 1.0)
    assert set(np.unique(grid.node_index)) == set(range(len(grid)))
    # quasi-uniform: nearest-neighbour spacing within a factor 1.5
    spacing = cKDTree(grid.directions).query(grid.directions, k=2)[0][:, 1]
    assert spacing.max() / spacing.min() < 1.5
    # locating a node returns it with weight one
    index, weights = grid.locate(grid.directions)
    best = index[np.arange(len(grid)), weights.argmax(axis=1)]
    np.testing.assert_array_equal(best, np.arange(len(grid)))
    np.testing.assert_allclose(weights.max(axis=1), 1.0, atol=1e-12)


def test_locate_weights_and_continuity_across_seams():
    grid = CubeSphereGrid(10)
    d = _random_directions(20000, seed=1)
    index, weights = grid.locate(d)
    assert weights.min() >= -1e-12
    np.testing.assert_allclose(weights.sum(axis=1), 1.0, atol=1e-12)
    blend = np.einsum("nk,nkc->nc", weights, grid.directions[index])
    blend /= np.linalg.norm(blend, axis=1, keepdims=True)
    assert np.arccos(np.clip(np.sum(blend * d, axis=1), -1, 1)).max() < np.pi / (2 * 10)
    # a random tabulated function is continuous across the cube seams (x = y plane)
    values = np.random.default_rng(2).random((len(grid), 1))
    seam = np.array([1.0, 1.0, 0.37])
    eps = 1e-9
    sides = seam + np.array([[eps, -eps, 0.0], [-eps, eps, 0.0]])
    i, w = grid.locate(sides)
    f = np.einsum("nk,nk->n", w, values[i, 0])
    assert abs(f[0] - f[1]) < 1e-6


# ------------------------------------------------------------------ exact fractions
@pytest.mark.parametrize("elevation_deg", [30.0, 45.0, 60.0])
def test_wall_shadow_on_floor_matches_geometry(elevation_deg):
    height, e = 0.5, np.radians(elevation_deg)
    model = _step(height)
    compiled = model.compiled()
    floor = compiled.facet_map[0]
    d = np.array([[-np.cos(e), 0.0, np.sin(e)]])
    fraction = shapes.visible_fraction(compiled, d, samples=4096)
    expected = 1.0 - min(1.0, height / np.tan(e))
    assert fraction[0, floor] == pytest.approx(expected, abs=0.02)
    assert fraction[0, compiled.facet_map[2]] == 0.0  # the +x wall face looks away
    assert fraction[0, compiled.facet_map[4]] == 1.0  # the −x wall face is unobstructed


def test_convex_body_ray_casting_equals_front_facing_test():
    compiled = primitives.ellipsoid((300.0, 200.0, 150.0), 2).compiled()
    assert not compiled.can_be_shadowed.any()
    forced = dataclasses.replace(compiled, can_be_shadowed=np.ones(len(compiled), bool))
    d = _random_directions(60, seed=5)
    cast = shapes.visible_fraction(forced, d)
    np.testing.assert_allclose(cast, (d @ compiled.normals.T > 0).astype(float), atol=1e-12)


def test_embree_and_trimesh_backends_agree():
    model = _step(0.5)
    d = np.vstack([_random_directions(11, seed=6), [[-(0.5**0.5), 0.0, 0.5**0.5]]])
    trimesh_result = shapes.visible_fraction(model, d, samples=64, backend="trimesh")
    assert trimesh_result[-1, model.compiled().facet_map[0]] == pytest.approx(0.5, abs=0.1)
    if has_embree:
        embree_result = shapes.visible_fraction(model, d, samples=64, backend="embree")
        np.testing.assert_allclose(embree_result, trimesh_result, atol=1e-12)
    with pytest.raises(ValueError, match="unknown ray-casting backend"):
        shapes.visible_fraction(model, d, backend="optix")


# ------------------------------------------------------------------------ tables
def test_table_mirror_continuation_and_nodes():
    model = _step(0.5)
    table = shapes.build_visibility_table(model, resolution=6, samples=256)
    compiled = model.compiled()
    d = table.directions
    exact = shapes.visible_fraction(compiled, d, samples=256)
    cos = d @ compiled.normals.T
    front = cos > 0
    np.testing.assert_allclose(table.fraction[front], exact[front], atol=1e-6)
    # behind a facet the table holds the fraction of the mirror direction
    floor = compiled.facet_map[0]
    behind = np.flatnonzero(cos[:, floor] < 0)
    mirror = d[behind] - 2 * cos[behind, floor, None] * compiled.normals[floor]
    mirrored = shapes.visible_fraction(compiled, mirror, samples=256)[:, floor]
    np.testing.assert_allclose(table.fraction[behind, floor], mirrored, atol=1e-6)
    # interpolation reproduces the table at its nodes
    np.testing.assert_allclose(table.interpolate(d), table.fraction, atol=1e-6)


@pytest.mark.parametrize(("name", "n_directions"), [("box_wing", 1000), ("itokawa", 250)])
def test_builtin_tables_match_ray_casting(builtin, name, n_directions):
    model = builtin.load(name)
    compiled = model.compiled()
    table = compiled.visibility
    assert table is not None and len(table.grid) >= 4000
    d = _random_directions(n_directions, seed=7)
    exact = shapes.visible_fraction(compiled, d, samples=table.samples)
    interpolated = table.interpolate(d)
    relevant = (d @ compiled.normals.T > 0) & compiled.can_be_shadowed
    error = np.abs(interpolated - exact)[relevant]
    print(f"{name}: mean |table − ray cast| = {error.mean():.4f}, max = {error.max():.3f}")
    assert error.mean() < 0.02
    assert relevant.sum() > 0.3 * n_directions * compiled.can_be_shadowed.sum()


def test_table_interpolation_numpy_and_torch_agree(builtin):
    table = builtin.load("box_wing").compiled().visibility
    d = _random_directions(500, seed=8).reshape(5, 100, 3)
    numpy64 = table.interpolate(d)
    assert numpy64.shape == (5, 100, table.n_facets) and numpy64.dtype == np.float64
    torch64 = table.interpolate(torch.from_numpy(d))
    assert isinstance(torch64, torch.Tensor) and torch64.dtype == torch.float64
    np.testing.assert_allclose(torch64.numpy(), numpy64, atol=1e-12)
    numpy32 = table.interpolate(d.astype(np.float32))
    torch32 = table.interpolate(torch.from_numpy(d).float())
    assert numpy32.dtype == np.float32 and torch32.dtype == torch.float32
    np.testing.assert_allclose(numpy32, numpy64, atol=1e-5)
    np.testing.assert_allclose(torch32.numpy(), numpy64, atol=1e-5)


def test_table_save_load_round_trip(tmp_path):
    model = _step(0.5)
    table = shapes.build_visibility_table(model, resolution=5, samples=64)
    path = tmp_path / "step.visibility.npz"
    table.save(path)
    assert [p.name for p in tmp_path.iterdir()] == [path.name]
    loaded = shapes.VisibilityTable.load(path)
    np.testing.assert_allclose(loaded.fraction, table.fraction, atol=0.5 / 255 + 1e-7)
    assert loaded.structure == table.structure and loaded.samples == 64
    loaded.check_fits(model.compiled())
    assert model.with_visibility(loaded).compiled().visibility is loaded
    path.write_bytes(b"not a table")
    with pytest.raises(shapes.ShapeError, match="not a readable visibility table"):
        shapes.VisibilityTable.load(path)


def test_table_of_another_mesh_is_refused(builtin):
    table = builtin.load("box_wing").compiled().visibility
    with pytest.raises(shapes.ShapeError, match="another mesh"):
        primitives.box().with_visibility(table)


def test_table_follows_principal_frame_rotation(builtin):
    model = builtin.load("box_wing")
    rotated = model.to_principal_frame()
    rotation = np.asarray(rotated.provenance["principal_frame"]["rotation"])
    assert not np.allclose(rotation, np.eye(3))
    table, new_table = model.compiled().visibility, rotated.compiled().visibility
    assert new_table is not None
    d = _random_directions(200, seed=9)
    np.testing.assert_allclose(
        new_table.interpolate(d @ rotation.T), table.interpolate(d), atol=1e-6
    )
    exact = shapes.visible_fraction(rotated, d[:50] @ rotation.T, samples=table.samples)
    reference = shapes.visible_fraction(model, d[:50], samples=table.samples)
    assert np.abs(exact - reference).mean() < 1e-3


def test_exact_fraction_defaults_to_the_table_sampling(builtin):
    compiled = builtin.load("box_wing").compiled()
    d = _random_directions(20, seed=10)
    table = compiled.visibility
    default = shapes.visible_fraction(compiled, d)
    same = shapes.visible_fraction(compiled, d, samples=table.samples, spacing=table.spacing)
    np.testing.assert_array_equal(default, same)
    coarse = shapes.visible_fraction(compiled, d, samples=4, spacing=0.0)
    assert np.abs(coarse - default).max() > 0  # the sampling matters, so it must match
