"""The whole-arc fit of state and model adjustments, on truths that are not the candidate."""

from __future__ import annotations

import math

import numpy as np
import pytest

from benchmarks.inversion_study import Scenario, simulate_run
from filters.attitude import (
    axis_angle_to_quaternion,
    quaternion_multiply,
)
from lightcurve.inversion import shape_symmetry
from lightcurve.inversion.model_fit import fit_arc
from lightcurve.io.observations import Observations
from lightcurve.photometry.adjusted import AdjustableShape
from lightcurve.photometry.measurement import PhotometricModel
from shapes import Material, get_library


class _Truth:
    def __init__(self, q0: np.ndarray, omega0: np.ndarray) -> None:
        self.q0, self.omega0 = q0, omega0


@pytest.fixture(scope="module")
def stretched_box() -> tuple[Observations, object, np.ndarray]:
    """A box 10 % longer, 8 % thinner and of a brighter paint than the library's, 20 min
    at 2 s, 0.03 mag."""
    box = get_library().load("box")
    stretch = np.array([1.10, 0.92, 1.04])  # along the principal axes, ascending moments
    d = (box.principal_axes * stretch) @ box.principal_axes.T
    com = box.center_of_mass
    paint = Material("ashikhmin-shirley", {"rd": 0.26, "rs": 0.45, "nu": 14.0, "nv": 14.0})
    truth_shape = box.replace(vertices=(box.vertices - com) @ d + com).with_materials(paint)
    scenario = Scenario(duration_s=1200.0, cadence_s=2.0, noise_mag=0.03)
    truth = _Truth(np.array([0.2, -0.3, 0.1, 0.927]), np.radians([0.6, -0.9, 0.5]))
    truth.q0 = truth.q0 / np.linalg.norm(truth.q0)
    return simulate_run(scenario, truth_shape, truth, 11), box, stretch


def test_fit_recovers_attitude_and_stretch_of_a_box_that_is_not_the_library_box(stretched_box):
    observations, box, stretch = stretched_box
    model = PhotometricModel(observations, {"box": box})
    adjustable = AdjustableShape(box, ("inertia", "scale", "stretch", "material"))
    truth = observations.truth
    # start 6° and 0.02°/s away from the truth at the last epoch
    turn = axis_angle_to_quaternion(np.array([0.6, 0.0, 0.8]), math.radians(6.0))
    start_q = quaternion_multiply(turn, truth[-1, :4])
    start_w = truth[-1, 4:7] + np.radians([0.02, 0.0, 0.0])
    library_only = fit_arc(model, AdjustableShape(box, ()), start_q[None], start_w[None])[0]
    fit = fit_arc(model, adjustable, start_q[None], start_w[None])[0]
    group = shape_symmetry(box)
    error = math.degrees(group.attitude_error(fit.quaternion[None], truth[-1:, :4])[0])
    assert error < 2.0
    assert error < 3.0 * math.degrees(fit.attitude_sigma) + 0.5  # honest 1σ
    described = adjustable.describe(fit.theta, fit.covariance[6:, 6:])
    got = np.array([described[f"stretch_{i}"]["value"] for i in (1, 2, 3)])
    # the box's photometry fixes the ratios of its dimensions; the overall size trades
    # against the albedo, so the ratios are what is compared
    np.testing.assert_allclose(got / got[2], stretch / stretch[2], rtol=0.05)
    # the adjusted fit explains the data to the noise; the library box alone does not
    assert fit.model_error_mag < 0.015
    assert library_only.model_error_mag > 2.0 * max(fit.model_error_mag, 0.01)
    assert library_only.inflation > fit.inflation


def test_covariance_inflates_with_the_model_error(stretched_box):
    observations, box, _ = stretched_box
    model = PhotometricModel(observations, {"box": box})
    truth = observations.truth
    fit = fit_arc(model, AdjustableShape(box, ()), truth[-1:, :4], truth[-1:, 4:7])[0]
    assert fit.inflation == pytest.approx(fit.chi2 / (len(observations) - 6))
    assert fit.model_error_mag > 0.0
    # ... and the misfit stands in the evidence (uninflated log det)
    assert np.isfinite(fit.log_det)
