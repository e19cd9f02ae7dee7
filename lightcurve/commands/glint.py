"""Glint analysis of a light curve (Gou et al. 2016, sec. 2.2).

Detects specular flashes above a smooth baseline (a local cubic that follows the bend of
a curve fading towards the terminator) at a stated false-alarm probability, and gives for
each glint its epoch (with 1σ error), brightening and the phase-angle bisector (PAB)
direction in the file's inertial frame. With three or more glints
the glint-to-glint spin period of a tumbler is estimated. With --normal the glints are taken
as flashes of one flat panel and its least-squares normal is estimated: inertially fixed
(--frame inertial) or fixed in the body (--frame body, using the file's attitude columns
q1..q4 — e.g. a nadir-pointing satellite's known attitude).

Prints a summary; with --out writes OUT/glints.json and OUT/glints.csv.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd

from lightcurve import io
from lightcurve.atomic import atomic_write_json, atomic_write_table, json_ready

NAME = "glint"
HELP = "detect glints: epochs, PAB directions, panel normal, glint-spacing period"
ORDER = 41


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("file", metavar="FILE", help="observation file")
    parser.add_argument(
        "--window",
        type=float,
        metavar="SECONDS",
        help="baseline window, s (default: 4 x --max-flash; flashes must be shorter than a "
        "quarter of it)",
    )
    parser.add_argument(
        "--max-flash",
        type=float,
        metavar="SECONDS",
        help="longest flash to be found, s; sets the default window (default: a sixteenth "
        "of the span)",
    )
    parser.add_argument(
        "--degree",
        type=int,
        choices=(0, 1, 2, 3),
        default=3,
        help="degree of the local polynomial baseline (default 3; 1: running straight line)",
    )
    parser.add_argument(
        "--false-alarm",
        type=float,
        default=1e-3,
        help="probability of a detection in a glint-free light curve (default 1e-3)",
    )
    parser.add_argument(
        "--normal", action="store_true", help="estimate one panel's normal from the glints"
    )
    parser.add_argument(
        "--frame",
        choices=("inertial", "body"),
        default="inertial",
        help="frame in which the panel is fixed (body: needs q1..q4 columns)",
    )
    parser.add_argument("--out", type=Path, help="output folder")


def run(args: argparse.Namespace) -> int:
    from lightcurve.glint import detect_glints, glint_period, panel_normal

    obs = io.read(args.file)
    detection = detect_glints(
        obs,
        window_s=args.window,
        false_alarm=args.false_alarm,
        max_flash_s=args.max_flash,
        degree=args.degree,
    )
    glints = detection.glints
    summary = {
        "file": str(args.file),
        "false_alarm": detection.false_alarm,
        "threshold_sigma": detection.threshold_sigma,
        "noise_mag": detection.noise_mag,
        "window_s": detection.window_s,
        "baseline_degree": detection.degree,
        "glints": [g.summary() for g in glints],
    }
    estimate = glint_period(glints)
    if estimate is not None:
        summary["glint_period_s"], summary["glint_period_sigma_s"] = estimate
    lines = [
        f"{len(glints)} glint(s) above {detection.threshold_sigma:.2f} sigma "
        f"(noise {detection.noise_mag:.3g} mag, false-alarm {detection.false_alarm:g})"
    ]
    if args.normal and glints:
        attitudes = None
        if args.frame == "body":
            if not obs.has_truth:
                raise ValueError(f"{args.file}: --frame body needs the attitude columns q1..q4")
            q = obs.truth[:, :4]
            attitudes = [q[int(np.argmin(np.abs(obs.times - g.time_s)))] for g in glints]
        normal = panel_normal(glints, attitudes)
        summary["panel_normal"] = {"frame": args.frame, **normal.summary()}
        n = normal.summary()
        lines.append(
            f"panel normal ({args.frame}) lon {n['lon_deg']:.2f} deg, lat {n['lat_deg']:.2f} "
            f"deg, sigma {n['sigma_deg']:.2g} deg from {normal.n_glints} glint(s)"
        )
    if estimate is not None:
        lines.append(f"glint-to-glint period {estimate[0]:.6g} ± {estimate[1]:.2g} s")
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        atomic_write_json(args.out / "glints.json", json_ready(summary))
        table = pd.DataFrame(
            [{k: v for k, v in g.summary().items() if k != "pab"} for g in glints],
            columns=[
                "mjd",
                "time_s",
                "sigma_time_s",
                "amplitude_mag",
                "significance",
                "duration_s",
                "pab_lon_deg",
                "pab_lat_deg",
            ],
        )
        atomic_write_table(table, args.out / "glints.csv")
    print("\n".join(lines))
    return 0
