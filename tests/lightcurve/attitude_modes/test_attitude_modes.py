"""Offset refinement of the attitude-mode test (multi-start, weak axes) and its option."""

import math

import numpy as np
import pytest

from lightcurve.attitude_modes.offsets import (
    OffsetFit,
    distinct_lowest,
    local_fit,
    posterior_cost,
    shell_restarts,
)
from lightcurve.attitude_modes.weak_axes import INTERVAL_CHI2, weak_axes
from lightcurve.cli import main
from lightcurve.inversion import InversionOptions, validate_request

DEG = math.radians(1.0)


class _Synthetic:
    """A stand-in for :class:`ProfileFit`: residuals of an offset and their Jacobian."""

    def jacobian(self, delta: np.ndarray, step: float = 1e-6) -> np.ndarray:
        probes = delta + np.concatenate([np.eye(3), -np.eye(3)]) * step
        r = self.residuals(probes)
        return ((r[:3] - r[3:]) / (2 * step)).T


class _TwoValleys(_Synthetic):
    """Residuals with a shallow side valley at the origin and the global minimum at
    ``target`` (rad), 2.8° away — a glint-like rough ``χ²`` surface in three axes."""

    def __init__(self, target: np.ndarray) -> None:
        self.target = target

    def residuals(self, delta: np.ndarray) -> np.ndarray:
        delta = np.asarray(delta, float)
        side = np.sum(delta**2, axis=-1) / (0.6 * DEG) ** 2
        main = np.sum((delta - self.target) ** 2, axis=-1) / (0.6 * DEG) ** 2
        depth = 3.0 - 2.5 * np.exp(-side) - 3.0 * np.exp(-main)  # ≥ 0; 0 at the target
        tilt = 0.01 * np.moveaxis(delta, -1, 0) / DEG  # keeps LM's residuals ≥ its unknowns
        return np.stack([np.sqrt(depth), *tilt], axis=-1) * 10.0


class _FlatAlongX(_Synthetic):
    """``χ² = (x/3°)⁴ + (y/0.1°)² + (z/0.1°)²``: flat-bottomed along x."""

    def residuals(self, delta: np.ndarray) -> np.ndarray:
        x, y, z = np.moveaxis(np.asarray(delta, float), -1, 0)
        return np.stack([(x / (3.0 * DEG)) ** 2, y / (0.1 * DEG), z / (0.1 * DEG)], -1)


def test_distinct_lowest_takes_one_start_per_valley():
    points = np.array([[0.0], [0.1], [5.0], [0.2], [5.1], [9.0]])
    values = np.array([1.0, 1.1, 2.0, 1.2, 2.1, 3.0])
    assert distinct_lowest(points, values, 3, separation=1.0).tolist() == [0, 2, 5]
    assert distinct_lowest(points, values, 2, separation=1.0).tolist() == [0, 2]
    assert distinct_lowest(points, values, 6, separation=0.05).tolist() == [0, 1, 3, 2, 4, 5]
    values[2] = np.inf  # a failed probe is never a start
    assert distinct_lowest(points, values, 3, separation=1.0).tolist() == [0, 4, 5]


def test_shell_restarts_leave_a_side_valley():
    """The local step started in the side valley stays there; the shells around it (spacing
    4°, the coarse scan's) find the deeper valley 2.8° away."""
    target = np.array([2.0, -1.5, 1.2]) * DEG * 2.8 / math.sqrt(2.0**2 + 1.5**2 + 1.2**2)
    fit = _TwoValleys(target)
    stuck = local_fit(fit, np.zeros(3), None)
    assert np.linalg.norm(stuck.delta) < 0.1 * DEG
    found = shell_restarts(fit, stuck, None, 4.0 * DEG)
    assert np.linalg.norm(found.delta - target) < 0.05 * DEG
    assert found.cost < stuck.cost - 40.0  # 50 in the side valley, 0.08 in the deep one
    assert found.cost == pytest.approx(float(posterior_cost(fit, found.delta, None)))


def test_weak_axis_interval_brackets_a_flat_valley():
    """A valley flat along x: the weak axis is x, its 95 % profile interval spans the flat
    stretch, the well-determined axes are not weak."""
    fit = _FlatAlongX()
    solution = OffsetFit(np.zeros(3), 0.0, 0.0, np.eye(3))
    covariance = np.diag([0.5 * DEG, 0.1 * DEG, 0.1 * DEG]) ** 2  # Laplace σ_x under 1°
    axes, restart = weak_axes(
        fit,
        solution,
        covariance,
        prior_sigma=None,
        weak_sigma=1.0 * DEG,
        half_width=10.0 * DEG,
        restart=True,
    )
    assert restart is None and len(axes) == 1
    np.testing.assert_allclose(np.abs(axes[0].axis), [1.0, 0.0, 0.0], atol=1e-12)
    edge = 3.0 * INTERVAL_CHI2**0.25  # (x/3°)⁴ = χ²₁(0.95) at |x| = 4.19°
    np.testing.assert_allclose(axes[0].interval_deg, [-edge, edge], atol=0.25)


def test_weak_axis_walk_finds_a_lower_point():
    """Started in the side valley of two, the profile walk along the line to the deeper one
    returns a point lower by more than ½ (the fit then restarts from there)."""
    target = np.array([2.8, 0.0, 0.0]) * DEG
    fit = _TwoValleys(target)
    stuck = local_fit(fit, np.zeros(3), None)
    axes, lower = weak_axes(
        fit,
        stuck,
        np.diag([0.5, 0.1, 0.1]) ** 2 * DEG**2,
        prior_sigma=None,
        weak_sigma=1.0 * DEG,
        half_width=10.0 * DEG,
        restart=True,
    )
    assert axes == [] and lower is not None and lower.cost < stuck.cost - 0.5


def test_weak_sigma_option_is_a_mode_option():
    assert validate_request("ukf", modes=True, mode_weak_sigma_deg=2.5).mode_weak_sigma_deg == 2.5
    with pytest.raises(ValueError, match="need modes=True"):
        validate_request("ukf", mode_weak_sigma_deg=2.5)
    for bad in (0.0, -1.0, math.inf):
        with pytest.raises(ValueError, match="mode_weak_sigma_deg must be positive"):
            InversionOptions(mode_weak_sigma_deg=bad)


def test_weak_sigma_cli_option_is_checked_at_start(tmp_path, capsys):
    argv = ["invert", "data/observations/box_tumbling_ccd.csv", "--shapes", "box"]
    out = tmp_path / "inv"
    assert main([*argv, "--method", "ukf", "--mode-weak-sigma", "2", "--out", str(out)]) == 2
    assert "need modes=True" in capsys.readouterr().err
    bad = ["--method", "ukf", "--modes", "--mode-weak-sigma", "0", "--out", str(out)]
    assert main([*argv, *bad]) == 2
    assert "mode_weak_sigma_deg must be positive" in capsys.readouterr().err
    assert not out.exists()
