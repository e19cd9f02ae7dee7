"""The big-mesh benchmark's core on tiny cases: the accuracy of both table builds against
exact ray casting, and the build-time ratio to the former build."""

from benchmarks.big_meshes import accuracy, build_ratio
from benchmarks.shapes import bumpy_sphere


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
