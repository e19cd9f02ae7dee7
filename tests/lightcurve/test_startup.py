"""Start-up cost of the command line: heavy packages load only for the commands that use
them (each check runs in a fresh interpreter and reads ``sys.modules``)."""

import json
import subprocess
import sys

import pytest

#: Packages that take a large part of a second or more to import.
HEAVY = ("pandas", "trimesh", "torch", "matplotlib", "scipy.spatial", "scipy.optimize", "numba")


def _loaded(code: str) -> set[str]:
    """The heavy packages in ``sys.modules`` after running ``code`` in a new interpreter."""
    probe = (
        f"{code}\nimport json, sys\nprint(json.dumps([m for m in {HEAVY!r} if m in sys.modules]))"
    )
    result = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, check=True
    )
    return set(json.loads(result.stdout.splitlines()[-1]))


def test_convex_command_module_loads_no_heavy_package():
    assert _loaded("import lightcurve.commands.convex") == set()


def test_light_shape_modules_do_not_load_trimesh():
    assert "trimesh" not in _loaded("import shapes, shapes.files, lightcurve.atomic")
    assert "trimesh" not in _loaded("from shapes import FacetModel, write_obj")


@pytest.mark.parametrize("command", ["", "convex"])
def test_help_builds_the_parser_only(command):
    code = (
        "import contextlib, io\nfrom lightcurve.cli import main\n"
        "with contextlib.redirect_stdout(io.StringIO()), contextlib.suppress(SystemExit):\n"
        f"    main({[*([command] if command else []), '--help']!r})"
    )
    assert _loaded(code) == set()
