"""Rotational symmetry groups of facet models and attitude errors modulo them."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from filters.attitude import (
    attitude_angle,
    attitude_matrix,
    axis_angle_to_quaternion,
    quaternion_from_matrix,
    quaternion_multiply,
    random_quaternion,
)
from filters.symmetry import SymmetryGroup, symmetry_group
from lightcurve.inversion import shape_symmetry
from lightcurve.photometry.render import Renderer
from shapes import FacetModel, Material, get_library, primitives

LIBRARY = get_library()


def _group(name: str) -> SymmetryGroup:
    return shape_symmetry(LIBRARY.load(name))


def _is_group(rotations: np.ndarray) -> bool:
    """Closed under products and inverses (up to 1e-6)."""
    flat = rotations.reshape(len(rotations), -1)

    def member(r: np.ndarray) -> bool:
        return bool(np.min(np.abs(flat - r.ravel()).max(axis=1)) < 1e-6)

    return all(member(a @ b) for a in rotations for b in rotations) and all(
        member(a.T) for a in rotations
    )


def test_box_with_three_sides_has_the_four_half_turns():
    group = _group("box")
    assert group.order == 4 and group.axis is None
    expected = np.array(
        [np.eye(3), np.diag([1, -1, -1]), np.diag([-1, 1, -1]), np.diag([-1, -1, 1])]
    )
    for r in expected:
        assert np.min(np.abs(group.rotations - r).reshape(4, -1).max(axis=1)) < 1e-9
    assert _is_group(group.rotations)


def test_cube_has_the_24_rotations_of_the_octahedral_group():
    group = _group("cube")
    assert group.order == 24
    assert _is_group(group.rotations)
    assert np.allclose(np.linalg.det(group.rotations), 1.0)


def test_cylinder_and_rocket_body_are_continuous_about_their_axis():
    cylinder = _group("cylinder")
    assert cylinder.axis is not None and abs(abs(cylinder.axis[2]) - 1.0) < 1e-9
    # Identical ends: half-turns about transverse axes belong to the group too.
    assert cylinder.order == 64
    rocket = _group("rocket_body")
    assert rocket.axis is not None and rocket.order == 32  # nose ≠ aft: no flips


def test_asymmetric_and_material_broken_symmetries():
    assert _group("itokawa").is_trivial
    # Plate 2 × 1 m, front and back of different materials: only the half-turn about its
    # normal; the merged facets alone would look symmetric about any normal rotation, the
    # vertices keep the outline.
    plate = _group("plate")
    assert plate.order == 2 and plate.axis is None
    # Painting one face of the box differently leaves the half-turn about that face's axis.
    box = primitives.box((1.0, 1.5, 2.0))
    group_index = (box.normals[:, 2] > 0.5).astype(int)
    painted = FacetModel(
        box.vertices,
        box.faces,
        group_index=group_index,
        group_names=["body", "top"],
        materials={
            "body": Material("lambert", {"rd": 0.3}),
            "top": Material("lambert", {"rd": 0.6}),
        },
    )
    group = shape_symmetry(painted)
    assert group.order == 2
    assert np.allclose(group.rotations[1], np.diag([-1, -1, 1]))


def test_inertia_that_breaks_the_geometric_symmetry_removes_it():
    cube = LIBRARY.load("cube")
    lopsided = cube.replace(inertia=[1.0, 1.2, 1.4])
    group = shape_symmetry(lopsided)
    assert group.order == 4  # only the half-turns about the principal axes survive


@pytest.mark.parametrize("name", ["box", "box_wing", "cube", "cylinder", "plate"])
def test_symmetry_equivalent_attitudes_render_identical_light_curves(name):
    shape = LIBRARY.load(name)
    group = shape_symmetry(shape)
    rng = np.random.default_rng(3)
    q = random_quaternion(16, rng)
    sun = rng.standard_normal((16, 3)) * 1.5e11
    observer = rng.standard_normal((16, 3)) * 4e7
    renderer = Renderer(shape)
    reference = renderer.flux(q, sun, observer)
    for equivalent in group.equivalent_attitudes(q)[1:]:
        assert np.allclose(renderer.flux(equivalent, sun, observer), reference, rtol=1e-9)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), angle=st.floats(0.0, 0.5))
def test_attitude_error_modulo_the_group(seed, angle):
    group = _group("box")
    rng = np.random.default_rng(seed)
    q = random_quaternion((), rng)
    axis = rng.standard_normal(3)
    turned = quaternion_multiply(axis_angle_to_quaternion(axis, angle), q)
    for equivalent in group.equivalent_attitudes(turned):
        assert math.isclose(float(group.attitude_error(equivalent, q)), angle, abs_tol=1e-9)
    # Never larger than the plain angle, and the closest equivalent attains it.
    other = random_quaternion((), rng)
    error = float(group.attitude_error(other, q))
    assert error <= float(attitude_angle(other, q)) + 1e-12
    closest, _ = group.closest(other, q)
    assert math.isclose(float(attitude_angle(other, closest)), error, abs_tol=1e-9)


def test_continuous_axis_error_ignores_rotations_about_the_axis():
    group = _group("rocket_body")
    rng = np.random.default_rng(5)
    q = random_quaternion((), rng)
    spun = quaternion_multiply(axis_angle_to_quaternion(group.axis, 1.234), q)
    assert float(group.attitude_error(spun, q)) < 1e-7
    tilted = quaternion_multiply(axis_angle_to_quaternion(np.cross(group.axis, [1, 0, 0]), 0.2), q)
    assert math.isclose(float(group.attitude_error(tilted, q)), 0.2, abs_tol=1e-9)


def test_nearest_equivalent_attains_the_error_modulo_the_group():
    rng = np.random.default_rng(11)
    q = random_quaternion((20,), rng)
    reference = random_quaternion((20,), rng)
    for name in ("box", "cube", "rocket_body"):
        group = _group(name)
        picked, rotation = group.nearest_equivalent(reference, q)
        error = group.attitude_error(picked, reference)
        # the picked state is the group's image of q, its angle to the reference is the error
        assert np.allclose(error, group.attitude_error(q, reference), atol=1e-9)
        assert np.allclose(attitude_angle(picked, reference), error, atol=1e-7)
        assert np.allclose(rotation @ attitude_matrix(q), attitude_matrix(picked), atol=1e-12)
        if group.axis is None:
            closest, _ = group.closest(reference, q)
            assert np.allclose(np.abs(np.sum(closest * picked, axis=-1)), 1.0, atol=1e-12)


def test_equivalent_rates_follow_the_rotation():
    group = _group("box")
    omega = np.array([0.01, -0.02, 0.03])
    rates = group.equivalent_rates(omega)
    for r, w in zip(group.rotations, rates, strict=True):
        assert np.allclose(r @ omega, w)
    assert np.allclose(quaternion_from_matrix(group.rotations), group.quaternions)


def test_degenerate_input_gives_the_identity_only():
    # All facet vectors along one line and no vertices: nothing pins a second direction.
    normals = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]])
    group = symmetry_group(np.zeros((2, 3)), normals, np.ones(2))
    assert group.is_trivial
