"""Which flagged answers get the uncertainty of an unknown state: those whose model does
not explain the data, not those flagged by a consistency window alone."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from lightcurve.inversion import InversionOptions
from lightcurve.inversion.result import (
    UNKNOWN_ATTITUDE_VARIANCE,
    InversionResult,
    unknown_state_uncertainty,
)


def _result(residual_rms: float, model_error: float) -> InversionResult:
    table = pd.DataFrame({f"sigma_att_{a}": [1.0, 1.0] for a in "xyz"})
    for a in "xyz":
        table[f"sigma_w{a}"] = 1e-4
    return InversionResult(
        method="pf",
        shape="box",
        shape_probabilities={"box": 1.0},
        none_fits=True,
        epoch_mjd=60000.0,
        quaternion=np.array([0.0, 0.0, 0.0, 1.0]),
        omega_rad_s=np.zeros(3),
        attitude_sigma_deg=math.sqrt(3.0),
        omega_sigma_rad_s=np.full(3, 1e-4),
        modes=[],
        residual_rms_mag=residual_rms,
        n_measurements=2,
        estimates=table,
        notes=[],
        model_error_mag=model_error,
        covariance=np.eye(6) * 1e-4,
    )


def _context() -> SimpleNamespace:
    model = SimpleNamespace(errors=np.full(100, 0.03))
    return SimpleNamespace(model=model, options=InversionOptions(), omega_max=math.radians(5.0))


def test_a_flag_with_residuals_at_the_noise_keeps_the_local_sigma() -> None:
    # a PF answer at 0.0316 mag rms against 0.03 mag errors: 0.010 mag beyond the noise
    result = _result(residual_rms=0.0316, model_error=math.sqrt(0.0316**2 - 0.03**2))
    unknown_state_uncertainty(_context(), result)
    assert result.attitude_sigma_deg == pytest.approx(math.sqrt(3.0))
    assert (result.estimates["sigma_att_x"] == 1.0).all()
    assert any("the local 1σ is kept" in note for note in result.notes)


@pytest.mark.parametrize(
    ("rms", "model_error"), [(0.46, math.sqrt(0.46**2 - 0.03**2)), (0.03, 0.2)]
)
def test_a_model_that_does_not_fit_gets_the_unknown_state(rms, model_error) -> None:
    result = _result(residual_rms=rms, model_error=model_error)
    unknown_state_uncertainty(_context(), result)
    assert result.attitude_sigma_deg == pytest.approx(
        math.degrees(math.sqrt(3.0 * UNKNOWN_ATTITUDE_VARIANCE))
    )
    assert np.allclose(np.radians(result.estimates["sigma_att_y"]) ** 2, UNKNOWN_ATTITUDE_VARIANCE)
    assert np.allclose(result.omega_sigma_rad_s, math.radians(5.0) / math.sqrt(5.0))
