"""Level-of-detail proxies: quadric decimation keeps groups, materials and mass properties; the
facet count doubles until the error passes; the library stores the proxy and its error with
the shape, loads it back, and refuses a changed proxy file."""

from __future__ import annotations

import json

import numpy as np
import pytest

import shapes.library.core as library_core
from shapes import ShapeError, ShapeLibrary, primitives
from shapes.library.proxy import choose_proxy, decimate


def _error(rms: float) -> dict:
    return {"rms_mag": rms, "max_mag": 3 * rms, "geometries": 100, "seed": 1,
            "max_phase_deg": 120.0, "shadows": "none"}  # fmt: skip


def _meter(model, proxy) -> dict:
    """An error falling with the proxy's facet count (passes from 1200 facets)."""
    return _error(12.0 / len(proxy.faces))


def test_decimation_keeps_the_body():
    sphere = primitives.icosphere(2.0, subdivisions=4)  # 5120 facets
    proxy = decimate(sphere, 320)
    assert 300 <= len(proxy.faces) <= 340
    assert proxy.is_convex and proxy.is_watertight
    assert proxy.group_names == sphere.group_names and proxy.materials == sphere.materials
    np.testing.assert_allclose(proxy.inertia, sphere.inertia)
    assert proxy.volume == pytest.approx(sphere.volume, rel=0.03)  # inscribed: a bit smaller
    assert proxy.volume < sphere.volume


def test_decimation_of_several_groups_keeps_each_group():
    model = primitives.cylinder(1.0, 2.0, sections=256)  # side and ends
    proxy = decimate(model, len(model.faces) // 4)
    assert proxy.group_names == model.group_names
    for k in range(len(model.group_names)):
        assert (
            0 < np.count_nonzero(proxy.group_index == k) < np.count_nonzero(model.group_index == k)
        )


def test_decimation_of_thin_plates_drops_collapsed_facets():
    """A box-wing's solar arrays are single sheets: collapsed edges leave zero-area facets,
    which the proxy drops (it stays a valid mesh with every group)."""
    wing = primitives.box_wing(subdivisions=8)
    proxy = decimate(wing, 768)
    assert len(proxy.faces) <= 800 and proxy.group_names == wing.group_names
    assert proxy.areas.min() > 0.0


def test_bad_facet_count_and_tolerance_are_refused():
    sphere = primitives.icosphere(1.0, subdivisions=2)
    with pytest.raises(ShapeError, match="at least 4 facets"):
        decimate(sphere, 3)
    with pytest.raises(ShapeError, match="tolerance must be positive"):
        choose_proxy(sphere, _meter, tolerance_mag=0.0)


def test_the_count_doubles_until_the_error_passes():
    sphere = primitives.icosphere(1.0, subdivisions=4)
    proxy, error = choose_proxy(sphere, _meter, start=320)
    assert 1200 <= len(proxy.faces) <= 1280  # the hull of the 1280-facet decimation
    assert error["rms_mag"] == pytest.approx(12.0 / len(proxy.faces))
    # a proxy needing more than half the facets is not worth it
    assert choose_proxy(sphere, lambda m, p: _error(1.0), start=320) is None


def test_the_library_stores_and_checks_the_proxy(tmp_path, monkeypatch):
    monkeypatch.setattr(library_core, "PROXY_MIN_FACETS", 1000)
    library = ShapeLibrary(tmp_path / "lib")
    sphere = primitives.icosphere(1.0, subdivisions=4)
    library.add_model("ball", sphere, proxy_meter=_meter)
    record = library.info("ball")["proxy"]
    assert 1200 <= record["facets"] <= 1536 and record["visibility"] is None
    assert record["rms_mag"] == pytest.approx(12.0 / record["facets"])
    proxy = library.load_proxy("ball")
    assert len(proxy.faces) == record["facets"] and proxy.name == "ball"
    np.testing.assert_allclose(proxy.inertia, library.load("ball").inertia)
    small = primitives.icosphere(1.0, subdivisions=2)  # 320 facets: no proxy
    library.add_model("pebble", small, proxy_meter=_meter)
    assert "proxy" not in library.info("pebble") and library.load_proxy("pebble") is None
    proxy_file = library.path / record["mesh"]
    proxy_file.write_text(proxy_file.read_text() + "\n")
    with pytest.raises(ShapeError, match=r"proxy of shape 'ball'.*sha256 mismatch"):
        library.load_proxy("ball")
    with pytest.raises(ShapeError, match=r"proxy of shape 'ball'.*sha256 mismatch"):
        library.validate("ball")
    library.remove("ball")
    assert not proxy_file.exists()


def test_a_malformed_proxy_record_is_named(tmp_path, monkeypatch):
    monkeypatch.setattr(library_core, "PROXY_MIN_FACETS", 1000)
    library = ShapeLibrary(tmp_path / "lib")
    library.add_model("ball", primitives.icosphere(1.0, subdivisions=4), proxy_meter=_meter)
    manifest = library.path / "manifest.json"
    data = json.loads(manifest.read_text())
    data["shapes"]["ball"]["proxy"]["rms_mag"] = "small"
    manifest.write_text(json.dumps(data))
    with pytest.raises(ShapeError, match=r"proxy of shape 'ball': field 'rms_mag' must be a"):
        library.proxy_info("ball")


def test_rebuild_chooses_the_proxy_again_with_the_new_table(tmp_path, monkeypatch):
    """Rebuilding a shape's table chooses and measures its proxy again (here the meter is
    more lenient the second time: a smaller proxy passes), with its own table at the
    shape's sampling, and swaps the files."""
    monkeypatch.setattr(library_core, "PROXY_MIN_FACETS", 1000)
    library = ShapeLibrary(tmp_path / "lib")
    wing = primitives.box_wing(subdivisions=12)  # 6336 facets, not convex
    small = {"resolution": 4, "samples": 4, "spacing": 0.2}
    library.add_model("wing", wing, proxy_meter=_meter, **small)
    before = library.info("wing")["proxy"]
    assert before["facets"] > 1200 and before["visibility"] == "wing.proxy.visibility.npz"
    model = library.rebuild_visibility("wing", proxy_meter=lambda m, p: _error(6.0 / len(p.faces)))
    after = library.info("wing")["proxy"]
    assert model.visibility.resolution == 4
    assert after["facets"] < 1000 and after["rms_mag"] == pytest.approx(6.0 / after["facets"])
    proxy = library.load_proxy("wing")
    assert len(proxy.faces) == after["facets"] and proxy.visibility.resolution == 4
    assert after["visibility_sha256"] != before["visibility_sha256"]
    assert sorted(p.name for p in library.path.iterdir() if p.name.startswith(("wing", "."))) == [
        ".manifest.lock", "wing.obj", "wing.proxy.obj", "wing.proxy.visibility.npz",
        "wing.visibility.npz",
    ]  # fmt: skip
    library.validate("wing")
