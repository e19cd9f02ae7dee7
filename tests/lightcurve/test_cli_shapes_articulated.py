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


def _parts_file(tmp_path, parts):
    path = tmp_path / "parts.json"
    path.write_text(json.dumps(parts))
    return path


def test_articulated_round_trip_add_show_render(tmp_path, capsys, wing_obj, monkeypatch):
    monkeypatch.delenv("LIGHTCURVE_LIBRARY", raising=False)
    library = tmp_path / "lib"
    parts = _parts_file(tmp_path, [TRACKING])
    assert (
        main(
            [
                "shapes",
                "add",
                "wing",
                str(wing_obj),
                "--library",
                str(library),
                "--parts",
                str(parts),
            ]
        )
        == 0
    )
    assert "parts arrays" in capsys.readouterr().out
    stored = get_library(library).articulation("wing")
    assert stored.to_list()[0]["joint"]["limits_deg"] == [-120.0, 120.0]
    assert stored.to_list()[0]["joint"]["offset_deg"] == 5.0
    assert main(["shapes", "show", "wing", "--library", str(library)]) == 0
    out = capsys.readouterr().out
    assert "arrays: groups solar_array, array_back; sun_tracking joint about [0, 1, 0]" in out
    assert "limits [-120, 120] deg, offset 5 deg, normal [1, 0, 0]" in out
    png = tmp_path / "wing.png"
    assert (
        main(
            [
                "shapes",
                "render",
                "wing",
                "--library",
                str(library),
                "--out",
                str(png),
                "--sun",
                "0,0,1",
            ]
        )
        == 0
    )
    assert imread(png).shape[2] in (3, 4)
    assert (
        main(
            [
                "shapes",
                "render",
                "wing",
                "--library",
                str(library),
                "--out",
                str(png),
                "--angle",
                "arrays=200",
            ]
        )
        == 2
    )
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
    assert main(["shapes", "add", "plain", str(wing_obj), "--library", str(library)]) == 0
    before = _snapshot(library)
    capsys.readouterr()
    parts = _parts_file(tmp_path, [{**TRACKING, **joint_or_groups}])
    for name, force in (("wing", []), ("plain", ["--force"])):
        code = main(
            [
                "shapes",
                "add",
                name,
                str(wing_obj),
                "--library",
                str(library),
                "--parts",
                str(parts),
                *force,
            ]
        )
        err = capsys.readouterr().err.strip()
        assert code == 2 and message in err and "\n" not in err
        assert _snapshot(library) == before
