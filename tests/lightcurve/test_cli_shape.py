"""`lightcurve shape`: the documented outputs, the `shapes add` round trip, bad input."""

import json

import numpy as np
import pytest

from lightcurve.cli import main
from shapes import get_library, material, primitives

from ._egi import known_attitude_file

SUMMARY_KEYS = {
    "method",
    "attitude_source",
    "residual_rms_mag",
    "n_facets",
    "material",
    "scale_note",
    "axis_ratios",
    "axis_ratio_sigma",
}


@pytest.fixture(autouse=True)
def _no_library_env(monkeypatch):
    monkeypatch.delenv("LIGHTCURVE_LIBRARY", raising=False)


@pytest.fixture(scope="module")
def box_file(tmp_path_factory):
    box = primitives.box(
        (3.0, 2.0, 1.0), materials={"body": material.Material("lambert", {"rd": 0.3})}
    )
    return known_attitude_file(box, tmp_path_factory.mktemp("data") / "box.csv", epochs=300, seed=7)


def _run(capsys, *argv):
    code = main(list(map(str, argv)))
    out, err = capsys.readouterr()
    return code, out, err


def test_shape_writes_the_documented_outputs_and_shapes_add_takes_them(box_file, tmp_path, capsys):
    out = tmp_path / "fit"
    code, stdout, _ = _run(
        capsys,
        "shape", box_file, "--out", out, "--attitude", "truth",
        "--brdf", "lambert", "--param", "rd=0.3", "--normals", "600", "--bootstrap", "3",
    )  # fmt: skip
    assert code == 0, stdout
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary) >= SUMMARY_KEYS
    assert summary["method"] == "egi" and summary["attitude_source"] == "truth"
    assert summary["material"] == {"brdf": "lambert", "params": {"rd": 0.3}}
    assert summary["residual_rms_mag"] < 1.3 * 0.02
    assert summary["axis_ratios"]["a/b"] == pytest.approx(1.5, rel=0.05)
    assert summary["axis_ratios"]["b/c"] == pytest.approx(2.0, rel=0.05)
    assert summary["axis_ratio_sigma"]["a/b"] > 0
    # random attitudes see every side: the fewest faces the data need, the box's six
    assert summary["faces"]["mode"] == "auto"
    assert summary["faces"]["kept_facets"] == 6 < summary["faces"]["fitted_facets"]
    for name in ("shape.obj", "fit.png", "egi.csv", "fit.csv"):
        assert (out / name).is_file()
    assert "principal frame" in (out / "shape.obj").read_text()
    library = tmp_path / "lib"
    params = [f"--param={k}={v}" for k, v in summary["material"]["params"].items()]
    code, _, err = _run(
        capsys, "shapes", "add", "found", out / "shape.obj", "--library", library,
        "--brdf", summary["material"]["brdf"], *params,
    )  # fmt: skip
    assert code == 0, err
    model = get_library(library).load("found")
    assert model.area == pytest.approx(summary["surface_area_m2"], rel=1e-6)
    assert np.allclose(model.center_of_mass, 0.0, atol=1e-6)


def test_faces_all_keeps_every_fitted_facet(box_file, tmp_path, capsys):
    out = tmp_path / "fit"
    code, _, err = _run(
        capsys, "shape", box_file, "--out", out, "--attitude", "truth", "--brdf", "lambert",
        "--param", "rd=0.3", "--normals", "300", "--bootstrap", "0", "--faces", "all",
    )  # fmt: skip
    assert code == 0, err
    faces = json.loads((out / "summary.json").read_text())["faces"]
    assert faces["mode"] == "all"
    assert faces["kept_facets"] == faces["fitted_facets"] > 6


def test_fitted_material_is_a_registry_model(box_file, tmp_path, capsys):
    out = tmp_path / "fit"
    code, _, err = _run(
        capsys, "shape", box_file, "--out", out, "--attitude", "truth", "--brdf", "phong",
        "--normals", "300", "--bootstrap", "0", "--albedo", "0.3",
    )  # fmt: skip
    assert code == 0, err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["material"]["brdf"] == "phong"
    assert set(summary["material"]["params"]) == {"rd", "rs", "n"}
    assert "rd = 0.3 assumed" in summary["scale_note"]


def test_bad_input_gets_one_line(box_file, tmp_path, capsys):
    geometry_only = tmp_path / "plain.csv"
    text = box_file.read_text().splitlines()
    header = text[0].split(",")
    keep = [
        i for i, name in enumerate(header) if name not in {"q1", "q2", "q3", "q4", "wx", "wy", "wz"}
    ]
    geometry_only.write_text(
        "\n".join(",".join(line.split(",")[i] for i in keep) for line in text) + "\n"
    )
    cases = [
        (("shape", geometry_only, "--attitude", "truth"), "needs the truth columns q1..q4"),
        (("shape", box_file, "--attitude", "truth", "--normals", "9000"), "cannot support"),
        (("shape", box_file, "--attitude", "truth", "--brdf", "lambert", "--param", "rd=1.5"),
         "outside its valid range"),
        (("shape", box_file, "--attitude", tmp_path / "nothing"), "neither 'truth' nor"),
    ]  # fmt: skip
    for argv, message in cases:
        code, _, err = _run(capsys, *argv, "--out", tmp_path / "o")
        assert code == 2
        assert message in err
        assert len(err.strip().splitlines()) == 1
    other = tmp_path / "res" / "box"
    other.mkdir(parents=True)
    (other / "summary.json").write_text(json.dumps({"input": "elsewhere.csv", "status": "ok"}))
    (other / "estimates.parquet").write_bytes(b"")
    code, _, err = _run(capsys, "shape", box_file, "--attitude", other, "--out", tmp_path / "o")
    assert code == 2 and "the result of another file (elsewhere.csv)" in err
