"""The figures of a monocular study: errors, convergence, Monte Carlo table, summary,
estimates table, plots and console lines (Deng et al. 2024, figs. 3–6).

Every function reads the run record :class:`lightcurve.studies.monocular_definition.Study`;
all are importable from :mod:`lightcurve.studies.monocular`.
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from filters.attitude import attitude_angle, inertia_from_tanh, normalized_from_inertia
from filters.navigation.monocular import InertiaForm, observability_at, trajectory_information
from filters.planning.observability import information_sigmas
from lightcurve.io.atomic import atomic_path
from lightcurve.studies.monocular_definition import L_NAMES, Study


def normalized_parameters(form: InertiaForm, p: np.ndarray) -> np.ndarray:
    """``l = [Lxx, Lyy, Lxy, Lxz, Lyz]`` of the form's parameters (any leading shape)."""
    if form.name == "L":
        return np.asarray(p)
    return np.asarray(normalized_from_inertia(inertia_from_tanh(p)))


def _normalized_sigma(form: InertiaForm, p: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """One-sigma of ``l`` by first-order propagation of the parameter covariance."""
    if form.name == "L":
        return np.sqrt(np.diag(cov))
    import torch
    from torch.func import jacfwd

    jac = jacfwd(lambda k: normalized_from_inertia(inertia_from_tanh(k)))(torch.as_tensor(p))
    jac = jac.numpy()
    return np.sqrt(np.diag(jac @ cov @ jac.T))


def error_series(study: Study) -> dict[str, np.ndarray]:
    """Attitude (deg), relative rate and max inertia errors over time, shape ``(K, runs)``."""
    states = study.history.states
    form = study.scenario.form
    att = np.degrees(np.asarray(attitude_angle(states[..., :4], study.truth_q[:, None])))
    rate = np.linalg.norm(states[..., 4:7] - study.truth_omega[:, None], axis=-1)
    rate_rel = rate / np.linalg.norm(study.truth_omega, axis=-1)[:, None]
    l_true = normalized_parameters(form, study.truth_p)
    l_err = normalized_parameters(form, states[..., 7:]) - l_true
    return {"attitude_deg": att, "rate": rate, "rate_fraction": rate_rel, "inertia": l_err}


def convergence(study: Study) -> dict[str, Any]:
    """Per-run success at the end and the time from which the criteria hold for good."""
    c = study.scenario.criteria
    err = error_series(study)
    ok = (
        (err["attitude_deg"] < c.attitude_deg)
        & (err["rate_fraction"] < c.rate_fraction)
        & (np.max(np.abs(err["inertia"]), axis=-1) < c.inertia)
    )
    last_bad = np.array(
        [np.flatnonzero(~ok[:, i])[-1] if np.any(~ok[:, i]) else -1 for i in range(ok.shape[1])]
    )
    t = study.times
    settle = np.where(last_bad + 1 < t.size, t[np.minimum(last_bad + 1, t.size - 1)], np.nan)
    return {"success": ok[-1], "converged_after_s": settle, "errors": err}


def _rms(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(values))))


def monte_carlo_table(study: Study) -> dict[str, Any]:
    """Success rate and RMS of the final errors over the runs."""
    conv = convergence(study)
    err = conv["errors"]
    settle = conv["converged_after_s"]
    c = study.scenario.criteria
    return {
        "runs": int(err["attitude_deg"].shape[1]),
        "success_rate": float(np.mean(conv["success"])),
        "criteria": {
            "attitude_deg": c.attitude_deg,
            "rate_fraction": c.rate_fraction,
            "inertia": c.inertia,
        },
        "rms": {
            "attitude_deg": _rms(err["attitude_deg"][-1]),
            "omega_rad_s": _rms(err["rate"][-1]),
            "omega_percent": 100 * _rms(err["rate_fraction"][-1]),
            **{name: _rms(err["inertia"][-1, :, i]) for i, name in enumerate(L_NAMES)},
        },
        "max": {
            "attitude_deg": float(np.max(err["attitude_deg"][-1])),
            "omega_percent": 100 * float(np.max(err["rate_fraction"][-1])),
            "inertia": float(np.max(np.abs(err["inertia"][-1]))),
        },
        "converged_after_s": {
            "median": float(np.nanmedian(settle)) if np.any(np.isfinite(settle)) else None,
            "max": float(np.max(settle)) if np.all(np.isfinite(settle)) else None,
        },
    }


def summarize(study: Study, seed: int) -> dict[str, Any]:
    """The ``summary.json`` content (the key names are a contract, see the docs)."""
    sc = study.scenario
    form = sc.form
    hist = study.history
    x_end, p_end = hist.states[-1, 0], hist.covariances[-1, 0]
    l_end = normalized_parameters(form, x_end[7:])
    l_sigma = _normalized_sigma(form, x_end[7:], p_end[6:, 6:])
    truth_known = study.truth_q is not None
    if truth_known:
        x_obs = np.concatenate([study.truth_q[0], study.truth_omega[0], study.truth_p])
        where = "true state at t = 0"
    else:
        x_obs, where = x_end, "final estimate"
    start = time.perf_counter()
    rank = observability_at(x_obs, form, sc.max_order, sc.rtol)
    seconds = {"observability_s": time.perf_counter() - start}
    start = time.perf_counter()
    sigma_qv = math.sqrt(float(np.mean(np.diag(sc.r))))
    finite = np.isfinite(study.measurements[:, 0, 0])
    info = trajectory_information(hist.states[finite, 0], study.times[finite], sigma_qv, form)
    crlb = information_sigmas(info)
    seconds["information_s"] = time.perf_counter() - start
    crlb_l = (
        crlb[6:]
        if form.name == "L"
        else _normalized_sigma(form, x_end[7:], np.linalg.pinv(info)[6:, 6:])
    )
    window = study.times >= study.times[-1] - sc.criteria.settle_fraction * (
        study.times[-1] - study.times[0]
    )
    l_hist = normalized_parameters(form, hist.states[window, 0, 7:])
    drift = float(np.max(np.abs(l_hist - l_end)))
    tol = sc.criteria.inertia
    crlb_ok = bool(np.all(np.isfinite(crlb_l)) and np.all(crlb_l < tol))
    converged = bool(rank.full and crlb_ok and drift < tol)
    summary: dict[str, Any] = {
        "scenario": sc.name,
        "inertia_form": form.name,
        "measurement_mode": "external" if study.external else sc.mode,
        "seed": seed,
        "run_length_s": float(study.times[-1] - study.times[0]),
        "epochs": int(study.times.size),
        "observability_rank": rank.rank,
        "observability_states": list(form.state_names),
        "observability_singular_values": rank.singular_values.tolist(),
        "observability_tolerance": rank.tolerance,
        "observability_order": rank.order,
        "observability_evaluated_at": where,
        "L": l_end.tolist(),
        "L_sigma": l_sigma.tolist(),
        "L_crlb": [float(v) if np.isfinite(v) else None for v in crlb_l],
        "inertia_drift_last_window": drift,
        "omega_rad_s": x_end[4:7].tolist(),
        "quaternion": x_end[:4].tolist(),
        "converged": converged,
        "nis_mean": float(np.nanmean(hist.nis[:, 0])),
    }
    if form.name == "k":
        summary["k"] = x_end[7:].tolist()
        summary["k_sigma"] = np.sqrt(np.diag(p_end[6:, 6:])).tolist()
    if not rank.full:
        summary["unobservable_directions"] = rank.unobservable_directions(form.state_names, 1e-6)
    if not converged:
        summary["assessment"] = _weakness(rank, crlb_l, drift, tol, form)
    if truth_known:
        conv = convergence(study)
        err = conv["errors"]
        summary["attitude_error_deg"] = float(err["attitude_deg"][-1, 0])
        summary["omega_error_rad_s"] = float(err["rate"][-1, 0])
        summary["omega_error_percent"] = 100 * float(err["rate_fraction"][-1, 0])
        summary["L_error"] = err["inertia"][-1, 0].tolist()
        summary["L_true"] = normalized_parameters(form, study.truth_p).tolist()
        summary["success"] = bool(conv["success"][0])
        settle = conv["converged_after_s"][0]
        summary["converged_after_s"] = None if not np.isfinite(settle) else float(settle)
        if hist.states.shape[1] > 1:
            summary["monte_carlo"] = monte_carlo_table(study)
    if study.measurement_info:
        summary["pixels"] = study.measurement_info
    summary["seconds"] = {**study.seconds, **seconds}
    return summary


def _weakness(rank: Any, crlb: np.ndarray, drift: float, tol: float, form: InertiaForm) -> str:
    parts = []
    if not rank.full:
        parts.append(
            f"observability rank {rank.rank} < {len(form.state_names)}: the unobservable "
            "directions cannot be estimated from attitude measurements"
        )
    names = [n for n, s in zip(L_NAMES, crlb, strict=True) if not (np.isfinite(s) and s < tol)]
    if names:
        parts.append(
            f"Cramér–Rao bound above {tol} for {', '.join(names)} along the estimated trajectory"
        )
    if drift >= tol:
        parts.append(f"inertia estimates still moving ({drift:.3g} over the last window)")
    return "weakly observable, no inertia result claimed: " + "; ".join(parts)


def estimates_table(study: Study) -> pd.DataFrame:
    """Estimates, one-sigma values, NIS, measurements and (when known) truth, all runs."""
    hist = study.history
    k, runs = hist.states.shape[:2]
    form = study.scenario.form
    cols: dict[str, np.ndarray] = {
        "run": np.repeat(np.arange(runs)[None], k, 0),
        "t": np.repeat(study.times[:, None], runs, 1),
    }
    names = ["q1", "q2", "q3", "q4", "wx", "wy", "wz", *form.parameter_names]
    for i, name in enumerate(names):
        cols[name] = hist.states[..., i]
    for i, name in enumerate(form.state_names):
        cols[f"sigma_{name}"] = hist.sigmas[..., i]
    cols["nis"] = hist.nis
    for i in range(4):
        cols[f"z_q{i + 1}"] = study.measurements[..., i]
    if study.truth_q is not None:
        for i in range(4):
            cols[f"true_q{i + 1}"] = np.repeat(study.truth_q[:, i, None], runs, 1)
        for i, axis in enumerate("xyz"):
            cols[f"true_w{axis}"] = np.repeat(study.truth_omega[:, i, None], runs, 1)
    return pd.DataFrame({key: np.asarray(v).T.ravel() for key, v in cols.items()})


def write_figures(study: Study, out: Path, prefix: str = "") -> list[Path]:
    """Figures like the paper's figs. 3–6 (run 0) and the Monte Carlo error envelopes.

    Writes ``quaternion.png``, ``rates.png``, ``inertia.png`` and, with a truth,
    ``errors.png`` into ``out``, each name preceded by ``prefix``.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    hist, t = study.history, study.times
    form = study.scenario.form
    truth = study.truth_q is not None
    written = []

    def save(fig: Any, name: str) -> None:
        with atomic_path(out / (prefix + name), suffix=".png") as tmp:
            fig.savefig(tmp, format="png", dpi=110)
        plt.close(fig)
        written.append(out / (prefix + name))

    fig, axes = plt.subplots(4, 1, sharex=True, figsize=(7, 7))
    for i, ax in enumerate(axes):
        if truth:
            ax.plot(t, study.truth_q[:, i], "r-", lw=1.2, label="truth")
        ax.plot(t, hist.states[:, 0, i], "b-", lw=0.8, label="estimate")
        ax.set_ylabel(f"q{i + 1}")
    axes[0].legend(loc="upper right")
    axes[-1].set_xlabel("time (s)")
    fig.suptitle("Relative attitude quaternion (cf. Deng et al. 2024, fig. 3)")
    save(fig, "quaternion.png")

    fig, axes = plt.subplots(3, 1, sharex=True, figsize=(7, 6))
    for i, ax in enumerate(axes):
        if truth:
            ax.plot(t, np.degrees(study.truth_omega[:, i]), "r-", lw=1.2, label="truth")
        ax.plot(t, np.degrees(hist.states[:, 0, 4 + i]), "b-", lw=0.8, label="estimate")
        ax.set_ylabel(f"ω{'xyz'[i]} (°/s)")
    axes[0].legend(loc="upper right")
    axes[-1].set_xlabel("time (s)")
    fig.suptitle("Body rates (cf. Deng et al. 2024, fig. 4)")
    save(fig, "rates.png")

    m = form.size
    fig, axes = plt.subplots(m, 1, sharex=True, figsize=(7, 1.5 * m + 1.5))
    for i, ax in enumerate(np.atleast_1d(axes)):
        est, sig = hist.states[:, 0, 7 + i], hist.sigmas[:, 0, 6 + i]
        ax.fill_between(t, est - 3 * sig, est + 3 * sig, color="b", alpha=0.12, lw=0, label="±3σ")
        if truth:
            ax.axhline(study.truth_p[i], color="r", lw=1.2, label="truth")
        ax.plot(t, est, "b-", lw=0.8, label="estimate")
        span = 0.6 if not truth else 0.3 + abs(study.truth_p[i])
        centre = study.truth_p[i] if truth else est[-1]
        ax.set_ylim(centre - span, centre + span)
        ax.set_ylabel(form.parameter_names[i])
    np.atleast_1d(axes)[0].legend(loc="upper right", ncol=3)
    np.atleast_1d(axes)[-1].set_xlabel("time (s)")
    fig.suptitle("Inertia parameters (cf. Deng et al. 2024, figs. 5–6)")
    save(fig, "inertia.png")

    if truth:
        err = error_series(study)
        c = study.scenario.criteria
        fig, axes = plt.subplots(3, 1, sharex=True, figsize=(7, 7))
        series = [
            (err["attitude_deg"], c.attitude_deg, "attitude error (°)"),
            (100 * err["rate_fraction"], 100 * c.rate_fraction, "rate error (% of |ω|)"),
            (np.max(np.abs(err["inertia"]), axis=-1), c.inertia, "max |L error|"),
        ]
        for ax, (values, limit, label) in zip(axes, series, strict=True):
            ax.semilogy(t, values, lw=0.5, alpha=0.5)
            ax.axhline(limit, color="k", ls="--", lw=1)
            ax.set_ylabel(label)
        axes[-1].set_xlabel("time (s)")
        fig.suptitle(f"Errors of {values.shape[1]} run(s); dashed: success thresholds")
        save(fig, "errors.png")
    return written


def print_summary(summary: dict[str, Any]) -> None:
    """Print the headline figures of a :func:`summarize` result (the command's console output)."""
    lines = [
        f"{summary['scenario']}: observability rank {summary['observability_rank']}"
        f"/{len(summary['observability_states'])} (order {summary['observability_order']})",
        f"L = {np.round(summary['L'], 4).tolist()} ± {np.round(summary['L_sigma'], 4).tolist()}",
        f"converged: {summary['converged']}",
    ]
    if "assessment" in summary:
        lines.append(summary["assessment"])
    if "attitude_error_deg" in summary:
        lines.append(
            f"final errors: attitude {summary['attitude_error_deg']:.3f} deg, rate "
            f"{summary['omega_error_percent']:.2f} %, max |L| "
            f"{max(abs(v) for v in summary['L_error']):.4f}"
        )
    if "monte_carlo" in summary:
        mc = summary["monte_carlo"]
        lines.append(f"Monte Carlo: {mc['runs']} runs, success rate {mc['success_rate']:.2f}")
        lines.append("RMS: " + json.dumps({k: round(v, 5) for k, v in mc["rms"].items()}))
    print("\n".join(lines))
