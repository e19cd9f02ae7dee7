"""`shapes add --brdf KIND` without a required parameter says which `--param` to pass."""

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
