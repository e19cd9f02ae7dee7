"""Batched Levenberg–Marquardt (lightcurve.analysis.convex.optimize) on known minima."""

import pytest
import torch

from lightcurve.analysis.convex.optimize import levenberg_marquardt, scaled_inverse

#: Epochs spanning 24 years in seconds, as the rotation rate of an asteroid sees them.
SECONDS = torch.linspace(0.0, 7.6e8, 200, dtype=torch.float64)


def _damped_sine(x, jacobian):
    """``r = y − A sin(ω t + φ)`` with ω ≈ 3e-4 rad/s over 7.6e8 s: the ω column of J is
    ~10⁹ times the others, as for a rotation period fitted over decades."""
    amplitude, rate, phase = x[:, 0:1], x[:, 1:2], x[:, 2:3]
    angle = rate * SECONDS + phase
    truth = 1.3 * torch.sin(3.0290e-4 * SECONDS + 0.4)
    r = truth - amplitude * torch.sin(angle)
    if not jacobian:
        return r, None
    cos = amplitude * torch.cos(angle)
    jac = -torch.stack([torch.sin(angle), cos * SECONDS, cos], dim=-1)
    return r, jac


@pytest.mark.parametrize("scaling", ["current", "max"])
def test_badly_scaled_problem_reaches_the_exact_minimum(scaling):
    """Two starts (batched; the rate 1e-6 off, 0.23 rad of phase over the span) reach the
    truth (χ² = 0) although diag(JᵀJ) spans 18 orders of magnitude; a parameter held fixed
    stays put."""
    x0 = torch.tensor(
        [[1.0, 3.0290e-4 * (1 + 1e-6), 0.3], [1.6, 3.0290e-4 * (1 - 1e-6), 0.5]],
        dtype=torch.float64,
    )
    free = torch.tensor([True, True, True])
    result = levenberg_marquardt(_damped_sine, x0, free, max_iter=60, rtol=1e-14, scaling=scaling)
    torch.testing.assert_close(result.x[:, 0], torch.full((2,), 1.3, dtype=torch.float64))
    torch.testing.assert_close(
        result.x[:, 1], torch.full((2,), 3.0290e-4, dtype=torch.float64), rtol=1e-15, atol=0
    )
    assert float(result.chi2.max()) < 1e-16
    diag = torch.diagonal(result.hessian, dim1=1, dim2=2)
    assert float((diag.max(1).values / diag.min(1).values).min()) > 1e15
    # The scaled inverse inverts JᵀJ: S H⁻¹ H S⁻¹ = I with S = diag(√diag H) (unscaled, the
    # product mixes entries 10¹⁸ apart).
    s = torch.sqrt(diag)
    product = s[:, :, None] * (scaled_inverse(result.hessian) @ result.hessian) / s[:, None, :]
    torch.testing.assert_close(
        product, torch.eye(3, dtype=torch.float64).expand(2, 3, 3), rtol=0, atol=1e-9
    )
    fixed = levenberg_marquardt(_damped_sine, x0, torch.tensor([True, False, True]), max_iter=5)
    torch.testing.assert_close(fixed.x[:, 1], x0[:, 1], rtol=0, atol=0)


def test_unknown_scaling_is_refused():
    with pytest.raises(ValueError, match="scaling"):
        levenberg_marquardt(
            _damped_sine, torch.zeros((1, 3)), torch.ones(3, dtype=bool), scaling="x"
        )
