"""`lightcurve shapes add/show/render` with articulated parts; bad parts leave the library."""

import json

import pytest
from matplotlib.image import imread

from lightcurve.cli import main
from shapes import get_library, primitives, write_obj
from shapes.files import file_sha256

TRACKING = {
    "name": "arrays",
    "groups": ["solar_array", "array_back"],
    "joint": {
        "kind": "sun_tracking",
        "axis": [0, 1, 0],
        "normal": [1, 0, 0],
        "limits_deg": [-120, 120],
        "offset_deg": 5,
    },
}


def _snapshot(folder):
    return {
        p.name: file_sha256(p)
        for p in sorted(folder.iterdir())
        if p.is_file() and p.name != ".manifest.lock"
    }


@pytest.fixture
def wing_obj(tmp_path):
    path = tmp_path / "wing.obj"
    write_obj(primitives.box_wing(), path)
    return path


def _shapes(library, command, *arguments):
    """Exit code of ``lightcurve shapes COMMAND ARGUMENTS… --library LIBRARY``."""
    return main(["shapes", command, *map(str, arguments), "--library", str(library)])


def _parts_file(tmp_path, parts):
    path = tmp_path / "parts.json"
    path.write_text(json.dumps(parts))
    return path


def test_articulated_round_trip_add_show_render(tmp_path, capsys, wing_obj, monkeypatch):
    monkeypatch.delenv("LIGHTCURVE_LIBRARY", raising=False)
    library = tmp_path / "lib"
    parts = _parts_file(tmp_path, [TRACKING])
    assert _shapes(library, "add", "wing", wing_obj, "--parts", parts) == 0
    assert "parts arrays" in capsys.readouterr().out
    stored = get_library(library).articulation("wing")
    assert stored.to_list()[0]["joint"]["limits_deg"] == [-120.0, 120.0]
    assert stored.to_list()[0]["joint"]["offset_deg"] == 5.0
    assert _shapes(library, "show", "wing") == 0
    out = capsys.readouterr().out
    assert "arrays: groups solar_array, array_back; sun_tracking joint about [0, 1, 0]" in out
    assert "limits [-120, 120] deg, offset 5 deg, normal [1, 0, 0]" in out
    png = tmp_path / "wing.png"
    assert _shapes(library, "render", "wing", "--out", png, "--sun", "0,0,1") == 0
    assert imread(png).shape[2] in (3, 4)
    assert _shapes(library, "render", "wing", "--out", png, "--angle", "arrays=200") == 2
    assert "outside the joint limits" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("joint_or_groups", "message"),
    [
        ({"joint": {**TRACKING["joint"], "axis": [0, 0, 0]}}, "has zero length"),
        ({"joint": {"kind": "telescopic"}}, "unknown joint kind 'telescopic'"),
        ({"groups": ["solar_array", "wingtip"]}, "names group 'wingtip'"),
    ],
)
def test_bad_parts_give_one_line_errors_and_leave_the_library(
    tmp_path, capsys, wing_obj, joint_or_groups, message
):
    library = tmp_path / "lib"
    assert _shapes(library, "add", "plain", wing_obj) == 0
    before = _snapshot(library)
    capsys.readouterr()
    parts = _parts_file(tmp_path, [{**TRACKING, **joint_or_groups}])
    for name, force in (("wing", []), ("plain", ["--force"])):
        code = _shapes(library, "add", name, wing_obj, "--parts", parts, *force)
        err = capsys.readouterr().err.strip()
        assert code == 2 and message in err and "\n" not in err
        assert _snapshot(library) == before
