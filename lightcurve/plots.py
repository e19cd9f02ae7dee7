"""Figures of an inversion result folder (``lightcurve plot DIR/<stem>``).

Every function takes the loaded result and returns a matplotlib figure; :func:`plot_result`
writes them all as PNGs. Angles are plotted in degrees and rates in deg/s.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from filters.attitude import (
    attitude_matrix,
    quaternion_multiply,
    quaternion_to_euler321,
    quaternion_to_rotation_vector,
)
from lightcurve import io
from lightcurve.io.atomic import atomic_path
from lightcurve.io.observations import Observations

__all__ = ["InversionFolder", "load_result", "plot_result"]


@dataclass
class InversionFolder:
    """An inversion result folder: its summary, estimates and (when readable) the input."""

    path: Path
    summary: dict
    estimates: pd.DataFrame
    observations: Observations | None


def load_result(path: str | Path) -> InversionFolder:
    """Read ``summary.json`` and ``estimates.parquet`` of one input's result folder."""
    path = Path(path)
    summary_file = path / "summary.json"
    if not summary_file.is_file():
        inputs = sorted(str(found.parent) for found in path.glob("*/summary.json"))
        if inputs:  # the batch folder of `lightcurve invert --out`
            shown = ", ".join(inputs[:3]) + (", …" if len(inputs) > 3 else "")
            raise FileNotFoundError(
                f"{path}: the folder of a whole batch; plot one input's result folder: {shown}"
            )
        raise FileNotFoundError(f"{path}: no summary.json (not an inversion result folder?)")
    summary = json.loads(summary_file.read_text())
    if summary.get("status") != "ok":
        raise ValueError(f"{path}: the inversion failed ({summary.get('error')}); nothing to plot")
    estimates = pd.read_parquet(path / "estimates.parquet")
    try:
        observations = io.read(summary["input"])
    except (OSError, ValueError):
        observations = None
    return InversionFolder(path, summary, estimates, observations)


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _minutes(result: InversionFolder) -> np.ndarray:
    mjd = result.estimates["mjd"].to_numpy()
    return (mjd - mjd[0]) * 1440.0


def light_curve_figure(result: InversionFolder):
    """Measured vs fitted magnitudes with residuals."""
    plt = _pyplot()
    est = result.estimates
    t = _minutes(result)
    fig, (top, bottom) = plt.subplots(
        2, 1, figsize=(9, 6), sharex=True, gridspec_kw={"height_ratios": [3, 1]}
    )
    measured = est["predicted_mag"] + est["residual"]
    top.errorbar(
        t,
        measured,
        yerr=_mag_err(result, len(t)),
        fmt=".",
        ms=3,
        lw=0.5,
        color="0.3",
        label="measured",
    )
    top.plot(t, est["predicted_mag"], "-", color="C3", lw=1, label="fitted")
    top.invert_yaxis()
    top.set(
        ylabel="magnitude",
        title=f"{Path(result.summary['input']).name}: "
        f"{result.summary['method']} / {result.summary['shape']}, "
        f"rms {result.summary['residual_rms_mag']:.3f} mag",
    )
    top.legend()
    bottom.plot(t, est["residual"], ".", ms=3, color="C0")
    bottom.axhline(0.0, color="k", lw=0.8)
    if "gated" in est and est["gated"].any():
        gated = est["gated"].to_numpy(bool)
        bottom.plot(t[gated], est["residual"][gated], "x", color="C3", label="gated")
        bottom.legend()
    bottom.set(xlabel="minutes since first epoch", ylabel="residual (mag)")
    fig.tight_layout()
    return fig


def _mag_err(result: InversionFolder, n: int):
    if result.observations is not None and len(result.observations) == n:
        return result.observations.magnitude_errors
    return None


def _truth(result: InversionFolder) -> np.ndarray | None:
    obs = result.observations
    if obs is None or not obs.has_truth or len(obs) != len(result.estimates):
        return None
    return obs.truth


def state_figure(result: InversionFolder):
    """Attitude error (or estimate) and rates with 3σ bands; truth when the input has it."""
    plt = _pyplot()
    est = result.estimates
    t = _minutes(result)
    q = est[["q1", "q2", "q3", "q4"]].to_numpy()
    w = np.rad2deg(est[["wx", "wy", "wz"]].to_numpy())
    sig_att = est[["sigma_att_x", "sigma_att_y", "sigma_att_z"]].to_numpy()
    sig_w = np.rad2deg(est[["sigma_wx", "sigma_wy", "sigma_wz"]].to_numpy())
    truth = _truth(result)
    fig, axes = plt.subplots(3, 2, figsize=(11, 7), sharex=True)
    if truth is not None:
        # Attitude error δq = q_est ⊗ q_true⁻¹ as a rotation vector (deg, body frame).
        q_true_inv = truth[:, :4] * np.array([-1.0, -1.0, -1.0, 1.0])
        error = np.rad2deg(quaternion_to_rotation_vector(quaternion_multiply(q, q_true_inv)))
        rate_error = w - np.rad2deg(truth[:, 4:])
    else:
        euler = np.rad2deg(quaternion_to_euler321(q))
    for k, axis in enumerate("xyz"):
        ax = axes[k, 0]
        if truth is not None:
            ax.plot(t, error[:, k], color="C0", lw=1, label="error")
            ax.fill_between(
                t, -3 * sig_att[:, k], 3 * sig_att[:, k], color="C0", alpha=0.2, label="±3σ"
            )
            ax.set_ylabel(f"δθ_{axis} (deg)")
        else:
            ax.plot(t, euler[:, k], color="C0", lw=1)
            ax.fill_between(
                t,
                euler[:, k] - 3 * sig_att[:, k],
                euler[:, k] + 3 * sig_att[:, k],
                color="C0",
                alpha=0.2,
            )
            ax.set_ylabel(f"{('yaw ψ', 'pitch θ', 'roll φ')[k]} (deg)")
        ax = axes[k, 1]
        if truth is not None:
            ax.plot(t, rate_error[:, k], color="C1", lw=1)
            ax.set_ylabel(f"δω_{axis} (deg/s)")
            center = 0.0
        else:
            ax.plot(t, w[:, k], color="C1", lw=1)
            ax.set_ylabel(f"ω_{axis} (deg/s)")
            center = w[:, k]
        ax.fill_between(
            t, center - 3 * sig_w[:, k], center + 3 * sig_w[:, k], color="C1", alpha=0.2
        )
    axes[0, 0].set_title(
        "attitude error with ±3σ" if truth is not None else "3-2-1 Euler angles with ±3σ (approx.)"
    )
    axes[0, 1].set_title("rate error with ±3σ" if truth is not None else "rates with ±3σ")
    for ax in axes[-1]:
        ax.set_xlabel("minutes since first epoch")
    fig.tight_layout()
    return fig


def probability_figure(result: InversionFolder):
    """Model probabilities over time (MMAE / multi-shape PF), or None."""
    columns = [c for c in result.estimates if c.startswith("p_")]
    if not columns:
        return None
    plt = _pyplot()
    t = _minutes(result)
    fig, ax = plt.subplots(figsize=(9, 4))
    for column in columns:
        ax.plot(t, result.estimates[column], lw=1.2, label=column[2:])
    ax.set(
        xlabel="minutes since first epoch",
        ylabel="probability",
        ylim=(-0.02, 1.02),
        title="shape probabilities" + ("  (none fits!)" if result.summary.get("none_fits") else ""),
    )
    ax.legend(ncol=2, fontsize=8)
    fig.tight_layout()
    return fig


def modes_figure(result: InversionFolder):
    """Final attitude distribution of the particle filter: its modes, or None.

    Each mode is drawn as the inertial directions of the body axes (right ascension,
    declination), marker area proportional to the mode's weight.
    """
    modes = result.summary.get("modes") or []
    if not modes:
        return None
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(8, 4.5))
    weights = np.array([m["weight"] for m in modes])
    quats = np.array([m["quaternion"] for m in modes])
    axes = attitude_matrix(quats)  # rows: body axes in the inertial frame
    for k, (axis, color) in enumerate(zip("xyz", ("C0", "C1", "C2"), strict=True)):
        v = axes[:, k, :]
        ra = np.rad2deg(np.arctan2(v[:, 1], v[:, 0])) % 360
        dec = np.rad2deg(np.arcsin(np.clip(v[:, 2], -1, 1)))
        ax.scatter(
            ra,
            dec,
            s=20 + 400 * weights / weights.max(),
            color=color,
            alpha=0.6,
            label=f"body {axis}",
        )
    ax.set(
        xlim=(0, 360),
        ylim=(-90, 90),
        xlabel="right ascension (deg)",
        ylabel="declination (deg)",
        title=f"particle-filter modes ({len(modes)})",
    )
    ax.legend()
    fig.tight_layout()
    return fig


def plot_result(path: str | Path, out_dir: str | Path | None = None) -> list[Path]:
    """Write every figure of a result folder as PNG files; returns their paths."""
    result = load_result(path)
    out_dir = Path(out_dir) if out_dir is not None else result.path
    plt = _pyplot()
    written = []
    for name, make in (
        ("light_curve", light_curve_figure),
        ("states", state_figure),
        ("probabilities", probability_figure),
        ("modes", modes_figure),
    ):
        fig = make(result)
        if fig is None:
            continue
        target = out_dir / f"{name}.png"
        with atomic_path(target, suffix=".png") as tmp:
            fig.savefig(tmp, dpi=110, format="png")
        plt.close(fig)
        written.append(target)
    return written
