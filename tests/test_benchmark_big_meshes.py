"""The big-mesh benchmark's core on tiny cases: the accuracy of both table builds against
exact ray casting, the build-time ratio to the former build, and the proxy record read back."""

import shapes.library.core as library_core
from benchmarks.big_meshes import accuracy, build_ratio, proxy_row
from benchmarks.shapes import bumpy_sphere
from shapes import ShapeLibrary, primitives


def test_accuracy_compares_both_builds_with_exact_ray_casting():
    compiled = bumpy_sphere(1).compiled()
    row = accuracy(compiled, 60, resolution=6, samples=4)
    assert row["directions"] == 60 and row["sample_points"] > 0
    for label in ("refined", "every_ray"):
        figures = row[label]
        assert 0.0 <= figures["joint_mean_abs_error"] <= figures["joint_p99_abs_error"] <= 1.0
        assert 0.0 <= figures["mean_abs_error"] < 0.2
    assert 0.0 <= row["differing_bits"] < 0.01


def test_build_ratio_times_both_builds():
    row = build_ratio(bumpy_sphere(1).compiled())
    assert row["every_ray_one_thread_seconds"] > 0 and row["refined_seconds"] > 0
    assert row["speed_up"] > 0
    assert 0.0 <= row["differing_bits"] < 0.01


def test_proxy_row_reads_the_proxy_record(tmp_path, monkeypatch):
    monkeypatch.setattr(library_core, "PROXY_MIN_FACETS", 1000)
    library = ShapeLibrary(tmp_path / "lib")
    error = {"max_mag": 0.02, "geometries": 90, "seed": 4, "max_phase_deg": 120.0}

    def meter(model, proxy):
        return {"rms_mag": 8.0 / len(proxy.faces), **error, "shadows": "none"}

    library.add_model("ball", primitives.icosphere(1.0, subdivisions=4), proxy_meter=meter)
    row = proxy_row(library.path, "ball")
    assert row["shape"] == "ball" and row["facets"] == 5120
    assert row["proxy_rms_mag"] == 8.0 / row["proxy_facets"] <= 0.01
    assert row["proxy_max_mag"] == 0.02 and row["proxy_geometries"] == 90
    assert row["proxy_seed"] == 4 and row["proxy_shadows"] == "none"
