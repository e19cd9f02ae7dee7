"""Rotation-period search over one or more observation files (Gou et al. 2016, sec. 2.1).

A multi-harmonic Fourier series (orders 2-6, chosen by BIC) with one zero point per light
curve is fitted at every trial period; the χ² minimum is the period, its curvature gives the
1σ error, and the aliases (half and double period, daily aliases, other deep minima) are
listed with their Δχ² rather than hidden. With --pole the phase is measured from the
phase-angle bisector and the sidereal period is scanned. A glint-spacing period is added as a
cross-check with --glints when a light curve shows at least three glints.

Tumbling (non-principal-axis rotation): with --tumbling the two-period Fourier series is
searched as well; it is called tumbling when it beats one period by ΔBIC > 10 + 2 ln M (M
the trial second frequencies) with non-commensurate periods that one period changing with
the geometry does not explain. Keys periods_h, precession_period_h, rotation_period_h, mode,
reading_method (a tumbler's pair read by a convex facet model, or the amplitude rule),
tumbling, delta_bic, combinations; plot OUT/tumbling_periodogram.png. Without --tumbling
these keys are null, and a note suggests it when the files span at most HINT_SPAN_DAYS and
the one-period fit leaves residuals HINT_REDUCED_CHI2 times their stated variance (the
search is not run unasked: it takes a minute on a long night and its verdict is not yet
reliable on principal-axis rotators, docs/analysis.md).

Drift (--drift, several files = nights): one period (two with --tumbling) per file and a
linear (--quadratic: quadratic) fit through them; period_derivative_s_per_day, the table
OUT/night_periods.csv and the plot OUT/night_periods.png.

Writes OUT/summary.json (period_h, sigma_h, aliases, …), OUT/periodogram.csv and
OUT/periodogram.png.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from lightcurve.commands._args import (
    add_false_alarm_option,
    add_observation_files,
    add_output_folder,
    add_progress_option,
    float_vector,
    progress_bar,
)

NAME = "period"
#: Without --tumbling, a note suggests it when the files span at most this many days …
HINT_SPAN_DAYS = 2.0
#: … and the one-period fit's reduced χ² exceeds this.
HINT_REDUCED_CHI2 = 2.0
HELP = "rotation period: Fourier periodogram, aliases, sidereal correction, tumbling, drift"
ORDER = 40


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_observation_files(parser)
    parser.add_argument(
        "--range",
        nargs=2,
        type=float,
        metavar=("A", "B"),
        help="trial periods from A to B hours (default: 4 samples to the time span)",
    )
    parser.add_argument(
        "--orders",
        type=lambda text: [int(v) for v in text.split(",")],
        default=[2, 3, 4, 5, 6],
        metavar="K,K,…",
        help="harmonic orders tried",
    )
    parser.add_argument("--oversample", type=float, default=10.0, help="frequency oversampling")
    parser.add_argument(
        "--pole",
        type=float_vector(2),
        metavar="LAMBDA,BETA",
        help="spin axis, deg (frame of the files): scan the sidereal period (default: the "
        "synodic period)",
    )
    parser.add_argument(
        "--glints",
        action="store_true",
        help="cross-check with the glint-to-glint period (tumbling satellites)",
    )
    parser.add_argument(
        "--tumbling",
        action="store_true",
        help="search two periods (non-principal-axis rotation) whatever the one-period fit",
    )
    parser.add_argument(
        "--drift",
        action="store_true",
        help="one period per file (night) and its linear drift over the files",
    )
    parser.add_argument(
        "--quadratic", action="store_true", help="with --drift: fit a quadratic drift"
    )
    add_false_alarm_option(parser, "glint false-alarm probability for --glints")
    add_progress_option(parser, "the period scan")
    add_output_folder(parser)


def run(args: argparse.Namespace) -> int:
    import pandas as pd

    from lightcurve import io
    from lightcurve.analysis.glint import detect_glints, glint_period
    from lightcurve.analysis.period import period_search
    from lightcurve.io.atomic import atomic_write_json, atomic_write_table, json_ready

    if any(k < 1 for k in args.orders):
        raise ValueError(f"--orders must be positive integers, got {args.orders}")
    if args.quadratic and not args.drift:
        raise ValueError("--quadratic needs --drift")
    observations = [io.read(path) for path in args.files]
    pole = None if args.pole is None else tuple(np.radians(args.pole))
    with progress_bar(args, total=0, desc="period scan", unit="trial") as bar:

        def report(done: int, total: int) -> None:
            bar.total = total
            bar.update(done - bar.n)

        result = period_search(
            observations,
            args.range,
            orders=args.orders,
            oversample=args.oversample,
            pole=pole,
            progress=report,
        )
    summary = {"files": [str(p) for p in args.files], **result.summary()}
    glint_periods = []
    for obs in observations if args.glints else []:
        detection = detect_glints(obs, false_alarm=args.false_alarm)
        estimate = glint_period(detection.glints)
        if estimate is not None:
            glint_periods.append(
                {
                    "file": str(obs.source),
                    "glints": len(detection.glints),
                    "period_h": estimate[0] / 3600.0,
                    "sigma_h": estimate[1] / 3600.0,
                }
            )
    summary["glint_cross_check"] = glint_periods
    args.out.mkdir(parents=True, exist_ok=True)
    span_days = float(np.ptp(np.concatenate([o.mjd for o in observations])))
    summary.update(_tumbling(observations, args))
    if (
        not args.tumbling
        and span_days <= HINT_SPAN_DAYS
        and summary["reduced_chi2"] > HINT_REDUCED_CHI2
    ):
        summary["two_period_note"] = (
            f"one period leaves residuals {summary['reduced_chi2']:.3g} times their variance: "
            "a tumbler? try --tumbling"
        )
    if args.drift:
        summary.update(_drift(observations, args))
    atomic_write_json(args.out / "summary.json", json_ready(summary))
    table = pd.DataFrame({"period_h": result.periods_h, "chi2": result.chi2_curve})
    atomic_write_table(table.iloc[::-1].reset_index(drop=True), args.out / "periodogram.csv")
    _plot(result, args.out / "periodogram.png")
    kinds = ", ".join(f"{a['kind']} {a['period_h']:.6g} h" for a in result.aliases[:3])
    print(
        f"period {result.period_h:.8g} ± {result.sigma_h:.2g} h (order {result.order}, "
        f"{'sidereal' if result.sidereal else 'synodic'}); aliases: {kinds}"
    )
    return 0


def _tumbling(observations: list, args: argparse.Namespace) -> dict:
    """The two-period keys of the summary (null when --tumbling was not asked)."""
    from lightcurve.analysis.tumbling import tumbling_search

    if not args.tumbling:
        return {
            "tumbling": None,
            "delta_bic": None,
            "periods_h": None,
            "precession_period_h": None,
            "rotation_period_h": None,
            "mode": None,
            "reading_method": None,
            "reading_delta_chi2": None,
            "combinations": [],
        }
    result = tumbling_search(observations, args.range)
    _plot_two_periods(result, args.out / "tumbling_periodogram.png")
    summary = result.summary()
    periods = " and ".join(
        f"{p['period_h']:.6g} ± {p['sigma_h']:.2g} h" for p in summary["periods_h"]
    )
    verdict = "tumbling" if result.tumbling else "not tumbling"
    print(
        f"two periods {periods}: {verdict} (ΔBIC {result.delta_bic:.4g}, mode {summary['mode']}, "
        f"reading {summary['reading_method']})"
    )
    return summary


def _drift(observations: list, args: argparse.Namespace) -> dict:
    """Per-file periods, their drift, the table and the plot."""
    import pandas as pd

    from lightcurve.analysis.drift import period_drift
    from lightcurve.io.atomic import atomic_write_table

    nights, drifts = period_drift(
        observations,
        args.range,
        quadratic=args.quadratic,
        tumbling=args.tumbling,
        pole=None if args.pole is None else tuple(np.radians(args.pole)),
    )
    table = pd.DataFrame([vars(n) for n in nights])
    atomic_write_table(table, args.out / "night_periods.csv")
    _plot_drift(nights, drifts, args.out / "night_periods.png")
    for fit in drifts:
        print(
            f"drift ({fit.series}): {fit.period_derivative_s_per_day:.4g} ± "
            f"{fit.derivative_sigma_s_per_day:.2g} s/day"
        )
    first = drifts[0]
    return {
        "period_derivative_s_per_day": {
            "value": first.period_derivative_s_per_day,
            "sigma": first.derivative_sigma_s_per_day,
        },
        "drift": [fit.summary() for fit in drifts],
    }


def _figure():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path: Path) -> None:
    import matplotlib.pyplot as plt

    from lightcurve.io.atomic import atomic_path

    fig.tight_layout()
    with atomic_path(path, suffix=".png") as tmp:
        fig.savefig(tmp, format="png", dpi=100)
    plt.close(fig)


def _plot_two_periods(result, path: Path) -> None:
    """χ² of the coarse scan: trial second period (x) for each first period (rows)."""
    plt = _figure()
    fig, ax = plt.subplots(figsize=(8, 4))
    chi2 = np.where(np.isfinite(result.scan_chi2), result.scan_chi2, np.nan)
    image = ax.pcolormesh(
        result.scan_periods_h,
        np.arange(len(result.scan_first_h)),
        chi2,
        shading="nearest",
        cmap="viridis_r",
    )
    ax.set_yticks(np.arange(len(result.scan_first_h)))
    ax.set_yticklabels([f"{p:.4g}" for p in result.scan_first_h])
    ax.set_xscale("log")
    for p in result.periods_h:
        ax.axvline(p, color="C3", lw=0.8)
    ax.set_xlabel("second period (h)")
    ax.set_ylabel("first period (h)")
    ax.set_title(
        f"two periods {result.periods_h[0]:.5g}, {result.periods_h[1]:.5g} h "
        f"(ΔBIC {result.delta_bic:.3g})"
    )
    fig.colorbar(image, ax=ax, label="χ² (order 2, coarse points)")
    _save(fig, path)


def _plot_drift(nights, drifts, path: Path) -> None:
    """Per-night periods with 1σ bars (the fit's and the geometry's) and each fitted drift."""
    plt = _figure()
    fig, ax = plt.subplots(figsize=(8, 4))
    for k, fit in enumerate(drifts):
        rows = [n for n in nights if n.series == fit.series]
        mjd = np.array([n.mjd for n in rows])
        ax.errorbar(
            mjd,
            [n.period_h * 3600 for n in rows],
            yerr=[n.total_sigma_h * 3600 for n in rows],
            fmt="o",
            ms=3,
            color=f"C{k}",
            label=f"{fit.series}: {fit.period_derivative_s_per_day:.3g} s/day",
        )
        x = np.linspace(mjd.min(), mjd.max(), 100) - fit.reference_mjd
        curve = fit.period_h * 3600 + fit.period_derivative_s_per_day * x
        if fit.second_derivative_s_per_day2 is not None:
            curve = curve + 0.5 * fit.second_derivative_s_per_day2 * x**2
        ax.plot(x + fit.reference_mjd, curve, color=f"C{k}", lw=0.8)
    ax.set_xlabel("MJD")
    ax.set_ylabel("period (s)")
    ax.legend(loc="best")
    _save(fig, path)


def _plot(result, path: Path) -> None:
    plt = _figure()
    fig, ax = plt.subplots(figsize=(8, 4))
    ax.plot(result.periods_h, result.chi2_curve, lw=0.8)
    ax.axvline(result.period_h, color="C3", lw=0.8, label=f"P = {result.period_h:.6g} h")
    for alias in result.aliases[:4]:
        ax.axvline(alias["period_h"], color="0.6", lw=0.6, ls="--")
    ax.set_xlabel("period (h)")
    ax.set_ylabel(f"χ² (order {result.order})")
    ax.legend(loc="best")
    _save(fig, path)
