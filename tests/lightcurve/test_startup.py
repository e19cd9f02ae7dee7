"""Start-up cost of the command line: heavy packages load only for the commands that use
them (each check runs in a fresh interpreter and reads ``sys.modules``)."""

import dataclasses
import importlib
import json
import subprocess
import sys

import pytest

from lightcurve.commands._source import dataclass_fields, literal
from lightcurve.photometry.noise import CCDNoise

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
    assert "trimesh" not in _loaded("import shapes, shapes.files, lightcurve.io.atomic")
    assert "trimesh" not in _loaded("from shapes import FacetModel, write_obj")


@pytest.mark.parametrize("command", ["", "convex", "simulate", "import", "shapes", "invert"])
def test_help_builds_the_parser_only(command):
    code = (
        "import contextlib, io\nfrom lightcurve.cli import main\n"
        "with contextlib.redirect_stdout(io.StringIO()), contextlib.suppress(SystemExit):\n"
        f"    main({[*([command] if command else []), '--help']!r})"
    )
    assert _loaded(code) == set()


@pytest.mark.parametrize(
    ("module", "name"),
    [
        ("lightcurve.photometry.profiles", "PROFILES"),
        ("lightcurve.photometry.profiles", "STABILISED_PROFILES"),
        ("lightcurve.photometry.render", "SHADOW_MODES"),
        ("lightcurve.sky.epochs", "TIME_FORMATS"),
        ("lightcurve.sky.epochs", "TIME_SCALES"),
        ("lightcurve.io.tables", "DELIMITERS"),
    ],
)
def test_constants_read_from_source_equal_the_imported_ones(module, name):
    assert literal(module, name) == getattr(importlib.import_module(module), name)


def test_dataclass_fields_read_from_source_equal_the_imported_ones():
    fields = tuple(field.name for field in dataclasses.fields(CCDNoise))
    assert dataclass_fields("lightcurve.photometry.noise", "CCDNoise") == fields


def test_missing_constants_are_named():
    with pytest.raises(LookupError, match="render has no literal assignment to NOPE"):
        literal("lightcurve.photometry.render", "NOPE")
    with pytest.raises(LookupError, match="defines no class Nope"):
        dataclass_fields("lightcurve.photometry.noise", "Nope")


def test_convex_fit_from_a_damit_file_loads_neither_pandas_nor_scipy_spatial():
    code = (
        "from lightcurve.analysis.convex import ConvexSettings, Photometry, fit\n"
        "from lightcurve.analysis.spin import SpinState\n"
        "d = Photometry.read(['data/ariadne/test_lcs_rel'])\n"
        "s = ConvexSettings(nrows=2, degree=2, order=2, max_iter=1)\n"
        "fit(d, SpinState.from_degrees(220.0, 0.0, 5.76198), s)"
    )
    assert _loaded(code) == {"numba"}
