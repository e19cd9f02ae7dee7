"""The identifiability study's core on one arc: the benchmark's draw, the true state in the
principal frame and the description of a fit."""

import numpy as np

from benchmarks import joint_identifiability as study
from benchmarks.shape_recovery import _true_material
from lightcurve.analysis.egi import FitEpochs, fit_egi
from lightcurve.analysis.egi.search import frame_free_angles


def test_the_true_state_reproduces_the_draw_and_is_described_exactly():
    case = study.geo_joint_case("box_3x2x1", 0, 34)
    arc = case["arc"]
    seconds = (arc.mjd - arc.mjd[0]) * 86400.0
    q = study.true_state(case).attitudes(seconds)
    truth = arc.table[["q1", "q2", "q3", "q4"]].to_numpy()
    assert np.max(frame_free_angles(truth, q)) < 0.01
    fit = fit_egi(FitEpochs.from_observations([arc], [q]), _true_material(), normals=300)
    row = study.describe(case, q, fit)
    assert row["attitude_error_deg"] < 0.01 and row["alignment"] == "direct"
    assert row["chi2_per_epoch"] == fit.chi2 / len(arc)
    assert row["heldout_ratio"] > 0.5
