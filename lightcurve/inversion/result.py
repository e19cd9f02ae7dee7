"""The outcome of an inversion: :class:`InversionResult` and the rows of its per-epoch table."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from filters.attitude import (
    quaternion_canonical,
)
from filters.symmetry import SymmetryGroup
from lightcurve.inversion.context import Context

#: Per-axis variance (rad²) of the rotation-vector error of an attitude distributed uniformly
#: on SO(3): the rotation angle ``θ`` has the density ``(1 − cos θ)/π`` on ``[0, π]`` (Miles
#: 1965, "On random rotations in R³", Biometrika 52, 636), so ``E[θ²] = π²/3 + 2`` and each
#: of the three components carries a third of it (1σ 76.1° per axis, 131.8° in total).
UNKNOWN_ATTITUDE_VARIANCE = (math.pi**2 / 3.0 + 2.0) / 3.0


@dataclass
class InversionResult:
    """Outcome of :func:`invert` (the fields the batch command writes).

    Attributes
    ----------
    method : str
    shape : str or None
        Most probable (or only) shape.
    shape_probabilities : dict
        Shape name → posterior probability.
    none_fits : bool
        No candidate shape is consistent with the last measurements.
    epoch_mjd : float
        Epoch of the LAST measurement (UTC MJD); the state below holds there.
    quaternion : (4,) numpy.ndarray
        Attitude, inertial → body, sign-canonical.
    omega_rad_s : (3,) numpy.ndarray
        Body rates (rad/s).
    attitude_sigma_deg : float
        Total 1σ attitude uncertainty ``√(tr P_δθ)`` (deg).
    omega_sigma_rad_s : (3,) numpy.ndarray
        1σ of the rates (rad/s).
    modes : list of dict
        PF posterior modes: ``quaternion``, ``omega_rad_s``, ``weight`` plus ``shape``,
        ``attitude_sigma_deg`` and ``equivalent_quaternions`` (the symmetry-equivalent
        attitudes of the mode's shape); empty for UKF/MMAE.
    residual_rms_mag : float
        RMS of the measured − predicted magnitudes (gated measurements excluded).
    n_measurements : int
    estimates : pandas.DataFrame
        One row per epoch: ``mjd, q1..q4, wx, wy, wz, sigma_att_x/y/z`` (deg),
        ``sigma_wx/wy/wz`` (rad/s), ``predicted_mag, residual, gated`` and ``p_<shape>``
        with several shapes.
    notes : list of str
    parameters : dict
        Model adjustments estimated with the state, name → ``{"value", "sigma"}`` (1σ):
        ``k1, k2`` (tanh inertia) and ``inertia_ratio_1/2`` (J₁/J₃, J₂/J₃),
        ``magnitude_offset`` (mag), ``stretch_1..3``, ``tilt_deg``,
        ``"<material>.<parameter>"`` (see
        :meth:`lightcurve.photometry.adjusted.AdjustableShape.physical`).
    rejected_fraction : float
        Fraction of the measurements the filters' innovation gate rejected (UKF/MMAE).
    model_error_mag : float
        rms magnitude misfit of the reported candidate beyond the measurement errors
        (UKF/MMAE: the whole-arc fit's; without it, the filter's covariance-matching
        estimate; PF: ``√max(0, rms² − σ̄²)`` of its per-epoch residuals, ``σ̄`` the rms
        measurement 1σ of the measurements used).
    symmetry : dict
        Symmetry group of the reported shape (order, continuous axis, quaternions).
    covariance : (6, 6) numpy.ndarray
        Final covariance of ``[δθ (rad, body frame), ω (rad/s)]``.
    runtime_s : float
    attitude_mode : dict or None
        With ``modes=True``: the summary of :func:`lightcurve.attitude_modes.identify_attitude_mode`
        (``attitude_mode``, ``attitude_mode_probability``, ``attitude_offsets_deg``, …).
    """

    method: str
    shape: str | None
    shape_probabilities: dict[str, float]
    none_fits: bool
    epoch_mjd: float
    quaternion: np.ndarray
    omega_rad_s: np.ndarray
    attitude_sigma_deg: float
    omega_sigma_rad_s: np.ndarray
    modes: list[dict[str, Any]]
    residual_rms_mag: float
    n_measurements: int
    estimates: pd.DataFrame
    notes: list[str] = field(default_factory=list)
    parameters: dict[str, dict[str, float]] = field(default_factory=dict)
    rejected_fraction: float = 0.0
    model_error_mag: float = math.nan
    symmetry: dict[str, Any] = field(default_factory=dict)
    covariance: np.ndarray = field(default_factory=lambda: np.full((6, 6), np.nan))
    runtime_s: float = 0.0
    attitude_mode: dict[str, Any] | None = None

    def summary(self) -> dict[str, Any]:
        """JSON-ready dictionary of the scalar fields (no table)."""
        return {
            "method": self.method,
            "shape": self.shape,
            "shape_probabilities": {k: float(v) for k, v in self.shape_probabilities.items()},
            "none_fits": bool(self.none_fits),
            "epoch_mjd": float(self.epoch_mjd),
            "quaternion": [float(v) for v in self.quaternion],
            "omega_rad_s": [float(v) for v in self.omega_rad_s],
            "attitude_sigma_deg": float(self.attitude_sigma_deg),
            "omega_sigma_rad_s": [float(v) for v in self.omega_sigma_rad_s],
            "modes": self.modes,
            "residual_rms_mag": float(self.residual_rms_mag),
            "n_measurements": int(self.n_measurements),
            "notes": list(self.notes),
            "parameters": {
                k: {"value": float(v["value"]), "sigma": float(v["sigma"])}
                for k, v in self.parameters.items()
            },
            "rejected_fraction": float(self.rejected_fraction),
            "model_error_mag": float(self.model_error_mag),
            "consistent": not bool(self.none_fits),
            "symmetry": self.symmetry,
            "runtime_s": float(self.runtime_s),
            **(self.attitude_mode or {}),
        }


def make_result(
    ctx: Context,
    *,
    name: str,
    probabilities: np.ndarray,
    none_fits: bool,
    q: np.ndarray,
    omega: np.ndarray,
    covariance: np.ndarray,
    estimates: pd.DataFrame,
    group: SymmetryGroup,
    modes: list[dict[str, Any]] | None = None,
    parameters: dict[str, dict[str, float]] | None = None,
) -> InversionResult:
    """The result of a run: the final state ``q, omega`` (rad/s) with its covariance of
    ``[δθ (rad), ω (rad/s)(, …)]``, the shape ``name`` and ``probabilities`` (one per
    candidate shape, in ``ctx.names`` order), the per-epoch table and the notes so far."""
    used = ~estimates["gated"].to_numpy(dtype=bool)
    residuals = estimates["residual"].to_numpy()[used]
    rms = float(np.sqrt(np.mean(residuals**2))) if residuals.size else math.nan
    noise = float(np.sqrt(np.mean(ctx.model.errors[used] ** 2))) if residuals.size else math.nan
    sigma_att = math.degrees(math.sqrt(max(float(np.trace(covariance[:3, :3])), 0.0)))
    if sigma_att > 10.0:
        ctx.notes.append(f"weakly observable: final attitude 1σ is {sigma_att:.1f}°")
    return InversionResult(
        method=ctx.method,
        shape=name,
        shape_probabilities={k: float(v) for k, v in zip(ctx.names, probabilities, strict=True)},
        none_fits=bool(none_fits),
        epoch_mjd=float(ctx.model.mjd[-1]),
        quaternion=quaternion_canonical(np.asarray(q, dtype=float)),
        omega_rad_s=np.asarray(omega, dtype=float),
        attitude_sigma_deg=sigma_att,
        omega_sigma_rad_s=np.sqrt(np.clip(np.diag(covariance)[3:6], 0.0, None)),
        modes=modes or [],
        residual_rms_mag=rms,
        n_measurements=len(ctx.model),
        estimates=estimates,
        notes=ctx.notes,
        parameters=parameters or {},
        symmetry=group.to_dict(),
        covariance=np.asarray(covariance, dtype=float)[:6, :6],
        runtime_s=time.perf_counter() - ctx.start,
        model_error_mag=math.sqrt(max(rms**2 - noise**2, 0.0)),
    )


def unknown_state_uncertainty(ctx: Context, result: InversionResult) -> None:
    """Give an answer that no candidate fits (``none_fits``) and whose model does not
    explain the data (``model_error_mag`` above ``model_tolerance_mag``) the uncertainty of
    an unknown state, in its summary and in every row of its table.

    The local 1σ of a fit bounds its error only when the model explains the data: the best
    fit of a model that does not (a real object is never exactly its library model) can end
    in any basin, and on such objects the search's and the filters' answers were measured
    60–150° off with a local 1σ of 1–5°. The reported uncertainty is then that of an
    attitude distributed uniformly on SO(3) (:data:`UNKNOWN_ATTITUDE_VARIANCE` per axis) and
    of rates uniform in the search's ball ``|ω| ≤ omega_max`` (``omega_max²/5`` per axis);
    the local 1σ is kept in the notes. An answer flagged only by a filter's consistency
    window while its fit leaves the residuals at the noise (the PF raised such false alarms
    on 6 of 20 exact-model runs, all within 5°) keeps its local 1σ.
    """
    if not result.none_fits:
        return
    misfit = result.model_error_mag
    if misfit <= ctx.options.model_tolerance_mag:
        result.notes.append(
            f"flagged by the consistency window, but the fit leaves {misfit:.3f} mag beyond "
            "the measurement errors: the local 1σ is kept"
        )
        return
    local = result.attitude_sigma_deg
    variance = np.array([UNKNOWN_ATTITUDE_VARIANCE] * 3 + [ctx.omega_max**2 / 5.0] * 3)
    sigma = np.sqrt(variance)
    result.covariance = np.diag(variance)
    result.attitude_sigma_deg = math.degrees(math.sqrt(variance[:3].sum()))
    result.omega_sigma_rad_s = sigma[3:].copy()
    for i, axis in enumerate("xyz"):
        result.estimates[f"sigma_att_{axis}"] = math.degrees(sigma[i])
        result.estimates[f"sigma_w{axis}"] = sigma[3 + i]
    result.notes.append(
        f"no candidate fits: the local 1σ of the best fit ({local:.2f}°) does not bound its "
        "error, so the state is reported with the uncertainty of an unknown one (attitude "
        "uniform on SO(3), rates uniform within omega_max)"
    )
