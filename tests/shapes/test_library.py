"""The shape library: built-in contents, manifest, add/remove safety, checksums."""

import json
import os
from pathlib import Path

import numpy as np
import pytest

import shapes
from shapes import primitives
from shapes.files import file_sha256
from shapes.library import LibraryReadOnlyError, ShapeLibrary, builtin_library_path, check_name

BUILTIN = [
    "bennu",
    "box",
    "box_wing",
    "box_wing_tracking",
    "cube",
    "cylinder",
    "itokawa",
    "plate",
    "rocket_body",
    "starlink_v1_5",
]


def _snapshot(folder):
    """File name → sha256 of every file in a folder (the lock file excluded)."""
    return {
        p.name: file_sha256(p)
        for p in sorted(folder.iterdir())
        if p.is_file() and p.name != ".manifest.lock"
    }


@pytest.fixture(scope="module")
def builtin():
    return shapes.ShapeLibrary(builtin_library_path(), read_only=True)


def test_builtin_library_contents(builtin):
    assert builtin.names() == BUILTIN
    assert builtin_library_path() == Path(shapes.__file__).parent / "data"  # package data
    assert (builtin_library_path() / "LICENSE-SBGAT.md").is_file()
    for name in BUILTIN:
        entry = builtin.info(name)
        assert entry["sha256"] == file_sha256(builtin.path / entry["mesh"])
        assert {"source", "license", "added"} <= set(entry["provenance"])
        assert entry["inertia"]["source"] in ("solid", "shell", "given")
        assert set(entry["materials"]) == set(entry["groups"])
    for asteroid in ("itokawa", "bennu"):
        entry = builtin.info(asteroid)
        assert entry["unit"] == "km" and "SBGAT" in entry["provenance"]["license"]
        assert {m["brdf"] for m in entry["materials"].values()} == {"lommel-seeliger"}
    assert builtin.info("itokawa")["sha256"] == file_sha256(builtin.path / "itokawa.obj")


def test_builtin_shapes_load_with_realistic_sizes(builtin):
    wing = builtin.load("box_wing")
    assert np.ptp(wing.vertices[:, 1]) == pytest.approx(15.5)
    assert wing.inertia_source == "given" and wing.visibility is not None
    assert wing.materials["bus"].brdf == "ashikhmin-shirley"
    assert wing.materials["solar_array"].params["nu"] >= 500  # strong specular lobe
    itokawa = builtin.load("itokawa")
    assert itokawa.unit == "km" and 500 < np.ptp(itokawa.vertices[:, 0]) < 600  # metres
    assert itokawa.mass == pytest.approx(3.51e10)
    assert not itokawa.is_convex and itokawa.visibility is not None
    cube = builtin.load("cube")
    assert cube.is_convex and cube.visibility is None
    assert cube.mass == pytest.approx(100.0)
    np.testing.assert_allclose(np.diag(cube.inertia), 100.0 / 6)
    rocket = builtin.load("rocket_body")
    assert rocket.inertia_source == "shell" and rocket.mass == pytest.approx(9000.0)


def test_builtin_library_is_read_only(builtin, tmp_path):
    before = _snapshot(builtin.path)
    with pytest.raises(LibraryReadOnlyError, match="read-only"):
        builtin.add("x", builtin.path / "cube.obj")
    with pytest.raises(LibraryReadOnlyError):
        builtin.remove("cube")
    assert _snapshot(builtin.path) == before
    assert shapes.get_library(builtin_library_path()).read_only


def test_get_library_honours_environment(monkeypatch, tmp_path):
    monkeypatch.delenv("LIGHTCURVE_LIBRARY", raising=False)
    assert shapes.get_library().read_only
    monkeypatch.setenv("LIGHTCURVE_LIBRARY", str(tmp_path))
    library = shapes.get_library()
    assert library.path == tmp_path and not library.read_only
    assert library.names() == []


@pytest.mark.parametrize("name", ["../x", "a/b", ".", "..", "", "a b", "x\\y", "é"])
def test_bad_names(name):
    with pytest.raises(shapes.ShapeError, match="invalid shape name"):
        check_name(name)


def test_add_load_remove_round_trip(tmp_path):
    library = ShapeLibrary(tmp_path / "lib")
    wing = primitives.box_wing(subdivisions=2)
    stored = library.add_model(
        "wing.v2", wing, provenance={"license": "CC0"}, samples=16, spacing=0.0
    )
    assert library.names() == ["wing.v2"]
    entry = library.info("wing.v2")
    assert entry["provenance"]["license"] == "CC0" and entry["visibility"]
    loaded = library.load("wing.v2")
    np.testing.assert_array_equal(loaded.vertices, stored.vertices)
    np.testing.assert_allclose(loaded.inertia, wing.inertia, rtol=1e-12)
    assert loaded.compiled().visibility is not None
    assert len(loaded.compiled()) == 14
    library.validate("wing.v2")
    with pytest.raises(shapes.ShapeError, match="already exists"):
        library.add_model("wing.v2", wing)
    library.remove("wing.v2")
    assert library.names() == []
    assert _snapshot(library.path) == {"manifest.json": file_sha256(library.manifest_path)}
    with pytest.raises(shapes.ShapeError, match=r"no shape 'wing\.v2'"):
        library.remove("wing.v2")


def test_add_mesh_file_with_units_inertia_and_force(tmp_path):
    library = ShapeLibrary(tmp_path)
    source = tmp_path / "src.stl"
    primitives.box((2.0, 1.0, 1.0)).mesh.export(source)
    model = library.add("rock", source, unit="km", mass=5.0)
    assert model.volume == pytest.approx(2e9) and model.mass == pytest.approx(5.0)
    assert library.info("rock")["provenance"]["source_sha256"] == file_sha256(source)
    given = [3.0, 4.0, 5.0]
    replaced = library.add("rock", source, inertia=given, force=True)
    assert replaced.inertia_source == "given"
    np.testing.assert_allclose(library.load("rock").inertia, np.diag(given))
    assert library.info("rock")["unit"] == "m"


def test_failed_add_leaves_library_unchanged(tmp_path, monkeypatch):
    library = ShapeLibrary(tmp_path)
    library.add_model("cube", primitives.box())
    before = _snapshot(tmp_path)
    bad = tmp_path / "bad.obj"
    bad.write_text("v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n")
    with pytest.raises(shapes.ShapeError, match="non-finite"):
        library.add("bad", bad)
    bad.unlink()

    # a failure while writing the manifest rolls the replaced files back
    def broken(manifest):
        raise OSError("disk full")

    monkeypatch.setattr(library, "_write_manifest", broken)
    with pytest.raises(OSError, match="disk full"):
        library.add_model("cube", primitives.box((2.0, 2.0, 2.0)), force=True)
    assert _snapshot(tmp_path) == before
    assert library.load("cube").volume == pytest.approx(1.0)


def test_changed_mesh_is_detected(tmp_path):
    library = ShapeLibrary(tmp_path)
    library.add_model("cube", primitives.box())
    with open(tmp_path / "cube.obj", "a") as handle:
        handle.write("# edited\n")
    with pytest.raises(shapes.ShapeError, match="changed since it was added"):
        library.load("cube")
    with pytest.raises(shapes.ShapeError, match="changed since it was added"):
        library.validate("cube")


def test_missing_table_is_built_and_cached(tmp_path):
    library = ShapeLibrary(tmp_path)
    library.add_model("wing", primitives.box_wing(), samples=4, spacing=0.0)
    manifest = json.loads(library.manifest_path.read_text())
    os.remove(tmp_path / manifest["shapes"]["wing"]["visibility"])
    manifest["shapes"]["wing"]["visibility"] = None
    library.manifest_path.write_text(json.dumps(manifest))
    with pytest.raises(shapes.ShapeError, match="no visibility table"):
        library.validate("wing")
    model = library.load("wing")
    assert model.visibility is not None
    assert library.info("wing")["visibility"] == "wing.visibility.npz"
    library.validate("wing")


def test_bad_manifest_fields_are_named(tmp_path):
    library = ShapeLibrary(tmp_path)
    library.add_model("cube", primitives.box())
    manifest = json.loads(library.manifest_path.read_text())
    manifest["shapes"]["cube"]["materials"]["body"] = {"brdf": "glossy", "params": {}}
    library.manifest_path.write_text(json.dumps(manifest))
    with pytest.raises(shapes.ShapeError, match=r"shape 'cube'.*group 'body'.*glossy"):
        library.load("cube")
    library.manifest_path.write_text('{"format": "something else"}')
    with pytest.raises(shapes.ShapeError, match="not a shape-library manifest"):
        library.names()
