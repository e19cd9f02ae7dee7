"""Validation of facet models and materials: each problem gives a clear ShapeError."""

import numpy as np
import pytest

import shapes
from shapes import primitives
from shapes.material import Material


def test_all_primitives_are_valid_with_outward_normals():
    for model in [
        primitives.plate(),
        primitives.box((1.0, 2.0, 3.0), subdivisions=3),
        primitives.cylinder(),
        primitives.rocket_body(),
        primitives.box_wing(subdivisions=2),
        primitives.icosphere(1.0, 4),
        primitives.ellipsoid(),
    ]:
        shapes.validate(model)
        if model.is_watertight:
            assert model.volume > 0  # outward normals enclose positive volume
    assert len(primitives.icosphere(1.0, 4).faces) >= 5000


def test_non_finite_coordinates():
    box = primitives.box()
    vertices = box.vertices.copy()
    vertices[3, 1] = np.nan
    with pytest.raises(shapes.ShapeError, match="non-finite coordinates at vertex 3"):
        shapes.FacetModel(vertices, box.faces, name="bad")


def test_bad_arrays():
    with pytest.raises(shapes.ShapeError, match=r"\(V, 3\)"):
        shapes.FacetModel(np.zeros((4, 2)), [[0, 1, 2]])
    with pytest.raises(shapes.ShapeError, match=r"outside 0\.\.2"):
        shapes.FacetModel(np.eye(3), [[0, 1, 3]])
    with pytest.raises(shapes.ShapeError, match="no facets"):
        shapes.FacetModel(np.eye(3), np.zeros((0, 3), int))
    with pytest.raises(shapes.ShapeError, match="group_index"):
        shapes.FacetModel(np.eye(3), [[0, 1, 2]], group_index=[1])


def test_degenerate_facets():
    vertices = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0]]
    model = shapes.FacetModel(vertices, [[0, 1, 2], [0, 1, 3]], name="sliver")
    with pytest.raises(shapes.ShapeError, match=r"degenerate \(zero-area\) facet 1"):
        shapes.validate(model)
    with pytest.raises(shapes.ShapeError, match="degenerate"):
        model.compiled()


def test_inconsistent_winding():
    box = primitives.box()
    faces = box.faces.copy()
    faces[4] = faces[4, ::-1]
    with pytest.raises(shapes.ShapeError, match=r"inconsistent winding: facets .*4"):
        shapes.validate(box.replace(faces=faces))


def test_inward_normals_on_closed_part():
    wing = primitives.box_wing()
    bus = wing.group_names.index("bus")
    faces = wing.faces.copy()
    faces[wing.group_index == bus] = faces[wing.group_index == bus][:, ::-1]
    with pytest.raises(shapes.ShapeError, match=r"inward normals.*group bus"):
        shapes.validate(wing.replace(faces=faces))


def test_watertight_requirement_and_facet_limit():
    plate = primitives.plate()
    shapes.validate(plate)
    with pytest.raises(shapes.ShapeError, match="watertight"):
        shapes.validate(plate, require_watertight=True)
    shapes.validate(primitives.box(), require_watertight=True)
    with pytest.raises(shapes.ShapeError, match="5120 facets exceed the limit of 5000"):
        shapes.validate(primitives.icosphere(1.0, 4), max_facets=5000)


def test_unknown_unit(tmp_path):
    with pytest.raises(shapes.ShapeError, match="unknown unit 'mm'"):
        shapes.FacetModel(np.eye(3), [[0, 1, 2]], unit="mm")
    path = tmp_path / "t.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(shapes.ShapeError, match="unknown unit 'ft'"):
        shapes.load(path, unit="ft")


def test_materials_are_checked():
    with pytest.raises(shapes.ShapeError, match="unknown BRDF 'lamber'"):
        Material("lamber", {"rd": 0.5})
    with pytest.raises(shapes.ShapeError, match="needs parameter"):
        Material("phong", {"rd": 0.5, "rs": 0.2})
    with pytest.raises(shapes.ShapeError, match="has no parameter"):
        Material("lambert", {"rd": 0.5, "rs": 0.1})
    with pytest.raises(shapes.ShapeError, match="not finite"):
        Material("lambert", {"rd": float("nan")})
    with pytest.raises(shapes.ShapeError, match="not a number"):
        Material("lambert", {"rd": "grey"})
    with pytest.raises(shapes.ShapeError, match="non-zero"):
        Material("lambert", {"rd": 0.5}, reference_direction=(0, 0, 0))
    ls = Material("lommel-seeliger", {"c": 0.1, "a": 0.5, "d": 0.1, "k": -0.5})
    assert Material.from_dict(ls.to_dict()) == ls
    anisotropic = Material(
        "ashikhmin-shirley", {"rd": 0.1, "rs": 0.5, "nu": 10, "nv": 1000}, "brushed", (2, 0, 0)
    )
    assert anisotropic.reference_direction == (1.0, 0.0, 0.0)
    assert Material.from_dict(anisotropic.to_dict()) == anisotropic
    assert hash(Material.from_dict(anisotropic.to_dict())) == hash(anisotropic)
    with pytest.raises(shapes.ShapeError, match=r"box_wing\.bus: unknown material field"):
        Material.from_dict({"brdf": "lambert", "params": {"rd": 1}, "colour": 3}, "box_wing.bus")


def test_materials_of_unknown_groups_are_refused():
    box = primitives.box()
    with pytest.raises(shapes.ShapeError, match="unknown group"):
        box.replace(materials={"wing": primitives.SOLAR_CELL})
    with pytest.raises(shapes.ShapeError, match="no group"):
        box.with_materials({"wing": primitives.SOLAR_CELL})
    with pytest.raises(shapes.ShapeError, match="no group"):
        primitives.box(materials={"wing": primitives.SOLAR_CELL})
