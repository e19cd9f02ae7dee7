"""FacetModel basics: geometry caches, groups, materials, derived models, primitives."""

import numpy as np
import pytest

import shapes
from shapes import primitives
from shapes.material import MLI, Material


def test_geometry_of_a_box():
    model = primitives.box((1.0, 2.0, 3.0), subdivisions=2)
    assert len(model.faces) == 6 * 2 * 2**2
    assert model.area == pytest.approx(2 * (2 + 3 + 6))
    np.testing.assert_allclose(np.linalg.norm(model.normals, axis=1), 1.0)
    # outward: the normal points away from the centre
    assert np.all(np.sum(model.normals * model.centroids, axis=1) > 0)
    assert model.is_watertight and model.is_convex
    assert not model.vertices.flags.writeable  # caches stay valid


def test_with_materials_and_fingerprint():
    wing = primitives.box_wing()
    assert wing.materials["bus"] is MLI
    white = Material("lambert", {"rd": 0.8}, name="white")
    repainted = wing.with_materials({"bus": white})
    assert repainted.materials["bus"] == white
    assert repainted.materials["solar_array"] == wing.materials["solar_array"]
    assert repainted.fingerprint != wing.fingerprint
    assert wing.with_materials(white).materials == dict.fromkeys(wing.group_names, white)
    # merging depends on materials: one material merges the yoke's and bus's coplanar sides
    assert len(wing.with_materials(white).compiled()) < len(wing.compiled())


def test_principal_frame_rotates_reference_directions():
    brushed = Material(
        "ashikhmin-shirley", {"rd": 0.1, "rs": 0.5, "nu": 10, "nv": 1000}, "brushed", (1, 0, 0)
    )
    model = primitives.box((3.0, 1.0, 2.0), materials=brushed)
    principal = model.to_principal_frame()
    rotation = np.asarray(principal.provenance["principal_frame"]["rotation"])
    new_ref = principal.materials["body"].reference_direction
    np.testing.assert_allclose(new_ref, rotation @ [1, 0, 0], atol=1e-12)
    # the tangents of the same physical faces agree after rotating back (where the reference
    # direction is not along the normal; there the fallback is a frame-dependent body axis)
    before = model.compiled()
    after = principal.compiled()
    usable = np.abs(before.normals[:, 0]) < 0.5
    np.testing.assert_allclose(
        (after.tangents @ rotation)[usable], before.tangents[usable], atol=1e-12
    )


def test_rocket_body_and_primitives_sizes():
    rocket = primitives.rocket_body()
    assert rocket.group_names == ["aft", "body", "nose"]
    extent = np.ptp(rocket.vertices, axis=0)
    np.testing.assert_allclose(extent, [3.9, 3.9, 11.0], rtol=1e-3)
    assert rocket.is_watertight and rocket.is_convex
    wing = primitives.box_wing()
    assert np.ptp(wing.vertices[:, 1]) == pytest.approx(15.5)
    assert len(primitives.box_wing(subdivisions=7).faces) == 44 * 49
    ellipsoid = primitives.ellipsoid((3.0, 2.0, 1.0), 3)
    np.testing.assert_allclose(np.ptp(ellipsoid.vertices, axis=0), [6.0, 4.0, 2.0])
    assert ellipsoid.materials["surface"].brdf == "lommel-seeliger"
    with pytest.raises(shapes.ShapeError, match="positive"):
        primitives.box((1.0, -1.0, 1.0))
    with pytest.raises(shapes.ShapeError, match="subdivisions"):
        primitives.icosphere(1.0, 9)
