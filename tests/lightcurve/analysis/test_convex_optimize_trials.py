"""Levenberg–Marquardt trial steps that overflow the model are rejected quietly."""

import warnings

import numpy as np

from lightcurve.analysis.convex.optimize import levenberg_marquardt


def steep(x, jacobian):
    """``r = e^{5x} − 2``: from x = −3 the first Gauss–Newton steps overflow ``exp``."""
    r = np.exp(5 * x) - 2.0
    return r, (5 * np.exp(5 * x))[:, :, None] if jacobian else None


def test_overflowing_trial_steps_are_rejected_without_warnings():
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        result = levenberg_marquardt(
            steep, np.array([[-3.0], [0.0]]), np.array([True]), max_iter=100, rtol=1e-12
        )
    np.testing.assert_allclose(result.x.ravel(), np.log(2) / 5, rtol=1e-9)
    assert result.converged.all()
