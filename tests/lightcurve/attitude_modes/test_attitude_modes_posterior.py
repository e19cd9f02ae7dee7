"""Sampled posterior of a profile offset: intervals that hold where the Laplace
approximation does not (a curved valley), agreement where it does, reproducibility."""

import math

import numpy as np
import pytest
from scipy.stats import chi2 as chi2_distribution

from filters.attitude import rotation_vector_to_quaternion
from lightcurve.attitude_modes import TUMBLING, ModeHypothesis, ModeIdentification
from lightcurve.attitude_modes.offsets import OffsetFit
from lightcurve.attitude_modes.posterior import sample_offset_posterior

DEG = math.radians(1.0)


class _Banana:
    """``χ² = ((y − x²/1°)/0.2°)² + (x/1°)² + (z/0.2°)²`` (x, y, z in rad): at its minimum
    (the origin) the Laplace 1σ of y is 0.2°, yet ``y − x²/1°`` and ``x`` are independent
    normals, so y reaches degrees along the curved valley — the marginal of y is about
    ``χ²₁`` in degrees (97.5 % point 5.0°), and the rise of ``−2 ln`` posterior above the
    minimum is ``χ²₃`` (the change of variables has unit Jacobian)."""

    def residuals(self, delta: np.ndarray) -> np.ndarray:
        x, y, z = np.moveaxis(np.asarray(delta, float), -1, 0)
        return np.stack([(y - x**2 / DEG) / (0.2 * DEG), x / DEG, z / (0.2 * DEG)], -1)


class _Normal:
    """``χ² = (x/0.5°)² + (y/0.3°)² + (z/1°)²``: the Laplace approximation is exact."""

    def residuals(self, delta: np.ndarray) -> np.ndarray:
        return np.asarray(delta, float) / (np.array([0.5, 0.3, 1.0]) * DEG)


def _at_minimum(information_sigma_deg: np.ndarray) -> tuple[OffsetFit, np.ndarray]:
    information = np.diag(1.0 / (np.asarray(information_sigma_deg) * DEG) ** 2)
    return OffsetFit(np.zeros(3), 0.0, 0.0, information), np.linalg.inv(information)


def _sample(fit, sigma_deg, seed: int, **kwargs):
    solution, covariance = _at_minimum(sigma_deg)
    return sample_offset_posterior(
        fit,
        solution,
        covariance,
        prior_sigma=None,
        offset_quaternions=rotation_vector_to_quaternion,
        seed=seed,
        **kwargs,
    )


def test_sampled_intervals_cover_a_curved_valley_that_laplace_excludes():
    posterior = _sample(_Banana(), [1.0, 0.2, 0.2], seed=3)
    assert not posterior.laplace_ok
    # Pitch ≈ y: the valley's 95 % reach is 5.0°; the Laplace bound 1.96 × 0.2° = 0.39°.
    # A curved valley mixes slowly (τ ~ 100 steps), so its reach is sampled to ~25 %.
    lo, hi = posterior.intervals_deg["95"][1]
    assert -0.3 < lo < 0.1 and 3.0 < hi < 8.0
    # Offsets along the valley, inside the sampled intervals, outside Laplace's.
    for key, point_deg in (("68", [0.7, 0.49, 0.0]), ("95", [1.5, 2.25, 0.0])):
        bounds = posterior.intervals_deg[key]
        assert np.all((bounds[:, 0] <= point_deg) & (point_deg <= bounds[:, 1]))
        assert point_deg[1] > 1.96 * 0.2
    # The joint region: the rise is χ²₃, so its quantiles are χ²₃'s.
    for key, level in (("68", 0.68), ("95", 0.95)):
        expected = chi2_distribution.ppf(level, 3)
        assert posterior.region_rise[key] == pytest.approx(expected, rel=0.25)
    assert posterior.samples == 32 * (posterior.steps - posterior.burn_in)
    assert posterior.steps > 600 and posterior.effective_samples > 150
    assert 0.2 < posterior.acceptance < 0.9


def test_sampled_intervals_agree_with_laplace_where_it_holds():
    posterior = _sample(_Normal(), [0.5, 0.3, 1.0], seed=5)
    assert posterior.laplace_ok
    half = posterior.intervals_deg["95"][:, 1] - posterior.intervals_deg["95"][:, 0]
    np.testing.assert_allclose(half / 2, 1.96 * np.array([0.5, 0.3, 1.0]), rtol=0.2)


def test_sampler_is_reproducible_for_a_fixed_seed():
    first = _sample(_Banana(), [1.0, 0.2, 0.2], seed=11, steps=200, max_steps=400)
    again = _sample(_Banana(), [1.0, 0.2, 0.2], seed=11, steps=200, max_steps=400)
    other = _sample(_Banana(), [1.0, 0.2, 0.2], seed=12, steps=200, max_steps=400)
    for key in ("68", "95"):
        np.testing.assert_array_equal(first.intervals_deg[key], again.intervals_deg[key])
    assert first.region_rise == again.region_rise and first.to_dict() == again.to_dict()
    assert not np.array_equal(first.intervals_deg["95"], other.intervals_deg["95"])
    with pytest.raises(ValueError, match="walkers >= 8"):
        _sample(_Normal(), [0.5, 0.3, 1.0], seed=0, steps=100, max_steps=50)


def test_summary_reports_the_sampled_posterior_of_a_stabilised_winner():
    posterior = _sample(_Normal(), [0.5, 0.3, 1.0], seed=5, steps=150, max_steps=150)
    common = {"shape": "box_wing", "n_params": 3, "log_evidence": 0.0, "consistent": True}
    state = {"quaternion": np.array([0.0, 0.0, 0.0, 1.0]), "omega_rad_s": np.zeros(3)}
    nadir = ModeHypothesis(
        mode="nadir",
        chi2=100.0,
        offsets_deg=np.array([1.0, 2.0, 3.0]),
        offset_sigma_deg=np.array([0.5, 0.3, 1.0]),
        posterior=posterior,
        **common,
        **state,
    )
    found = ModeIdentification("nadir", 0.99, {"nadir": 0.99}, nadir, [nadir], False)
    summary = found.summary()
    assert summary["attitude_offsets_deg"] == [1.0, 2.0, 3.0]
    assert summary["attitude_offset_intervals_deg"]["95"] == posterior.intervals_deg["95"].tolist()
    assert summary["attitude_offset_region_rise"] == posterior.region_rise
    assert summary["attitude_offset_laplace_ok"] is posterior.laplace_ok
    assert summary["attitude_offset_posterior"]["samples"] == 32 * 100
    tumbler = ModeHypothesis(
        mode=TUMBLING, chi2=90.0, offsets_deg=None, offset_sigma_deg=None, **common, **state
    )
    summary = ModeIdentification(TUMBLING, 0.9, {TUMBLING: 0.9}, tumbler, [tumbler], False)
    keys = ("intervals_deg", "region_rise", "laplace_ok", "posterior")
    assert all(summary.summary()[f"attitude_offset_{k}"] is None for k in keys)
