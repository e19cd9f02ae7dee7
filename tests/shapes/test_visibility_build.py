"""The coarse-to-fine visibility-table build against the build that casts every ray, and
against exact ray casting; the refinement levels of the direction grid."""

import numpy as np
import pytest

import shapes
from shapes import primitives
from shapes.visibility import build_visibility_table, joint_visible_fraction
from shapes.visibility.build import describe_build
from shapes.visibility.directions import CubeSphereGrid

RESOLUTION = 10  # 602 directions: small tables, fast builds


def bumpy(subdivisions: int = 2) -> shapes.FacetModel:
    """A non-convex rock: an icosphere with seeded radial relief (±25 %)."""
    base = primitives.icosphere(100.0, subdivisions)
    rng = np.random.default_rng(20261206)
    u = base.vertices / np.linalg.norm(base.vertices, axis=1, keepdims=True)
    relief = sum(np.sin(3.0 * u @ w + k) for k, w in enumerate(rng.normal(size=(6, 3)))) / 6
    return base.replace(vertices=base.vertices * (1.0 + 0.5 * relief)[:, None], name="bumpy")


@pytest.fixture(scope="module")
def tables():
    compiled = bumpy().compiled()
    assert compiled.can_be_shadowed.any()
    refined = build_visibility_table(compiled, resolution=RESOLUTION, samples=8, workers=2)
    every = build_visibility_table(compiled, resolution=RESOLUTION, samples=8, refine=False)
    return compiled, refined, every


def test_refinement_levels_hold_each_node_once_after_its_neighbours():
    grid = CubeSphereGrid(RESOLUTION)
    levels = grid.refinement_levels()
    nodes = np.concatenate([level[0] for level in levels])
    assert np.array_equal(np.sort(nodes), np.arange(len(grid)))
    assert levels[0][1] is None
    assert len(levels[0][0]) == len(CubeSphereGrid(RESOLUTION // 2))
    done = set(levels[0][0].tolist())
    spacing = np.pi / (2 * RESOLUTION)
    for level_nodes, neighbours in levels[1:]:
        assert set(neighbours.ravel().tolist()) <= done
        cos = np.einsum("ij,ikj->ik", grid.directions[level_nodes], grid.directions[neighbours])
        angle = np.arccos(np.clip(cos, -1.0, 1.0))
        assert angle.min() > 0.6 * spacing  # the nearest nodes done, and no farther than
        assert angle.max() < 2.6 * spacing  # the far corners of the cells beside an edge
        done |= set(level_nodes.tolist())
    assert len(CubeSphereGrid(7).refinement_levels()) == 1  # odd: no coarser grid inside


def test_refined_table_matches_the_table_of_every_ray(tables):
    _, refined, every = tables
    assert refined.bits.shape == every.bits.shape
    differing = np.unpackbits((refined.bits ^ every.bits).view(np.uint8)).sum()
    assert differing <= 1e-3 * refined.n_points * len(refined.grid)
    # the coarse grid's nodes are cast for every point: identical there
    coarse = refined.grid.refinement_levels()[0][0]
    assert np.array_equal(refined.bits[coarse], every.bits[coarse])
    assert np.abs(refined.fraction - every.fraction).mean() < 1e-3


def test_refined_table_agrees_with_exact_ray_casting_as_the_full_one(tables):
    compiled, refined, every = tables
    rng = np.random.default_rng(7)
    light = rng.normal(size=(300, 3))
    light /= np.linalg.norm(light, axis=1, keepdims=True)
    view = light + 0.5 * rng.normal(size=(300, 3))
    view /= np.linalg.norm(view, axis=1, keepdims=True)
    exact = joint_visible_fraction(compiled, light, view, samples=8)
    front = (light @ compiled.normals.T > 0) & (view @ compiled.normals.T > 0)
    pairs = front & compiled.can_be_shadowed
    assert pairs.sum() > 1000
    error_refined = np.abs(refined.joint(light, view) - exact)[pairs].mean()
    error_every = np.abs(every.joint(light, view) - exact)[pairs].mean()
    assert error_every < 0.05  # the table's own interpolation error at this coarse grid
    assert error_refined <= error_every + 2e-3


def test_thread_count_does_not_change_the_table():
    compiled = bumpy(1).compiled()
    one = build_visibility_table(compiled, resolution=6, samples=8, workers=1)
    two = build_visibility_table(compiled, resolution=6, samples=8, workers=2)
    assert np.array_equal(one.bits, two.bits)


def test_a_convex_body_casts_no_ray_that_is_hidden():
    table = build_visibility_table(primitives.icosphere(1.0, 1), resolution=6, workers=2)
    assert table.n_points == 0 or np.all(table.fraction == 1.0)


def test_describe_build_names_the_work():
    line = describe_build(bumpy(1), resolution=RESOLUTION, samples=8, workers=2)
    assert line.startswith("visibility table (joint lit and seen) of 80 effective facets: 602")
    assert line.endswith(" s on 2 threads")
