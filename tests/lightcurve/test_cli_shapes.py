"""`lightcurve shapes …` through the CLI: round trip, errors, built-ins."""

import contextlib
import io
import shutil

import numpy as np
import pytest
from matplotlib.image import imread

import brdf
from lightcurve.cli import main
from shapes import get_library, material, primitives
from shapes.files import file_sha256
from shapes.library import builtin_library_path


def _snapshot(folder):
    return {
        p.name: file_sha256(p)
        for p in sorted(folder.iterdir())
        if p.is_file() and p.name != ".manifest.lock"
    }


def _run(capsys, *argv):
    code = main(["shapes", *argv])
    out, err = capsys.readouterr()
    return code, out, err


def _l_shape_obj() -> str:
    """An L-shaped (non-convex) OBJ with two groups, in km."""
    a = primitives.box((0.002, 0.001, 0.001))
    tower = a.vertices + np.array([0.0005, 0.001, 0.0])
    lines = [f"v {x} {y} {z}" for x, y, z in np.vstack([a.vertices, tower]).tolist()]
    lines.append("g base")
    lines += [f"f {i + 1} {j + 1} {k + 1}" for i, j, k in a.faces]
    lines.append("g tower")
    lines += [f"f {i + 9} {j + 9} {k + 9}" for i, j, k in a.faces]
    return "\n".join(lines) + "\n"


L_SHAPE_OBJ = _l_shape_obj()


@pytest.fixture
def mesh_file(tmp_path):
    """The L-shaped OBJ in a file."""
    path = tmp_path / "ell.obj"
    path.write_text(L_SHAPE_OBJ)
    return path


@pytest.fixture(autouse=True)
def _no_library_env(monkeypatch):
    monkeypatch.delenv("LIGHTCURVE_LIBRARY", raising=False)


def test_round_trip_add_list_show_render_remove(tmp_path, capsys, mesh_file):
    library = tmp_path / "lib"
    code, out, err = _run(
        capsys,
        "add",
        "ell",
        str(mesh_file),
        "--library",
        str(library),
        "--brdf",
        "ashikhmin-shirley",
        "--param",
        "rd=0.4",
        "--param",
        "rs=0.3",
        "--param",
        "nu=100",
        "--param",
        "nv=100",
        "--units",
        "km",
        "--inertia",
        "10,12,15",
        "--license",
        "CC0",
    )
    assert code == 0, err
    assert "added ell: 24 facets" in out and "visibility table built" in out

    code, out, _ = _run(capsys, "--library", str(library), "list")
    assert code == 0 and "ell" in out and "table" in out

    code, out, _ = _run(capsys, "show", "ell", "--library", str(library))
    assert code == 0
    for text in (
        "facets: 24",
        "base",
        "tower",
        "ashikhmin-shirley(rd=0.4, rs=0.3, nu=100",
        "inertia (given",
        "principal moments",
        "license: CC0",
        "volume: 4 m³",
    ):
        assert text in out

    png = tmp_path / "ell.png"
    code, out, _ = _run(
        capsys, "render", "ell", "--out", str(png), "--view", "1,2,3", "--library", str(library)
    )
    assert code == 0 and png.is_file()
    image = imread(png)[..., :3]
    colours = np.unique((image.reshape(-1, 3) * 255).astype(int), axis=0)
    assert image.std() > 0.05 and len(colours) > 20  # not blank

    code, out, _ = _run(capsys, "remove", "ell", "--library", str(library))
    assert code == 0 and "removed ell" in out
    code, out, _ = _run(capsys, "list", "--library", str(library))
    assert code == 0 and "0 shapes" in out


@pytest.fixture(scope="module")
def library_with_first(tmp_path_factory):
    """A library holding one non-convex shape, "first" (its visibility table built once)."""
    folder = tmp_path_factory.mktemp("first")
    mesh = folder / "ell.obj"
    mesh.write_text(L_SHAPE_OBJ)
    library = folder / "lib"
    with contextlib.redirect_stdout(io.StringIO()):
        assert main(["shapes", "add", "first", str(mesh), "--library", str(library)]) == 0
    return library


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["add", "../x", "MESH"], "invalid shape name '../x'"),
        (["add", "a/b", "MESH"], "invalid shape name 'a/b'"),
        (["add", "good", "MALFORMED"], "malformed.obj"),
        (["add", "first", "MESH"], "already exists"),
        (["add", "new", "MESH", "--brdf", "lamber", "--param", "rd=0.4"], "unknown BRDF"),
        (["add", "new", "MESH", "--brdf", "lambert", "--param", "rd"], "--param"),
        (["add", "new", "MESH", "--brdf", "lambert", "--param", "rd=1.5"], "rd"),
        (["add", "new", "MESH", "--inertia", "1,2"], "--inertia"),
        (["add", "new", "MESH", "--inertia", "1,1,3"], "triangle inequality"),
        (["remove", "nothing"], "no shape 'nothing'"),
        (["show", "nothing"], "no shape 'nothing'"),
        (["render", "first", "--out", "OUT", "--view", "0,0"], "--view"),
    ],
)
def test_errors_are_one_line_and_leave_library_unchanged(
    tmp_path, capsys, mesh_file, library_with_first, argv, message
):
    library = tmp_path / "lib"
    shutil.copytree(library_with_first, library)
    malformed = tmp_path / "malformed.obj"
    malformed.write_text("v 0 0 0\nv 1 0 0\nf 1 2 7\n")
    replace = {"MESH": str(mesh_file), "MALFORMED": str(malformed), "OUT": str(tmp_path / "o.png")}
    before = _snapshot(library)
    code, _, err = _run(capsys, *[replace.get(a, a) for a in argv], "--library", str(library))
    assert code != 0
    lines = err.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], err
    assert lines[0].startswith("lightcurve shapes: error:")
    assert _snapshot(library) == before


@pytest.mark.parametrize("action", [["add", "mine", "MESH"], ["remove", "cube"]])
def test_builtin_library_is_read_only(capsys, mesh_file, action):
    before = _snapshot(builtin_library_path())
    code, _, err = _run(capsys, *[str(mesh_file) if a == "MESH" else a for a in action])
    assert code != 0
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "read-only" in lines[0] and "--library" in lines[0]
    assert _snapshot(builtin_library_path()) == before


def test_environment_selects_the_library(tmp_path, capsys, monkeypatch, library_with_first):
    shutil.copytree(library_with_first, tmp_path / "env")
    monkeypatch.setenv("LIGHTCURVE_LIBRARY", str(tmp_path / "env"))
    code, out, _ = _run(capsys, "list")
    assert code == 0 and str(tmp_path / "env") in out and "first" in out
    code, out, _ = _run(capsys, "remove", "first")  # written to the library the variable names
    assert code == 0 and "removed first" in out
    code, out, _ = _run(capsys, "list", "--library", str(tmp_path / "env"))
    assert code == 0 and "0 shapes" in out


def test_validate_passes_on_every_builtin_shape(capsys):
    code, out, err = _run(capsys, "validate")
    assert code == 0, err
    builtin = ("cube", "box", "plate", "cylinder", "rocket_body", "box_wing", "box_wing_tracking")
    for name in (*builtin, "starlink_v1_5", "itokawa", "bennu"):
        assert f"ok {name}:" in out
    assert "10 of 10 shapes valid" in out


def test_validate_reports_bad_shapes_and_continues(tmp_path, capsys, mesh_file, library_with_first):
    library = tmp_path / "lib"
    shutil.copytree(library_with_first, library)
    assert main(["shapes", "add", "two", str(mesh_file), "--library", str(library)]) == 0
    with open(library / "first.obj", "a") as handle:
        handle.write("# edited\n")
    code, out, err = _run(capsys, "validate", "--library", str(library))
    assert code != 0
    assert "FAILED first" in err and "sha256" in err
    assert "ok two" in out and "1 of 2 shapes valid" in out


def test_shape_materials_match_the_brdf_registry():
    """shapes keeps its own table of BRDF parameter names (it must not import brdf)."""
    assert set(material.BRDF_PARAMETERS) == set(brdf.available())
    for name, (required, optional) in material.BRDF_PARAMETERS.items():
        assert set(required) | set(optional) == set(brdf.describe(name).parameter_names)
    presets = [v for v in vars(material).values() if isinstance(v, material.Material)]
    library = get_library(builtin_library_path())
    shipped = [m for n in library.names() for m in library.load(n).materials.values()]
    assert len(presets) >= 7 and len(shipped) >= 14
    for spec in presets + shipped:
        brdf.get(spec.brdf, **spec.params)  # every default material is in range
