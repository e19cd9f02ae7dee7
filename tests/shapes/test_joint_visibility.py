"""Joint (lit and seen) self-shadowing: ray casting, bit-mask tables, table format versions."""

import json

import numpy as np
import pytest
import torch

import shapes
from lightcurve.cli import main
from lightcurve.photometry.render import Renderer
from shapes import Material, primitives
from shapes.files import file_sha256
from shapes.library import ShapeLibrary, builtin_library_path
from shapes.visibility import TableFormatError

AU = 1.495978707e11


def _unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _random_directions(n, seed):
    return _unit(np.random.default_rng(seed).normal(size=(n, 3)))


def _plate_over_plate(cover_height=0.5):
    """A unit floor (normal +z) under a two-sided cover over its half x < 0.5."""
    floor = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]
    cover = [[0, 0, cover_height], [0.5, 0, cover_height], [0.5, 1, cover_height]]
    cover += [[0, 1, cover_height]]
    vertices = np.array(floor + cover + cover, float)
    faces = [[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7], [8, 10, 9], [8, 11, 10]]
    lambert = Material("lambert", {"rd": 0.5})
    return shapes.FacetModel(
        vertices,
        faces,
        group_index=[0, 0, 1, 1, 2, 2],
        group_names=["floor", "cover_top", "cover_bottom"],
        materials={"floor": lambert, "cover_top": lambert, "cover_bottom": lambert},
    )


@pytest.fixture(scope="module")
def builtin():
    return ShapeLibrary(builtin_library_path(), read_only=True)


@pytest.fixture(scope="module")
def plates():
    model = _plate_over_plate()
    table = shapes.build_visibility_table(model, resolution=12, samples=4096, spacing=0.0)
    return model.with_visibility(table)


def _tilted(angle_deg):
    a = np.radians(angle_deg)
    return np.array([np.sin(a), 0.0, np.cos(a)])


def test_joint_differs_from_product_at_low_phase(plates):
    """Sun 10° and observer 20° from the zenith, on the side of the cover's open edge: the
    floor is lit beyond x = 0.5 − h tan θ_L and seen beyond 0.5 − h tan θ_V, so the lit and
    seen floor is the lit floor, and the product of the two fractions counts the shadow
    twice. The cover's top (same normal and material) merges with the floor into one
    effective facet of 1.5 m², whose joint fraction is the area-weighted mean."""
    compiled = plates.compiled()
    merged = compiled.facet_map[0]
    assert compiled.facet_map[2] == merged and compiled.areas[merged] == pytest.approx(1.5)
    light, view = _tilted(10.0)[None], _tilted(20.0)[None]
    lit_floor, seen_floor = 0.5 + 0.5 * np.tan(np.radians([10.0, 20.0]))
    joint_expected = (lit_floor + 0.5) / 1.5
    joint = shapes.joint_visible_fraction(compiled, light, view)[0, merged]
    lit = shapes.visible_fraction(compiled, light)[0, merged]
    seen = shapes.visible_fraction(compiled, view)[0, merged]
    assert lit == pytest.approx(joint_expected, abs=0.01)
    assert seen == pytest.approx((seen_floor + 0.5) / 1.5, abs=0.01)
    assert joint == pytest.approx(joint_expected, abs=0.01)
    assert joint - lit * seen > 0.1  # the product counts the shadow twice
    table_joint = compiled.visibility.joint(light, view)[0, merged]
    assert table_joint == pytest.approx(joint_expected, abs=0.02)
    # the renderer: ρ (n·L)(n·V) (A_floor · lit floor + A_top)
    q = np.array([0.0, 0.0, 0.0, 1.0])
    expected_flux = 0.5 / np.pi * light[0, 2] * view[0, 2] * (lit_floor + 0.5)
    for mode, tol in (("exact", 0.01), ("table", 0.02)):
        flux = Renderer(plates, shadows=mode).flux(q, AU * light[0], view[0])
        assert flux == pytest.approx(expected_flux, rel=tol)


def test_exact_joint_at_zero_phase_equals_visible_fraction(plates):
    d = _random_directions(40, seed=1)
    compiled = plates.compiled()
    np.testing.assert_array_equal(
        shapes.joint_visible_fraction(compiled, d, d), shapes.visible_fraction(compiled, d)
    )


def test_table_joint_equals_ray_casting_at_grid_nodes(builtin):
    compiled = builtin.load("box_wing").compiled()
    table = compiled.visibility
    rng = np.random.default_rng(2)
    nodes = table.directions[rng.choice(len(table.directions), size=(2, 150))]
    exact = shapes.joint_visible_fraction(compiled, nodes[0], nodes[1])
    np.testing.assert_allclose(table.joint(nodes[0], nodes[1]), exact, atol=1e-9)
    assert (exact[(exact > 0) & (exact < 1)]).size > 20  # partial shadows were compared


@pytest.mark.parametrize("name", ["box_wing", "itokawa"])
def test_table_joint_close_to_ray_casting(builtin, name):
    compiled = builtin.load(name).compiled()
    light = _random_directions(200, seed=3)
    view = _unit(light + 0.3 * np.random.default_rng(4).normal(size=light.shape))
    exact = shapes.joint_visible_fraction(compiled, light, view)
    table = compiled.visibility.joint(light, view)
    relevant = (exact > 0) | (table > 0)
    relevant &= compiled.can_be_shadowed
    error = np.abs(table - exact)[relevant]
    print(f"{name}: mean |table − ray cast| = {error.mean():.4f}, max = {error.max():.3f}")
    assert error.mean() < 0.02
    assert np.all(table[~((light @ compiled.normals.T > 0) & (view @ compiled.normals.T > 0))] == 0)


def test_reciprocity_swapping_sun_and_observer(builtin):
    compiled = builtin.load("itokawa").compiled()
    light, view = _random_directions(300, seed=5), _random_directions(300, seed=6)
    table = compiled.visibility
    np.testing.assert_allclose(table.joint(light, view), table.joint(view, light), atol=1e-12)
    exact = shapes.joint_visible_fraction(compiled, light[:60], view[:60])
    swapped = shapes.joint_visible_fraction(compiled, view[:60], light[:60])
    np.testing.assert_array_equal(exact, swapped)


def test_torch_joint_matches_numpy_and_has_gradients(builtin):
    table = builtin.load("box_wing").compiled().visibility
    light, view = _random_directions(64, seed=7), _random_directions(64, seed=8)
    order = np.random.default_rng(9).permutation(table.n_facets)
    reference = table.joint(light, view, order=order)
    light_t = torch.tensor(light, requires_grad=True)
    joint_t = table.joint(light_t, torch.tensor(view), order=order)
    np.testing.assert_allclose(joint_t.detach().numpy(), reference, atol=1e-12)
    joint_t.sum().backward()
    assert torch.isfinite(light_t.grad).all() and light_t.grad.abs().sum() > 0
    single = table.joint(light.astype(np.float32), view.astype(np.float32))
    assert single.dtype == np.float32
    np.testing.assert_allclose(single[:, order], reference, atol=1e-5)


@pytest.mark.parametrize("name", ["cylinder", "rocket_body"])
def test_convex_shapes_none_table_and_exact_agree(name):
    shape = shapes.get_library().load(name)
    assert not shape.compiled().can_be_shadowed.any()
    shape = shape.with_visibility(shapes.build_visibility_table(shape, resolution=4))
    rng = np.random.default_rng(10)
    q = _unit(rng.normal(size=(200, 4)))
    sun = AU * _random_directions(200, seed=11)
    obs = 4e7 * _random_directions(200, seed=12)
    none = Renderer(shape, shadows="none").flux(q, sun, obs)
    for mode in ("table", "exact"):
        np.testing.assert_allclose(Renderer(shape, shadows=mode).flux(q, sun, obs), none, 1e-9)


def test_save_load_round_trip_keeps_the_bits(tmp_path, plates):
    table = plates.compiled().visibility
    path = tmp_path / "plates.visibility.npz"
    table.save(path)
    loaded = shapes.VisibilityTable.load(path)
    np.testing.assert_array_equal(loaded.bits, table.bits)
    assert (loaded.samples, loaded.spacing, loaded.n_points) == (4096, 0.0, table.n_points)
    light, view = _random_directions(50, seed=13), _random_directions(50, seed=14)
    np.testing.assert_array_equal(loaded.joint(light, view), table.joint(light, view))


def _write_version_1_table(path, n_facets):
    """A table file as written before the per-point bits (one fraction per facet)."""
    np.savez_compressed(
        path,
        format_version=np.int64(1),
        resolution=np.int64(2),
        n_facets=np.int64(n_facets),
        columns=np.arange(1, dtype=np.int64),
        fraction_u8=np.full((26, 1), 255, np.uint8),
        structure=np.str_("x"),
        areas=np.ones(n_facets),
        samples=np.int64(4),
        rotation=np.eye(3),
    )


def test_old_table_format_is_detected_and_rebuilt(tmp_path, capsys):
    _write_version_1_table(tmp_path / "old.npz", 3)
    with pytest.raises(TableFormatError, match=r"version 1.*rebuild"):
        shapes.VisibilityTable.load(tmp_path / "old.npz")
    library = ShapeLibrary(tmp_path / "lib")
    library.add_model("plates", _plate_over_plate(), resolution=4, samples=4, spacing=0.0)
    table_path = library.path / "plates.visibility.npz"
    _write_version_1_table(table_path, 3)
    manifest = json.loads(library.manifest_path.read_text())
    manifest["shapes"]["plates"]["visibility_sha256"] = file_sha256(table_path)
    library.manifest_path.write_text(json.dumps(manifest))
    # a read-only library refuses it, saying how to rebuild; validate reports it
    readonly = ShapeLibrary(library.path, read_only=True)
    with pytest.raises(shapes.ShapeError, match="lightcurve shapes rebuild plates --library"):
        readonly.load("plates")
    with pytest.raises(shapes.ShapeError, match="format version 1"):
        library.validate("plates")
    assert main(["shapes", "rebuild", "plates", "--library", str(library.path)]) == 0
    assert "rebuilt plates" in capsys.readouterr().out
    rebuilt = library.load("plates").visibility
    assert rebuilt.samples == 4 and rebuilt.resolution == 2  # kept from the old file
    library.validate("plates")
    # a writable library rebuilds an old table on load
    _write_version_1_table(table_path, 3)
    manifest = json.loads(library.manifest_path.read_text())
    manifest["shapes"]["plates"]["visibility_sha256"] = file_sha256(table_path)
    library.manifest_path.write_text(json.dumps(manifest))
    assert library.load("plates").visibility.n_points == rebuilt.n_points
    assert shapes.VisibilityTable.load(table_path).n_points == rebuilt.n_points


def test_builtin_tables_are_the_current_format(builtin):
    for name in builtin.names():
        entry = builtin.info(name)
        if entry["visibility"]:
            with np.load(builtin.path / entry["visibility"]) as data:
                assert int(data["format_version"]) == shapes.visibility.FORMAT_VERSION


def test_sampling_resolves_large_merged_facets():
    """A coarse CAD mesh (two triangles per bus face) gets points ≤ 1 % of its size apart."""
    wing = primitives.box_wing()
    compiled = wing.compiled()
    sampling = shapes.visibility.facet_sampling(compiled, 16)
    scale = np.linalg.norm(np.ptp(wing.vertices, axis=0))
    point_area = sampling.weight * compiled.areas[sampling.facet]
    assert np.sqrt(point_area.max()) <= 0.01 * scale
    np.testing.assert_allclose(np.bincount(sampling.facet, sampling.weight)[sampling.facet], 1.0)
    coarse = shapes.visibility.facet_sampling(compiled, 16, spacing=0.0)
    assert len(coarse) < len(sampling) / 10


def test_joint_columns_may_repeat_facets_or_be_unused(builtin):
    table = builtin.load("box_wing").compiled().visibility
    light, view = _random_directions(200, seed=21), _random_directions(200, seed=22)
    columns = np.array([3, -1, 0, 3, 7, -1, 13, 0])
    reference = table.joint(light, view)
    joint = table.joint(light, view, order=columns)
    used = columns >= 0
    assert joint.shape == (200, len(columns))
    np.testing.assert_array_equal(joint[:, used], reference[:, columns[used]])
    with pytest.raises(ValueError, match="facet indices below"):
        table.joint(light, view, order=np.array([0, table.n_facets]))


@pytest.mark.parametrize("name", ["box_wing", "itokawa"])
def test_fused_table_flux_matches_the_torch_table_path(name):
    """The fused path (joint fractions written into the kernels' slots, shortcuts for
    unshadowed words) against the torch path (nine node pairs per facet, blended by einsum)."""
    shape = shapes.get_library().load(name)
    rng = np.random.default_rng(23)
    n = 400
    q = _unit(rng.normal(size=(n, 4)))
    sun = AU * _random_directions(n, seed=24)
    obs = 4e7 * _random_directions(n, seed=25)
    fused = Renderer(shape, shadows="table").flux(q, sun, obs)
    eager = Renderer(shape, shadows="table", backend="torch").flux(q, sun, obs)
    np.testing.assert_array_equal(fused == 0.0, eager == 0.0)  # dark epochs stay dark
    # the fused path keeps the corners' visible fractions as float32 (2⁻²⁴ relative)
    np.testing.assert_allclose(fused, eager, rtol=2e-7, atol=0.0)
    single = Renderer(shape, shadows="table", dtype=torch.float32).flux(q, sun, obs)
    np.testing.assert_allclose(single, fused, rtol=1e-4, atol=1e-6 * fused.max())


def _joint_from_bits(table, light, view):
    """The interpolated joint fraction straight from the per-point bits (numpy, no kernel):
    ``Σ_p w_p (Σ_a α_a bit_a(p)) (Σ_b β_b bit_b(p))`` with the grid's barycentric weights."""
    lay = table.layout
    length = lay["segment_length"]
    first_point = np.cumsum(length) - length
    bit_of_point = np.repeat(64 * lay["segment_word"] + lay["segment_shift"] - first_point, length)
    bit_of_point += np.arange(length.sum())
    point_facet = np.repeat(lay["segment_facet"], lay["segment_length"])
    point_weight = np.repeat(lay["segment_weight"], lay["segment_length"])
    grid_frame = table.rotation  # grid → body; rows @ rotation: body → grid
    index_l, weight_l = table.grid.locate(light @ grid_frame)
    index_v, weight_v = table.grid.locate(view @ grid_frame)
    shift = (bit_of_point % 64).astype(np.uint64)

    def blend(index, weight):
        words = table.bits[index][..., bit_of_point // 64]  # (rows, 3, points)
        return np.einsum("ra,rap->rp", weight, ((words >> shift) & np.uint64(1)).astype(float))

    lit, seen = blend(index_l, weight_l), blend(index_v, weight_v)
    out = np.ones((len(light), table.n_facets))
    shadowable = np.unique(point_facet)
    pooled = np.zeros_like(out)
    np.add.at(pooled.T, point_facet, (point_weight * lit * seen).T)
    out[:, shadowable] = pooled[:, shadowable]
    normals = table.normals @ table.rotation.T
    front = (light @ normals.T > 0) & (view @ normals.T > 0)
    return np.where(front, out, 0.0)


@pytest.mark.parametrize("name", ["box_wing", "itokawa"])
def test_cell_lookup_equals_the_blend_of_the_bits(builtin, name):
    """The per-cell entry lists (corner fractions, corner words) give the barycentric blend
    of every point's bits, computed here from the raw bit rows: at random directions, at low
    phase angles (most points shared by both sides) and for a rotated body frame. The
    one-sided entries hold the corners' visible fractions as float32: within 1e-7."""
    table = builtin.load(name).compiled().visibility
    light = _random_directions(120, seed=31)
    view = np.concatenate([_random_directions(60, seed=32), _unit(light[60:] + 0.05)])
    np.testing.assert_allclose(
        table.joint(light, view), _joint_from_bits(table, light, view), rtol=0, atol=1e-7
    )
    turn = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    rotated = table.rotated(turn)
    np.testing.assert_allclose(
        rotated.joint(light, view), _joint_from_bits(rotated, light, view), rtol=0, atol=1e-7
    )


def test_writeable_column_order_is_read_again_after_a_change(builtin):
    """Only read-only orders are recognised by identity: a writeable one changed in place
    between calls gives the new columns."""
    table = builtin.load("box_wing").compiled().visibility
    light, view = _random_directions(50, seed=33), _random_directions(50, seed=34)
    reference = table.joint(light, view)
    order = np.array([1, 2, 3])
    first = table.joint(light, view, order=order)
    order[:] = [4, 5, 6]
    np.testing.assert_array_equal(table.joint(light, view, order=order), reference[:, 4:7])
    np.testing.assert_array_equal(first, reference[:, 1:4])
    frozen = np.array([6, 0])
    frozen.flags.writeable = False
    np.testing.assert_array_equal(table.joint(light, view, order=frozen), reference[:, [6, 0]])
