"""Solid mass properties (signed tetrahedra) against closed forms and trimesh's
divergence-theorem integrals."""

import numpy as np
import pytest
import trimesh
from scipy.spatial import ConvexHull
from scipy.spatial.transform import Rotation

from shapes.mass import solid_properties


def _outward_hull(points):
    """Vertices and outward-wound triangles of the convex hull of ``points``."""
    hull = ConvexHull(points)
    faces = hull.simplices.copy()
    a, b, c = (points[faces[:, k]] for k in range(3))
    inward = np.einsum("ij,ij->i", np.cross(b - a, c - a), a - points.mean(axis=0)) < 0
    faces[inward] = faces[inward][:, ::-1]
    return points, faces


def test_box_far_from_the_origin_matches_the_closed_form():
    sides = np.array([1.0, 2.0, 3.0])
    mesh = trimesh.creation.box(extents=sides)
    rotation = Rotation.from_euler("zyx", [30.0, -50.0, 70.0], degrees=True).as_matrix()
    offset = np.array([80.0, -40.0, 25.0])
    props = solid_properties((mesh.vertices @ rotation.T + offset)[mesh.faces], density=2.0)
    volume = sides.prod()
    principal = volume / 12.0 * (sides @ sides - sides**2)
    np.testing.assert_allclose(props.measure, volume, rtol=1e-12)
    np.testing.assert_allclose(props.mass, 2.0 * volume, rtol=1e-12)
    np.testing.assert_allclose(props.center_of_mass, offset, rtol=0, atol=1e-12)
    np.testing.assert_allclose(
        props.inertia, 2.0 * rotation @ np.diag(principal) @ rotation.T, rtol=0, atol=2e-11
    )


def test_random_convex_polyhedron_matches_trimesh():
    rng = np.random.default_rng(7)
    vertices, faces = _outward_hull(rng.normal(size=(200, 3)) * [3.0, 1.5, 1.0] + [2.0, 0, -1])
    props = solid_properties(vertices[faces])
    reference = trimesh.Trimesh(vertices, faces, process=False).mass_properties
    np.testing.assert_allclose(props.measure, reference.volume, rtol=1e-12)
    np.testing.assert_allclose(props.center_of_mass, reference.center_mass, rtol=1e-12)
    np.testing.assert_allclose(props.inertia, reference.inertia, rtol=1e-11, atol=1e-14)


def test_inward_winding_is_rejected():
    mesh = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    with pytest.raises(ValueError, match="no volume"):
        solid_properties(mesh.vertices[mesh.faces[:, ::-1]])
