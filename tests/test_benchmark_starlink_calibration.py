"""The Starlink calibration benchmark runs end to end on a thinned set."""

import json

from benchmarks import starlink_calibration


def test_the_benchmark_reports_every_parameter_set(capsys):
    sets = "offset,offset_array,lobes"
    argv = ["--every", "30", "--folds", "2", "--splits", "1", "--sets", sets, "--starts", "2"]
    starlink_calibration.main(argv)
    report = json.loads(capsys.readouterr().out)
    assert set(report["parameter_sets"]) == set(sets.split(","))
    for entry in report["parameter_sets"].values():
        assert entry["cv_rms_mag"] > 0.0
        assert len(entry["per_fold"]) == 2
    # the offset alone removes the unfitted prediction's mean
    offset = report["parameter_sets"]["offset"]
    assert abs(offset["cv_bias_mag"]) < 0.5 * abs(report["unfitted_prediction"]["mean_mag"])
