"""Figures of an inversion result folder (``lightcurve plot DIR/<stem>``).

Every function takes the loaded result and returns a matplotlib figure; :func:`plot_result`
writes them all as PNGs. Angles are plotted in degrees and rates in deg/s.

Against truth columns, ``states.png`` plots the errors modulo the rotational symmetry group
``G`` of the result's shape (the most probable one for MMAE and the PF), as the inversion's
figures in ``docs/inversion.md`` measure them: light curves determine the attitude only up
to ``G`` (:mod:`filters.symmetry`), so an estimate at a symmetric twin of the truth is a
right answer. :func:`state_errors` computes the plotted errors.
"""

from __future__ import annotations

import json
import textwrap
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from filters.attitude import (
    attitude_matrix,
    quaternion_conjugate,
    quaternion_multiply,
    quaternion_to_euler321,
    quaternion_to_rotation_vector,
)
from filters.symmetry import SymmetryGroup
from lightcurve import io
from lightcurve.io.atomic import atomic_path
from lightcurve.io.observations import Observations

__all__ = ["InversionFolder", "StateErrors", "load_result", "plot_result", "state_errors"]


@dataclass
class InversionFolder:
    """An inversion result folder: its summary, estimates and (when readable) the input.

    ``symmetry`` is the rotational symmetry group of the summary's shape, loaded when the
    input has truth columns (None otherwise, or when the shape cannot be loaded: then
    ``symmetry_problem`` says why and the errors are plotted unfolded).
    """

    path: Path
    summary: dict
    estimates: pd.DataFrame
    observations: Observations | None
    symmetry: SymmetryGroup | None = None
    symmetry_problem: str | None = None


def load_result(path: str | Path, library: str | None = None) -> InversionFolder:
    """Read ``summary.json`` and ``estimates.parquet`` of one input's result folder.

    With truth columns in the input, the symmetry group of the summary's shape is taken
    from ``library`` (default: ``$LIGHTCURVE_LIBRARY`` or the built-in library, as for
    ``lightcurve invert``).
    """
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
    result = InversionFolder(path, summary, estimates, observations)
    if _truth(result) is not None:
        result.symmetry, result.symmetry_problem = _shape_symmetry(summary.get("shape"), library)
    return result


def _shape_symmetry(
    name: str | None, library: str | None
) -> tuple[SymmetryGroup | None, str | None]:
    """The symmetry group of the result's shape, or None and the reason."""
    if not name:
        return None, "the summary names no shape"
    from lightcurve.inversion import shape_symmetry
    from shapes import get_library

    try:
        shape = get_library(library).load(name)
    except (OSError, ValueError, KeyError) as exc:
        return None, f"shape {name!r} not loadable ({exc}); pass its --library"
    return shape_symmetry(shape), None


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


@dataclass
class StateErrors:
    """The errors ``states.png`` plots against the truth, per epoch.

    Attributes
    ----------
    attitude_deg : (N, 3) numpy.ndarray
        Rotation vector of ``δq = q̂' ⊗ q⁻¹`` (deg, body frame), ``q̂'`` the estimate mapped
        onto its symmetry-equivalent attitude nearest the truth ``q``.
    rate_deg_s : (N, 3) numpy.ndarray
        ``R ω̂ − ω`` (deg/s): the estimated rates mapped with the same element ``R``.
    sigma_attitude_deg, sigma_rate_deg_s : (N, 3) numpy.ndarray
        1σ of the mapped estimate: ``√((R∘R) σ²)``, the diagonal of ``R P Rᵀ`` for the
        stored diagonal ``P`` (exact for the signed-permutation elements of box-like
        groups; equal to ``σ`` when ``R`` is diagonal, e.g. 180° turns about body axes).
    rotations : (N, 3, 3) numpy.ndarray
        The group element ``R`` used at each epoch (``A(q̂') = R A(q̂)``); the identity
        when not folded.
    folded : bool
        Whether the errors are taken modulo a non-trivial group.
    """

    attitude_deg: np.ndarray
    rate_deg_s: np.ndarray
    sigma_attitude_deg: np.ndarray
    sigma_rate_deg_s: np.ndarray
    rotations: np.ndarray
    folded: bool


def state_errors(
    q: np.ndarray,
    omega: np.ndarray,
    sigma_attitude_deg: np.ndarray,
    sigma_rate: np.ndarray,
    truth: np.ndarray,
    group: SymmetryGroup | None = None,
) -> StateErrors:
    """Attitude and rate errors against the truth modulo a symmetry group.

    At each epoch the estimate ``(q̂, ω̂)`` is replaced by the symmetry-equivalent state
    ``(s ⊗ q̂, R ω̂)`` whose attitude is nearest the truth
    (:meth:`~filters.symmetry.SymmetryGroup.nearest_equivalent`; for a continuous axis the
    rotation about it is chosen too, so the error has no component along the axis). The
    element is chosen per epoch, as :meth:`~filters.symmetry.SymmetryGroup.attitude_error`
    (and the summary figures of ``docs/inversion.md``) do: equivalent states fit every
    measurement alike, so a filter whose leading hypothesis passes from one to another has
    made no error. The norm of the attitude error is ``group.attitude_error(q̂, q)``.

    Parameters
    ----------
    q : (N, 4) array
        Estimated attitudes.
    omega : (N, 3) array
        Estimated body rates, rad/s.
    sigma_attitude_deg : (N, 3) array
        1σ of the attitude error per body axis, deg.
    sigma_rate : (N, 3) array
        1σ of the rates, rad/s.
    truth : (N, 7) array
        True ``q1..q4, wx, wy, wz`` (rad/s).
    group : SymmetryGroup, optional
        The shape's group; None or trivial leaves the errors unfolded.

    Returns
    -------
    StateErrors
    """
    q = np.asarray(q, dtype=float)
    omega = np.asarray(omega, dtype=float)
    truth = np.asarray(truth, dtype=float)
    q_true, omega_true = truth[:, :4], truth[:, 4:7]
    folded = group is not None and not group.is_trivial
    if folded:
        q, rotations = group.nearest_equivalent(q_true, q)
        omega = np.einsum("nij,nj->ni", rotations, omega)
    else:
        rotations = np.broadcast_to(np.eye(3), (len(q), 3, 3)).copy()
    squares = rotations**2  # variances of R x for a diagonal covariance of x
    sigma_att = np.sqrt(np.einsum("nij,nj->ni", squares, np.asarray(sigma_attitude_deg) ** 2))
    sigma_w = np.sqrt(np.einsum("nij,nj->ni", squares, np.asarray(sigma_rate) ** 2))
    error = quaternion_to_rotation_vector(quaternion_multiply(q, quaternion_conjugate(q_true)))
    return StateErrors(
        attitude_deg=np.rad2deg(error),
        rate_deg_s=np.rad2deg(omega - omega_true),
        sigma_attitude_deg=sigma_att,
        sigma_rate_deg_s=np.rad2deg(sigma_w),
        rotations=rotations,
        folded=folded,
    )


def _group_label(result: InversionFolder) -> str | None:
    """How the folding is named in the figure (None: not folded)."""
    group = result.symmetry
    if group is None or group.is_trivial:
        return None
    shape = result.summary.get("shape")
    if group.axis is not None:
        axis = ", ".join(f"{v:.3g}" for v in group.axis + 0.0)
        return (
            f"errors modulo the symmetry group of {shape} (rotations about body axis [{axis}], "
            f"not counted, and {group.order} discrete ones)"
        )
    return f"errors modulo the symmetry group of {shape} ({group.order} rotations)"


def state_figure(result: InversionFolder):
    """Attitude error (or estimate) and rates with 3σ bands; truth when the input has it.

    The errors against the truth are taken modulo the shape's symmetry group
    (:func:`state_errors`); the figure's title says so when the group is not trivial.
    """
    plt = _pyplot()
    est = result.estimates
    t = _minutes(result)
    q = est[["q1", "q2", "q3", "q4"]].to_numpy()
    w = np.rad2deg(est[["wx", "wy", "wz"]].to_numpy())
    sig_att = est[["sigma_att_x", "sigma_att_y", "sigma_att_z"]].to_numpy()
    sig_w = np.rad2deg(est[["sigma_wx", "sigma_wy", "sigma_wz"]].to_numpy())
    truth = _truth(result)
    fig, axes = plt.subplots(3, 2, figsize=(11, 7.5), sharex=True)
    label = None
    if truth is not None:
        errors = state_errors(
            q,
            est[["wx", "wy", "wz"]].to_numpy(),
            sig_att,
            est[["sigma_wx", "sigma_wy", "sigma_wz"]].to_numpy(),
            truth,
            result.symmetry,
        )
        error, rate_error = errors.attitude_deg, errors.rate_deg_s
        sig_att, sig_w = errors.sigma_attitude_deg, errors.sigma_rate_deg_s
        label = _group_label(result)
    else:
        euler = np.rad2deg(quaternion_to_euler321(q))
    for k, axis in enumerate("xyz"):
        ax = axes[k, 0]
        if truth is not None:
            ax.plot(t, error[:, k], color="C0", lw=1, label="error mod G" if label else "error")
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
    if truth is not None:
        axes[0, 0].legend(loc="upper right", fontsize=8)
        axes[0, 0].set_title(
            "attitude error mod G with ±3σ" if label else "attitude error with ±3σ"
        )
        axes[0, 1].set_title(
            "rate error of the equivalent state with ±3σ" if label else "rate error with ±3σ"
        )
        if label:
            text = label + "; each epoch's estimate mapped to its equivalent nearest the truth"
            fig.suptitle(textwrap.fill(text, 120), fontsize=9)
        elif result.symmetry_problem:
            text = f"errors not folded by symmetry: {result.symmetry_problem}"
            fig.suptitle(textwrap.fill(text, 120), fontsize=9)
    else:
        axes[0, 0].set_title("3-2-1 Euler angles with ±3σ (approx.)")
        axes[0, 1].set_title("rates with ±3σ")
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


def plot_result(
    path: str | Path, out_dir: str | Path | None = None, library: str | None = None
) -> list[Path]:
    """Write every figure of a result folder as PNG files; returns their paths.

    ``library`` is the shape library of the inversion (for the shape's symmetry group).
    """
    result = load_result(path, library)
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
