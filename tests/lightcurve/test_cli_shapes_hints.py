"""`shapes add` and `shapes list` tell a user what to do next: the `--param` a BRDF needs, how
to start a library in an empty folder."""

from lightcurve.cli import main

TETRAHEDRON = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"


def test_a_missing_brdf_parameter_names_the_option_to_pass(tmp_path, capsys):
    mesh, library = tmp_path / "tetra.obj", tmp_path / "library"
    mesh.write_text(TETRAHEDRON)
    command = ["shapes", "add", "tetra", str(mesh), "--library", str(library)]
    assert main([*command, "--brdf", "lommel-seeliger", "--param", "w=0.5"]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1
    assert error.rstrip().endswith("needs parameter(s) c: give them, e.g. --param c=0.1")
    assert not (library / "manifest.json").exists()
    assert main([*command, "--brdf", "lommel-seeliger", "--param", "c=0.1"]) == 0


def test_listing_a_folder_that_holds_no_library_says_how_to_start_one(tmp_path, capsys):
    missing = tmp_path / "shapes"
    assert main(["shapes", "list", "--library", str(missing)]) == 0
    out = capsys.readouterr().out
    assert "0 shapes" in out
    assert f"no library there yet: `lightcurve shapes add NAME MESH --library {missing}`" in out
    assert not missing.exists()
