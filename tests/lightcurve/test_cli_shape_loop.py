"""The analyst's loop on an object outside the library: MMAE finds no candidate that fits,
`lightcurve shape` recovers a convex shape, `shapes add` files it, and MMAE picks it."""

import json
import shutil

import pytest

from lightcurve.cli import main
from shapes import builtin_library_path, primitives, write_obj

MATERIAL = [
    "--brdf",
    "ashikhmin-shirley",
    *(f"--param={p}" for p in ("rd=0.35", "rs=0.25", "nu=40", "nv=40")),
]
CANDIDATES = "box"


@pytest.fixture(autouse=True)
def _no_library_env(monkeypatch):
    monkeypatch.delenv("LIGHTCURVE_LIBRARY", raising=False)


def _run(*argv) -> None:
    assert main([str(a) for a in argv]) == 0


def _mmae(observed, library, shapes, out):
    _run(
        "invert",
        observed,
        "--library",
        library,
        "--shapes",
        shapes,
        "--method",
        "mmae",
        "--omega-max",
        "1.5",
        "--out",
        out,
        "-q",
    )
    return json.loads((out / observed.stem / "summary.json").read_text())


def test_mmae_picks_the_recovered_shape_after_none_fits(tmp_path):
    write_obj(primitives.cylinder(1.0, 3.0, sections=3, name="prism"), tmp_path / "prism.obj")
    truth, library = tmp_path / "truth", tmp_path / "library"
    shutil.copytree(builtin_library_path(), library)
    _run("shapes", "add", "prism", tmp_path / "prism.obj", "--library", truth, *MATERIAL, "-q")
    geometry, observed = tmp_path / "geo.csv", tmp_path / "prism_night.csv"
    _run(
        "geometry",
        "--geo",
        "-100",
        "--site",
        "32.44,-110.79,2790",
        "--start",
        "2024-01-15T05:00:00",
        "--duration",
        "1200",
        "--cadence",
        "6",
        "--out",
        geometry,
        "-q",
    )
    _run(
        "simulate",
        geometry,
        "--library",
        truth,
        "--shape",
        "prism",
        "--q0",
        "0.3,0.5,-0.2,0.787",
        "--omega0",
        "0.6,-0.9,0.4",
        "--noise-mag",
        "0.03",
        "--seed",
        "3",
        "--shadows",
        "none",
        "--out",
        observed,
        "-q",
    )
    first = _mmae(observed, library, CANDIDATES, tmp_path / "first")
    assert first["none_fits"]
    _run(
        "shape",
        observed,
        "--attitude",
        "truth",
        *MATERIAL,
        "--normals",
        "500",
        "--bootstrap",
        "0",
        "--out",
        tmp_path / "found",
        "-q",
    )
    _run(
        "shapes",
        "add",
        "found",
        tmp_path / "found" / "shape.obj",
        "--library",
        library,
        *MATERIAL,
        "-q",
    )
    second = _mmae(observed, library, CANDIDATES + ",found", tmp_path / "second")
    assert second["shape"] == "found"
    assert second["shape_probabilities"]["found"] >= 0.9
    assert not second["none_fits"]
