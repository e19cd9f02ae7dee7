"""Mesh input/output: trimesh formats with groups and materials, DAMIT files, grouped OBJ."""

import numpy as np
import pytest
import trimesh

import shapes
from shapes import primitives

MTL = """newmtl gold
Kd 0.8 0.6 0.2
newmtl black
Kd 0.05 0.05 0.05
"""

GROUPED_OBJ = """mtllib parts.mtl
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0 0 1
g lid
usemtl gold
f 1 3 2
f 1 4 3
g sides
usemtl black
f 1 2 5
f 2 3 5
usemtl gold
f 3 4 5
f 4 1 5
"""


def test_obj_groups_and_mtl_become_groups_and_materials(tmp_path):
    (tmp_path / "parts.mtl").write_text(MTL)
    path = tmp_path / "parts.obj"
    path.write_text(GROUPED_OBJ)
    model = shapes.load(path)
    # group 'sides' uses two materials: it is split into one group per material
    assert sorted(model.group_names) == ["lid", "sides_black", "sides_gold"]
    count = {g: int((model.group_index == k).sum()) for k, g in enumerate(model.group_names)}
    assert count == {"lid": 2, "sides_black": 2, "sides_gold": 2}
    assert model.materials["lid"].brdf == "lambert"
    assert model.materials["lid"].params["rd"] == pytest.approx((0.8 + 0.6 + 0.2) / 3, abs=0.01)
    assert model.materials["sides_black"].params["rd"] == pytest.approx(0.05, abs=0.01)
    assert model.is_watertight and model.volume == pytest.approx(1 / 3)
    assert model.provenance["file"] == "parts.obj"
    # explicit materials override the file's
    painted = shapes.load(path, materials=shapes.Material("lambert", {"rd": 0.9}))
    assert {m.params["rd"] for m in painted.materials.values()} == {0.9}


def test_obj_without_groups_is_grouped_by_material(tmp_path):
    (tmp_path / "parts.mtl").write_text(MTL)
    path = tmp_path / "bymat.obj"
    lines = [line for line in GROUPED_OBJ.splitlines() if not line.startswith("g")]
    path.write_text("\n".join(lines))
    assert sorted(shapes.load(path).group_names) == ["black", "gold"]
    plain = tmp_path / "plain.obj"
    plain.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    model = shapes.load(plain, unit="km")
    assert model.group_names == ["body"] and model.unit == "km"
    assert model.area == pytest.approx(0.5e6)


@pytest.mark.parametrize("suffix", [".stl", ".ply", ".off"])
def test_single_mesh_formats_round_trip(tmp_path, suffix):
    box = primitives.box((1.0, 2.0, 3.0))
    path = tmp_path / f"box{suffix}"
    box.mesh.export(path)
    model = shapes.load(path)
    assert len(model.faces) == 12
    assert model.is_watertight  # STL triangle soups are welded on load
    assert model.volume == pytest.approx(6.0)
    np.testing.assert_allclose(model.inertia, box.inertia, rtol=1e-6, atol=1e-6)


def test_glb_scene_nodes_become_groups_with_transforms(tmp_path):
    scene = trimesh.Scene()
    scene.add_geometry(trimesh.creation.box((1, 1, 1)), node_name="bus", geom_name="bus")
    panel = trimesh.creation.box((0.1, 4, 2))
    scene.add_geometry(
        panel,
        node_name="panel",
        geom_name="panel",
        transform=trimesh.transformations.translation_matrix([0, 3, 0]),
    )
    path = tmp_path / "sat.glb"
    scene.export(path)
    model = shapes.load(path)
    assert sorted(model.group_names) == ["bus", "panel"]
    k = model.group_names.index("panel")
    centroid = model.vertices[np.unique(model.faces[model.group_index == k])].mean(axis=0)
    np.testing.assert_allclose(centroid, [0, 3, 0], atol=1e-6)
    assert model.is_watertight


def _damit_text(vertices, faces):
    lines = [f"{len(vertices)} {len(faces)}"]
    lines += [" ".join(f"{c:.6f}" for c in v) for v in vertices]
    lines += [" ".join(str(i + 1) for i in f) for f in faces]
    return "\n".join(lines) + "\n"


def test_damit_shape_format(tmp_path):
    tetra = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    faces = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    path = tmp_path / "shape.txt"
    path.write_text(_damit_text(tetra, faces))
    model = shapes.load(path, unit="km")
    assert model.volume == pytest.approx(1e9 / 6)
    other = tmp_path / "shape.dat"
    other.write_text(_damit_text(tetra, faces))
    assert len(shapes.load_damit(other).faces) == 4


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("four 4\n", "line 1"),
        ("4 4\n0 0 0\n1 0 0\n", "announces 4 vertices"),
        ("3 1\n0 0 0\n1 0 x\n0 1 0\n1 2 3\n", "line 3"),
        ("3 1\n0 0 0\n1 0 0\n0 1 0\n1 2 9\n", "outside"),
    ],
)
def test_bad_damit_files_name_the_line(tmp_path, text, message):
    path = tmp_path / "bad.txt"
    path.write_text(text)
    with pytest.raises(shapes.ShapeError, match=message) as info:
        shapes.load(path)
    assert "bad.txt" in str(info.value)


def test_unreadable_mesh_names_the_file(tmp_path):
    path = tmp_path / "broken.glb"
    path.write_bytes(b"\x00garbage" * 10)
    with pytest.raises(shapes.ShapeError, match=r"broken\.glb"):
        shapes.load(path)
    with pytest.raises(shapes.ShapeError, match="no such mesh file"):
        shapes.load(tmp_path / "missing.obj")
    with pytest.raises(shapes.ShapeError, match="unknown mesh format"):
        shapes.load(path, file_format="vrml")


def test_write_obj_round_trip(tmp_path):
    model = primitives.box_wing(subdivisions=2)
    path = tmp_path / "bw.obj"
    shapes.write_obj(model, path)
    loaded = shapes.load(path)
    assert sorted(loaded.group_names) == sorted(model.group_names)
    np.testing.assert_array_equal(loaded.vertices, model.vertices)
    for group in model.group_names:
        original = model.faces[model.group_index == model.group_names.index(group)]
        again = loaded.faces[loaded.group_index == loaded.group_names.index(group)]
        np.testing.assert_array_equal(again, original)
    # km files keep their unit
    km = primitives.ellipsoid((300.0, 200.0, 100.0), 1).replace(unit="km")
    shapes.write_obj(km, tmp_path / "e.obj")
    back = shapes.load(tmp_path / "e.obj", unit="km")
    np.testing.assert_allclose(back.vertices, km.vertices, rtol=1e-15)
    first_vertex = (tmp_path / "e.obj").read_text().splitlines()[1]
    assert abs(float(first_vertex.split()[1])) < 1.0  # written in km
