"""`shapes add --shadows none` skips the visibility table, a later `--shadows table` use says
how to build it, `shapes rebuild` builds it; `-v` prints the build's stage lines and `add`
says what it builds and how long it should take."""

import json
import os
import subprocess
import sys
from pathlib import Path

from lightcurve.cli import main
from shapes import ShapeLibrary, primitives
from shapes.io import write_obj

ROOT = Path(__file__).resolve().parents[2]
GEOMETRY = ROOT / "data" / "geometry" / "geo_mount_lemmon.csv"


def _mesh(tmp_path: Path) -> Path:
    path = tmp_path / "wing.obj"
    write_obj(primitives.box_wing(), path)
    return path


def test_shadows_none_then_table_explains_how_to_build_it(tmp_path, capsys):
    library = tmp_path / "library"
    add = ["shapes", "add", "wing", str(_mesh(tmp_path)), "--library", str(library)]
    assert main([*add, "--shadows", "none"]) == 0
    out = capsys.readouterr()
    assert "no visibility table (`lightcurve shapes rebuild wing` builds it)" in out.out
    assert "building" not in out.err
    entry = json.loads((library / "manifest.json").read_text())["shapes"]["wing"]
    assert entry["visibility"] is None and entry["shadows"] == "none"
    simulate = ["simulate", str(GEOMETRY), "--shape", "wing", "--library", str(library)]
    simulate += ["--profile", "inertial", "--q0", "0,0,0,1", "--out", str(tmp_path / "s.csv")]
    assert main([*simulate, "--shadows", "table"]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1
    assert "shape 'wing' has no visibility table (added with --shadows none)" in error
    assert f"`lightcurve shapes rebuild wing --library {library}`" in error
    assert not (tmp_path / "s.csv").exists()
    assert main(["shapes", "list", "--library", str(library)]) == 0
    assert "none (skipped: shapes rebuild)" in capsys.readouterr().out
    # the table is not built on first use either
    assert main(["shapes", "validate", "--library", str(library)]) == 0
    assert not list(library.glob("*.npz"))
    assert main(["shapes", "rebuild", "wing", "--library", str(library)]) == 0
    assert "rebuilt wing: 4058 directions" in capsys.readouterr().out
    assert "shadows" not in json.loads((library / "manifest.json").read_text())["shapes"]["wing"]
    assert main([*simulate, "--shadows", "table"]) == 0


def test_add_says_what_it_builds(tmp_path, capsys):
    library = tmp_path / "library"
    add = ["shapes", "add", "wing", str(_mesh(tmp_path)), "--library", str(library)]
    assert main(add) == 0
    error = capsys.readouterr().err
    assert "building the visibility table (joint lit and seen) of 6 effective facets" in error
    assert "4058 directions" in error and "(--shadows none skips it)" in error


def test_rebuild_with_v_prints_a_line_per_stage(tmp_path):
    library = ShapeLibrary(tmp_path / "library")
    library.add("wing", _mesh(tmp_path), visibility_table=False, samples=4, spacing=0.0)
    command = [sys.executable, "-m", "lightcurve", "shapes", "rebuild", "wing", "-v"]
    env = {**os.environ, "PYTHONPATH": str(ROOT), "OMP_NUM_THREADS": "1"}
    done = subprocess.run(
        [*command, "--library", str(library.path)], capture_output=True, text=True, env=env
    )
    assert done.returncode == 0, done.stderr
    stages = [line for line in done.stderr.splitlines() if "visibility table: level" in line]
    assert [line.split("level ")[1][:1] for line in stages] == ["0", "1", "2"]
    assert "directions ×" in done.stderr and "% of every point" in done.stderr
    assert "rebuilt wing" in done.stdout
