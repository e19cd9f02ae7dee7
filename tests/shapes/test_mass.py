"""Mass properties against closed forms and the principal-axis frame."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

import shapes
from shapes import mass, primitives

PHI = (1 + 5**0.5) / 2


def assert_tensor(actual, expected, rtol):
    """Tensors equal to ``rtol`` of the largest element (zeros compared at that scale)."""
    expected = np.asarray(expected)
    np.testing.assert_allclose(actual, expected, rtol=rtol, atol=rtol * np.abs(expected).max())


def _moved(model, rotation, offset):
    """The same body rotated by ``rotation`` (3×3) and shifted by ``offset`` (m)."""
    return model.replace(vertices=model.vertices @ rotation.T + offset)


def test_box_solid_matches_closed_form_in_general_position():
    a, b, c = 1.0, 2.0, 3.0
    rotation = Rotation.from_rotvec([0.3, -0.7, 0.5]).as_matrix()
    offset = np.array([10.0, -4.0, 2.5])
    model = _moved(primitives.box((a, b, c)), rotation, offset)
    m = model.mass
    assert model.inertia_source == "solid"
    assert m == pytest.approx(a * b * c, rel=1e-12)  # density 1 kg/m³
    body = m / 12 * np.diag([b**2 + c**2, a**2 + c**2, a**2 + b**2])
    np.testing.assert_allclose(model.center_of_mass, offset, rtol=1e-12)
    assert_tensor(model.inertia, rotation @ body @ rotation.T, 1e-9)


def test_regular_prism_matches_closed_form_and_fine_cylinder():
    radius, height, n = 0.5, 2.0, 12
    model = primitives.cylinder(radius, height, sections=n)
    m = model.mass
    # regular n-gon of circumradius R: polar moment per mass R²(2 + cos 2π/n)/6
    jzz = m * radius**2 * (2 + np.cos(2 * np.pi / n)) / 6
    jxx = jzz / 2 + m * height**2 / 12
    np.testing.assert_allclose(np.diag(model.inertia), [jxx, jxx, jzz], rtol=1e-9)
    np.testing.assert_allclose(m, n / 2 * radius**2 * np.sin(2 * np.pi / n) * height, rtol=1e-12)
    fine = primitives.cylinder(radius, height, sections=128)
    m = fine.mass
    cylinder = [m * (3 * radius**2 + height**2) / 12] * 2 + [m * radius**2 / 2]
    np.testing.assert_allclose(np.diag(fine.inertia), cylinder, rtol=1e-3)


def test_icosahedron_exact_and_fine_icosphere_matches_sphere():
    ico = primitives.icosphere(1.0, 0)
    edge = np.linalg.norm(ico.vertices[ico.faces[0, 0]] - ico.vertices[ico.faces[0, 1]])
    # solid regular icosahedron: J = φ²/10 · m a²
    assert_tensor(ico.inertia, PHI**2 / 10 * ico.mass * edge**2 * np.eye(3), 1e-9)
    radius = 2.0
    fine = primitives.icosphere(radius, 5)
    assert_tensor(fine.inertia, 0.4 * fine.mass * radius**2 * np.eye(3), 1e-3)
    shell = fine.replace(inertia="shell")
    assert_tensor(shell.inertia, 2 / 3 * shell.mass * radius**2 * np.eye(3), 1e-3)


def test_shell_of_cube_is_five_eighteenths():
    side = 1.7
    model = primitives.box((side, side, side)).replace(inertia="shell", mass=12.0)
    assert model.inertia_source == "shell"
    assert_tensor(model.inertia, 5 / 18 * 12.0 * side**2 * np.eye(3), 1e-12)


def test_open_mesh_defaults_to_shell_and_plate_inertia():
    plate = primitives.plate(2.0, 1.0).replace(mass=10.0)
    assert plate.inertia_source == "shell" and not plate.is_watertight
    # two coincident sheets of one thin plate: J = m/12 diag(b², a², a² + b²)
    np.testing.assert_allclose(np.diag(plate.inertia), 10 / 12 * np.array([1.0, 4.0, 5.0]))


def test_assembly_of_two_half_boxes_equals_whole_box():
    half = mass.solid_properties(primitives.box((1.0, 2.0, 1.5)).triangles)
    left = mass.MassProperties(half.mass, np.array([0, -1.0, 0]), half.inertia, half.measure)
    right = mass.MassProperties(half.mass, np.array([0, 1.0, 0]), half.inertia, half.measure)
    whole = mass.solid_properties(primitives.box((1.0, 4.0, 1.5)).triangles)
    combined = mass.combine([left, right])
    assert combined.mass == pytest.approx(whole.mass)
    assert_tensor(combined.inertia, whole.inertia, 1e-12)


@settings(max_examples=25, deadline=None)
@given(
    rotvec=st.lists(st.floats(-3, 3), min_size=3, max_size=3),
    offset=st.lists(st.floats(-50, 50), min_size=3, max_size=3),
)
def test_inertia_transforms_as_a_tensor(rotvec, offset):
    base = primitives.box((0.5, 1.2, 2.0))
    rotation = Rotation.from_rotvec(rotvec).as_matrix()
    moved = _moved(base, rotation, np.array(offset))
    assert_tensor(moved.inertia, rotation @ base.inertia @ rotation.T, 1e-9)
    np.testing.assert_allclose(moved.principal_moments, base.principal_moments, rtol=1e-9)


@pytest.mark.parametrize(
    "model",
    [
        _moved(
            primitives.box((1.0, 2.0, 3.0)),
            Rotation.from_rotvec([0.4, 0.2, -1.1]).as_matrix(),
            np.array([3.0, 1.0, -2.0]),
        ),
        primitives.box_wing(array_normal=(1.0, 0.0, 1.0)),
        primitives.ellipsoid((3.0, 2.0, 1.0), 2),
    ],
    ids=["rotated box", "box-wing (given)", "ellipsoid"],
)
def test_principal_frame_diagonalises_inertia(model):
    principal = model.to_principal_frame()
    scale = model.principal_moments.max()
    off_diagonal = principal.inertia - np.diag(np.diag(principal.inertia))
    assert np.abs(off_diagonal).max() < 1e-9 * scale
    np.testing.assert_allclose(np.diag(principal.inertia), model.principal_moments, rtol=1e-9)
    np.testing.assert_allclose(principal.center_of_mass, 0.0, atol=1e-9 * model.scale)
    axes = model.principal_axes
    np.testing.assert_allclose(axes.T @ axes, np.eye(3), atol=1e-12)
    assert np.linalg.det(axes) == pytest.approx(1.0)
    assert principal.inertia_source == model.inertia_source
    recorded = np.asarray(principal.provenance["principal_frame"]["rotation"])
    np.testing.assert_allclose(recorded, axes.T)


def test_principal_axes_of_equal_moments_do_not_depend_on_the_eigensolver():
    """Equal moments leave the eigenvectors to the eigensolver (and the processor's BLAS
    kernels); the axes returned are canonical: rounding-level changes do not move them."""
    rng = np.random.default_rng(12)
    for moments in ([1.0, 1.0, 2.0], [2.0, 1.0, 1.0], [3.0, 3.0, 3.0]):
        rotation = Rotation.from_rotvec(rng.normal(size=3)).as_matrix()
        tensor = rotation @ np.diag(moments) @ rotation.T
        reference = mass.principal_axes(tensor)[1]
        np.testing.assert_allclose(
            reference.T @ tensor @ reference, np.diag(sorted(moments)), atol=1e-12
        )
        for _ in range(20):
            noise = 1e-16 * rng.normal(size=(3, 3))
            axes = mass.principal_axes(tensor + noise + noise.T)[1]
            np.testing.assert_allclose(axes, reference, atol=1e-9)
    # Model axes in a degenerate eigenspace are kept: a cube's, a cylinder's (moments Jz < Jx = Jy).
    np.testing.assert_allclose(primitives.box((1.0, 1.0, 1.0)).principal_axes, np.eye(3), atol=1e-9)
    cylinder = primitives.cylinder(0.5, 2.0, sections=12).principal_axes
    np.testing.assert_allclose(cylinder, np.eye(3)[:, [2, 0, 1]], atol=1e-9)


def test_given_inertia_is_validated():
    box = primitives.box()
    with pytest.raises(shapes.ShapeError, match="triangle inequality"):
        box.replace(inertia=[1.0, 1.0, 3.0]).inertia
    with pytest.raises(shapes.ShapeError, match="positive definite"):
        box.replace(inertia=[1.0, -1.0, 1.0]).inertia
    with pytest.raises(shapes.ShapeError, match="3 or 6"):
        shapes.inertia_from_components([1.0, 2.0])
    tensor = shapes.inertia_from_components([2.0, 3.0, 4.0, 0.1, -0.2, 0.3])
    np.testing.assert_array_equal(tensor, tensor.T)
    assert tensor[0, 1] == 0.1 and tensor[0, 2] == -0.2 and tensor[1, 2] == 0.3


def test_solid_inertia_of_open_mesh_is_refused():
    with pytest.raises(shapes.ShapeError, match="watertight"):
        primitives.plate().replace(inertia="solid").inertia
