"""The compiled convex model against the torch model, and the period scan's early rejection."""

import dataclasses

import numpy as np
import pytest
import torch

from filters.attitude import attitude_matrix
from lightcurve import io
from lightcurve.analysis.convex import (
    ConvexSettings,
    EarlyRejection,
    GaussianSphere,
    Photometry,
    fit,
    period_scan,
)
from lightcurve.analysis.convex import data as convex_data
from lightcurve.analysis.convex.compiled import CompiledModel
from lightcurve.analysis.convex.model import ConvexModel
from lightcurve.analysis.spin import SpinState, pole_matrix, pole_quaternion
from lightcurve.io.observations import Observations
from lightcurve.sky.geometry import AU_M

ARIADNE = "data/ariadne/test_lcs_rel"


@pytest.fixture(scope="module")
def mixed_data():
    """Relative and calibrated curves (DAMIT test_lcs_abs), thinned."""
    obs = io.read("data/ariadne/test_lcs_abs")
    keep = np.isin(obs.lightcurve_ids, list(range(0, 37, 4)))
    table = obs.table.loc[keep].iloc[::3].reset_index(drop=True)
    data = Photometry.from_observations([Observations(table, obs.meta, obs.source)])
    assert data.relative.any() and not data.relative.all()
    return data


def _parameters(layout, seed):
    rng = np.random.default_rng(seed)
    x = np.zeros((3, layout.size))
    x[:, 1 : layout.n_coefficients] = rng.normal(0, 0.25, (3, layout.n_coefficients - 1))
    x[:, layout.spin] = [[4.4, -0.3, 3.03e-4, 0.2], [1.0, 0.7, 3.0e-4, 1.0], [2.0, 1.5, 3e-4, 5.0]]
    x[:, layout.phase] = [[0.5, 0.1, -0.5], [0.3, 0.2, -0.1], [0.5, 0.1, -0.5]]
    x[:, layout.lambert] = [0.1, 0.3, 0.0]
    x[:, layout.log_scale] = [0.3, -0.2, 0.0]
    return x


def test_compiled_model_matches_the_torch_model(mixed_data):
    """Residuals and Jacobian (every column, or a chosen subset) of the compiled kernels equal
    the torch model's, whose Jacobian test_convex checks against forward-mode autograd."""
    sphere = GaussianSphere(4, 4, 4)
    compiled = CompiledModel(mixed_data, sphere, mixed_data.mean_epoch)
    reference = ConvexModel(mixed_data, sphere, mixed_data.mean_epoch)
    x = _parameters(compiled.layout, seed=3)
    r, jac = compiled.residuals(x, jacobian=True, lambert_free=True)
    r_ref, jac_ref = (t.numpy() for t in reference.residuals(torch.as_tensor(x), True, True))
    np.testing.assert_allclose(r, r_ref, rtol=1e-10, atol=1e-10 * np.abs(r_ref).max())
    scale = np.abs(jac_ref).max(axis=1, keepdims=True).clip(1e-300)
    assert np.abs((jac - jac_ref) / scale).max() < 1e-9
    r_plain, none = compiled.residuals(x, jacobian=False)
    assert none is None
    np.testing.assert_allclose(r_plain, r_ref, rtol=1e-10, atol=1e-10 * np.abs(r_ref).max())
    columns = np.array([2, 7, compiled.layout.index("rate"), compiled.layout.log_scale])
    _, subset = compiled.residuals(x, True, True, columns)
    np.testing.assert_array_equal(subset, jac[..., columns])
    model, model_jac = compiled.evaluate(x, jacobian=True, lambert_free=True)
    ref_model, ref_jac = (t.numpy() for t in reference.evaluate(torch.as_tensor(x), True, True))
    np.testing.assert_allclose(model, ref_model, rtol=1e-10)
    assert np.abs(model_jac - ref_jac).max() < 1e-9 * np.abs(ref_jac).max()
    # float32 facet sums: the same model to single precision.
    single = CompiledModel(mixed_data, sphere, mixed_data.mean_epoch, dtype=np.float32)
    np.testing.assert_allclose(single.evaluate(x, False)[0], ref_model, rtol=2e-5)


def test_pole_matrix_is_that_of_the_pole_quaternion():
    lam, beta = np.array([0.3, 4.0, 6.1]), np.array([-0.7, 1.2, 0.0])
    value, d_lambda, d_beta = pole_matrix(lam, beta, derivatives=True)
    np.testing.assert_allclose(value, attitude_matrix(pole_quaternion(lam, beta)), atol=1e-15)
    step = 1e-6
    central = (pole_matrix(lam + step, beta) - pole_matrix(lam - step, beta)) / (2 * step)
    np.testing.assert_allclose(d_lambda, central, atol=1e-9)
    central = (pole_matrix(lam, beta + step) - pole_matrix(lam, beta - step)) / (2 * step)
    np.testing.assert_allclose(d_beta, central, atol=1e-9)
    assert convex_data.AU_M == AU_M


def test_engines_give_the_same_fit():
    """engine='torch' (ConvexModel through the same optimiser) and the compiled default agree."""
    data = Photometry.from_observations([io.read(ARIADNE)]).thinned(6)
    start = SpinState.from_degrees(220.0, 0.0, 5.76198, 0.0, float(data.mjd.min()))
    settings = ConvexSettings(degree=3, order=3, nrows=3, max_iter=15)
    numba_fit = fit(data, start, settings)[0]
    torch_fit = fit(data, start, dataclasses.replace(settings, engine="torch"))[0]
    assert numba_fit.iterations == torch_fit.iterations
    assert numba_fit.spin.period_h == pytest.approx(torch_fit.spin.period_h, abs=1e-9)
    assert numba_fit.chi2 == pytest.approx(torch_fit.chi2, rel=1e-8)
    with pytest.raises(ValueError, match="engine"):
        ConvexSettings(engine="jax")
    with pytest.raises(ValueError, match="compile"):
        ConvexSettings(compile=True)


def test_early_rejection_rule():
    rule = EarlyRejection(after=2, factor=3.0)
    lowest = np.full(5, np.inf)
    chi2 = np.array([10.0, 25.0, 40.0])
    assert not rule.stop(1, chi2, lowest).any()  # before `after` iterations nothing stops
    assert lowest[1] == 10.0
    np.testing.assert_array_equal(rule.stop(2, chi2, lowest), [False, False, True])
    lowest[3] = 5.0  # an earlier batch did better after three iterations
    np.testing.assert_array_equal(rule.stop(3, chi2, lowest), [False, True, True])
    with pytest.raises(ValueError, match="factor"):
        EarlyRejection(factor=1.0)


def test_scan_with_early_rejection_keeps_the_minimum():
    """Around Ariadne's period (reduced data), the scan with early rejection stops most fits
    early and finds the same deepest minima as the scan that runs every fit to the end;
    progress reaches the total."""
    data = Photometry.from_observations([io.read(ARIADNE)]).thinned(10)
    window = (5.7612, 5.7628)
    calls = []
    full = period_scan(data, window, poles=2, reject=None)
    fast = period_scan(data, window, poles=2, progress=lambda done, total: calls.append(done))
    assert calls[-1] == len(fast.periods_h) and calls == sorted(calls)
    assert not full.rejected.any() and fast.rejected.mean() > 0.3
    kept = ~fast.rejected
    np.testing.assert_allclose(fast.chi2[kept], full.chi2[kept], rtol=1e-6)
    # The periods within 1.5 times the lowest χ² (the deepest minima) are never stopped.
    near = full.chi2 < 1.5 * full.chi2.min()
    assert not fast.rejected[near].any()
    assert fast.minimum().spin.period_h == pytest.approx(full.minimum().spin.period_h, abs=1e-9)
