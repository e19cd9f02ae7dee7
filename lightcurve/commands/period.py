"""Rotation-period search over one or more observation files (Gou et al. 2016, sec. 2.1).

A multi-harmonic Fourier series (orders 2-6, chosen by BIC) with one zero point per light
curve is fitted at every trial period; the χ² minimum is the period, its curvature gives the
1σ error, and the aliases (half and double period, daily aliases, other deep minima) are
listed with their Δχ² rather than hidden. With --pole the phase is measured from the
phase-angle bisector and the sidereal period is scanned. A glint-spacing period is added as a
cross-check with --glints when a light curve shows at least three glints.

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
HELP = "rotation period: Fourier periodogram with aliases, sidereal correction"
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


def _plot(result, path: Path) -> None:
    import matplotlib

    from lightcurve.io.atomic import atomic_path

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 4))
    ax.plot(result.periods_h, result.chi2_curve, lw=0.8)
    ax.axvline(result.period_h, color="C3", lw=0.8, label=f"P = {result.period_h:.6g} h")
    for alias in result.aliases[:4]:
        ax.axvline(alias["period_h"], color="0.6", lw=0.6, ls="--")
    ax.set_xlabel("period (h)")
    ax.set_ylabel(f"χ² (order {result.order})")
    ax.legend(loc="best")
    fig.tight_layout()
    with atomic_path(path, suffix=".png") as tmp:
        fig.savefig(tmp, format="png", dpi=100)
    plt.close(fig)
