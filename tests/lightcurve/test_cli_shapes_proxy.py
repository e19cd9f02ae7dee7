"""`shapes add` builds the level-of-detail proxy of a big mesh and records its error (`shapes
list` and `show` print it); `invert` renders the proxy when its error is below the file's
noise and says so under `shape_model`, `--full-mesh` forces the full mesh."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from lightcurve import io
from lightcurve.cli import main
from lightcurve.photometry.simulate import GaussianNoise, simulate
from lightcurve.pipeline import candidate_model
from lightcurve.sky.ephemeris import CircularOrbit, Site, orbit_geometry
from shapes import ShapeLibrary, primitives
from shapes.io import write_obj

START_MJD = 60379.2  # night at Mount Lemmon
Q0 = np.array([0.2, -0.1, 0.3, 0.927]) / np.linalg.norm([0.2, -0.1, 0.3, 0.927])
OMEGA0_DEG_S = np.array([0.8, -0.5, 1.2])


@pytest.fixture(scope="module")
def library(tmp_path_factory) -> Path:
    """A library with a 5120-facet ellipsoid (convex: its proxy renders without shadows)."""
    folder = tmp_path_factory.mktemp("proxy")
    mesh = folder / "rock.obj"
    write_obj(primitives.ellipsoid((3.0, 2.0, 1.5), subdivisions=4), mesh)
    assert main(["shapes", "add", "rock", str(mesh), "--library", str(folder / "lib")]) == 0
    return folder / "lib"


def test_add_records_the_proxy_and_list_shows_it(library, capsys):
    record = ShapeLibrary(library).info("rock")["proxy"]
    assert record["facets"] < 5120 // 2 and record["rms_mag"] <= 0.01
    assert record["geometries"] > 9000 and record["shadows"] == "none"
    assert (library / record["mesh"]).is_file()
    assert main(["shapes", "list", "--library", str(library)]) == 0
    assert f"{record['facets']} ({record['rms_mag']:.4f} mag rms)" in capsys.readouterr().out
    assert main(["shapes", "show", "rock", "--library", str(library)]) == 0
    assert "level-of-detail proxy: " in capsys.readouterr().out


def test_the_proxy_is_used_only_below_the_noise(library):
    lib = ShapeLibrary(library)
    rms = lib.info("rock")["proxy"]["rms_mag"]
    model, record = candidate_model(lib, "rock", 0.05)
    assert record["proxy"] and len(model.faces) == record["n_facets"] < 5120
    assert record["full_facets"] == 5120 and record["proxy_rms_mag"] == rms
    model, record = candidate_model(lib, "rock", rms / 2)  # data more precise than the proxy
    assert not record["proxy"] and len(model.faces) == 5120
    _, record = candidate_model(lib, "rock", 0.05, full_mesh=True)
    assert not record["proxy"]


def test_invert_summary_names_the_model_used(library, tmp_path):
    mjd = START_MJD + np.arange(30) / 86400.0
    site = Site(32.4434, -110.7881, 2790.0, "Mount Lemmon")
    geometry = orbit_geometry(CircularOrbit.geostationary(-100.0, START_MJD), site, mjd)
    shape = ShapeLibrary(library).load("rock")
    result = simulate(
        geometry, shape, q0=Q0, omega0=np.deg2rad(OMEGA0_DEG_S), noise=GaussianNoise(0.05), seed=2
    )
    io.write(result, tmp_path / "rock.csv")
    argv = ["invert", str(tmp_path / "rock.csv"), "--method", "ukf", "--shape", "rock"]
    argv += ["--library", str(library), "--q0", ",".join(f"{v:.12f}" for v in Q0)]
    argv += ["--omega0", ",".join(map(str, OMEGA0_DEG_S)), "--init", "none"]
    argv += ["--estimate", "none", "-q"]
    for extra, proxy in (([], True), (["--full-mesh"], False)):
        out = tmp_path / f"out{proxy}"
        assert main([*argv, "--out", str(out), *extra]) == 0
        summary = json.loads((out / "rock" / "summary.json").read_text())
        assert summary["status"] == "ok", summary
        assert summary["shape_model"]["name"] == "rock"
        assert summary["shape_model"]["proxy"] is proxy
        assert summary["shape_model"]["noise_mag"] == pytest.approx(0.05)
