"""Coplanar merging, tangents and the can-be-shadowed flags."""

import numpy as np
import pytest

import shapes
from shapes import primitives
from shapes.material import MLI, SOLAR_CELL, Material


def _projected_area(normals, areas, directions):
    """Σ_i A_i max(0, n_i·d) for each direction (m²)."""
    return np.maximum(directions @ normals.T, 0.0) @ areas


def _random_directions(n, seed):
    d = np.random.default_rng(seed).normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def test_cad_box_wing_merges_to_few_facets_and_keeps_projected_area():
    model = primitives.box_wing(subdivisions=7)
    assert 1900 <= len(model.faces) <= 2200
    compiled = model.compiled()
    assert len(compiled) <= 30
    assert len(compiled) == 14  # 6 bus + 6 yoke sides + cell side + rear side
    directions = _random_directions(1000, seed=3)
    original = _projected_area(model.normals, model.areas, directions)
    merged = _projected_area(compiled.normals, compiled.areas, directions)
    np.testing.assert_allclose(merged, original, rtol=1e-12)
    # flux-like sums with a second cosine (observer) are preserved too
    v = _random_directions(1000, seed=4)
    both = lambda n, a: (np.maximum(directions @ n.T, 0) * np.maximum(v @ n.T, 0)) @ a  # noqa: E731
    np.testing.assert_allclose(
        both(compiled.normals, compiled.areas), both(model.normals, model.areas), rtol=1e-12
    )
    np.testing.assert_allclose(compiled.areas.sum(), model.area, rtol=1e-13)


def test_members_and_centroids_are_consistent():
    model = primitives.box_wing(subdivisions=3)
    compiled = model.compiled()
    _, group_material = model.distinct_materials
    members = np.concatenate(compiled.members)
    assert sorted(members.tolist()) == list(range(len(model.faces)))
    for k, group in enumerate(compiled.members):
        assert np.all(compiled.facet_map[group] == k)
        np.testing.assert_allclose(compiled.areas[k], model.areas[group].sum())
        centroid = model.areas[group] @ model.centroids[group] / model.areas[group].sum()
        np.testing.assert_allclose(compiled.centroids[k], centroid, atol=1e-12)
        # one material and one normal per effective facet
        assert set(group_material[model.group_index[group]]) == {compiled.material_index[k]}
        assert np.abs(model.normals[group] @ compiled.normals[k] - 1).max() < 1e-12


def test_different_materials_never_merge():
    model = primitives.box((1.0, 1.0, 1.0))
    assert len(model.compiled()) == 6
    # split one face's two triangles into different groups with different materials
    groups = np.zeros(12, dtype=int)
    top = np.flatnonzero(model.normals[:, 2] > 0.5)
    groups[top[0]] = 1
    split = model.replace(
        group_index=groups,
        group_names=["body", "patch"],
        materials={"body": MLI, "patch": SOLAR_CELL},
    )
    assert len(split.compiled()) == 7
    same = split.with_materials({"patch": MLI})
    assert len(same.compiled()) == 6


def test_angle_tolerance():
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0], [3, 0, 0], [2, 1, 1e-3]])
    faces = np.array([[0, 1, 2], [3, 4, 5]])
    model = shapes.FacetModel(vertices, faces)
    angle = np.arccos(model.normals[0] @ model.normals[1])
    assert 5e-4 < angle < 2e-3
    assert len(model.compiled()) == 2
    assert len(model.compiled(angle_tolerance=1e-2)) == 1
    with pytest.raises(ValueError, match="angle_tolerance"):
        model.compiled(angle_tolerance=-1.0)


def test_tangents_follow_reference_direction_with_fallback():
    anisotropic = Material(
        "ashikhmin-shirley",
        {"rd": 0.3, "rs": 0.4, "nu": 1000, "nv": 10},
        reference_direction=(0.0, 0.0, 2.0),
    )
    compiled = primitives.box((1.0, 2.0, 3.0), materials=anisotropic).compiled()
    t, n = compiled.tangents, compiled.normals
    np.testing.assert_allclose(np.linalg.norm(t, axis=1), 1.0)
    np.testing.assert_allclose(np.sum(t * n, axis=1), 0.0, atol=1e-15)
    sides = np.abs(n[:, 2]) < 0.5
    np.testing.assert_allclose(t[sides], [[0, 0, 1]] * int(sides.sum()), atol=1e-15)
    # on ±z faces the reference is parallel to the normal: a body axis is used instead
    assert np.all(np.abs(t[~sides][:, 2]) < 1e-15)


def test_shadow_flags():
    assert not primitives.icosphere(1.0, 2).compiled().can_be_shadowed.any()
    assert not primitives.plate().compiled().can_be_shadowed.any()
    model = primitives.box_wing()
    compiled = model.compiled()
    assert not model.is_convex
    names = [model.group_names[model.group_index[m[0]]] for m in compiled.members]
    flags = dict()
    for name, normal, flag in zip(names, compiled.normals, compiled.can_be_shadowed, strict=True):
        flags[(name, tuple(np.round(normal, 6)))] = flag
    # bus faces facing the wings can be shadowed; those facing ±x, ±z cannot
    assert flags[("bus", (0.0, 1.0, 0.0))] and flags[("bus", (0.0, -1.0, 0.0))]
    assert not flags[("bus", (1.0, 0.0, 0.0))] and not flags[("bus", (0.0, 0.0, 1.0))]
    assert flags[("solar_array", (1.0, 0.0, 0.0))] and flags[("array_back", (-1.0, 0.0, 0.0))]


def test_array_normal_is_configurable():
    model = primitives.box_wing(array_normal=(0.0, 0.3, 1.0))
    compiled = model.compiled()
    cells = [
        k
        for k, m in enumerate(compiled.members)
        if model.group_names[model.group_index[m[0]]] == "solar_array"
    ]
    np.testing.assert_allclose(compiled.normals[cells[0]], [0, 0, 1], atol=1e-15)
    assert model.provenance["span_m"] == pytest.approx(15.5)
    with pytest.raises(shapes.ShapeError, match="parallel to y"):
        primitives.box_wing(array_normal=(0.0, 2.0, 0.0))
