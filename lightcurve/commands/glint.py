"""Glint analysis of a light curve (Gou et al. 2016, sec. 2.2).

Detects specular flashes above a smooth baseline (a local cubic that follows the bend of
a curve fading towards the terminator) at a stated false-alarm probability, and gives for
each glint its epoch (with 1σ error), brightening and the phase-angle bisector (PAB)
direction in the file's inertial frame. With three or more glints
the glint-to-glint spin period of a tumbler is estimated. With --normal the glints are taken
as flashes of one flat panel and its least-squares normal is estimated: inertially fixed
(--frame inertial) or fixed in the body (--frame body, using the file's attitude columns
q1..q4 — e.g. a nadir-pointing satellite's known attitude). With --profile the object is
taken as held in a known attitude profile (inertial, nadir with optional --yaw-steering,
sun-pointing; the obj_* columns that `lightcurve geometry` writes for nadir) with a fixed
--offset-deg ROLL,PITCH,YAW (as `simulate`, and as `invert --modes` reports it): each glint's
bisector is turned into the body frame with the profile's attitude at its epoch; glints
within --panel-tolerance of each other are taken as one panel, whose weighted mean is its
normal in the body frame. The summary gives normal_body and normal_body_spread_deg (the
panel of the brightest glint) and every panel under normal_body_panels.

Prints a summary; with --out writes OUT/glints.json and OUT/glints.csv.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from lightcurve.commands._args import add_false_alarm_option, float_vector
from lightcurve.commands._source import literal

NAME = "glint"
HELP = "detect glints: epochs, PAB directions, panel normal, glint-spacing period"
ORDER = 41
#: glints.csv columns of each glint's body-frame bisector (with --profile).
NORMAL_BODY_COLUMNS = ("normal_body_x", "normal_body_y", "normal_body_z")


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
        help="degree of the local polynomial baseline (1: running straight line)",
    )
    add_false_alarm_option(parser, "probability of a detection in a glint-free light curve")
    parser.add_argument(
        "--normal", action="store_true", help="estimate one panel's normal from the glints"
    )
    parser.add_argument(
        "--frame",
        choices=("inertial", "body"),
        default="inertial",
        help="frame in which the panel is fixed (body: needs q1..q4 columns)",
    )
    parser.add_argument(
        "--profile",
        choices=literal("lightcurve.photometry.profiles", "STABILISED_PROFILES"),
        help="known attitude profile: report the glints' panel normal in the body frame "
        "(normal_body)",
    )
    parser.add_argument(
        "--offset-deg",
        type=float_vector(3),
        metavar="ROLL,PITCH,YAW",
        help="fixed 3-2-1 offset of --profile from its frame, deg (default: 0,0,0; for "
        "inertial: the attitude's angles from the inertial axes)",
    )
    parser.add_argument(
        "--yaw-steering",
        action="store_true",
        help="--profile nadir: yawed about the nadir axis to keep the Sun in the body x-z plane",
    )
    parser.add_argument(
        "--panel-tolerance",
        type=float,
        default=5.0,
        metavar="DEG",
        help="--profile: glints whose body-frame bisectors lie within this angle of a panel's "
        "mean are that panel's (default: 5)",
    )
    parser.add_argument(
        "--out", type=Path, metavar="DIR", help="output folder (default: print only)"
    )


def run(args: argparse.Namespace) -> int:
    import pandas as pd

    from lightcurve import io
    from lightcurve.analysis.glint import detect_glints, glint_period, panel_normal
    from lightcurve.analysis.glint.profile import body_normals
    from lightcurve.io.atomic import atomic_write_json, atomic_write_table, json_ready

    if args.profile is None and (args.offset_deg is not None or args.yaw_steering):
        raise ValueError("--offset-deg and --yaw-steering go with --profile")
    if not args.panel_tolerance > 0:
        raise ValueError(f"--panel-tolerance must be positive, got {args.panel_tolerance}")
    if args.yaw_steering and args.profile != "nadir":
        raise ValueError("--yaw-steering applies to --profile nadir only")
    if args.profile is not None and args.normal and args.frame == "body":
        raise ValueError("--profile gives the body attitude: not with --frame body")
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
    if args.profile is not None and glints:
        panels = body_normals(
            obs,
            glints,
            args.profile,
            offset_deg=args.offset_deg,
            yaw_steering=args.yaw_steering,
            tolerance_deg=args.panel_tolerance,
        )
        summary.update(
            attitude_profile={
                "profile": args.profile,
                "offset_deg": [0.0, 0.0, 0.0] if args.offset_deg is None else args.offset_deg,
                "yaw_steering": args.yaw_steering,
            },
            normal_body=panels[0].normal,
            normal_body_spread_deg=panels[0].spread_deg,
            normal_body_sigma_deg=panels[0].sigma_deg,
            normal_body_panels=[p.summary() for p in panels],
        )
        for index, panel in enumerate(panels):
            for row, direction in zip(panel.glints, panel.directions, strict=True):
                summary["glints"][row].update(normal_body=direction, panel=index)
        for index, panel in enumerate(panels):
            nx, ny, nz = panel.normal
            lines.append(
                f"panel {index} normal (body, --profile {args.profile}) "
                f"[{nx:.4f}, {ny:.4f}, {nz:.4f}], spread {panel.spread_deg:.2g} deg, "
                f"sigma {panel.sigma_deg:.2g} deg from {panel.n_glints} glint(s)"
            )
    elif args.profile is not None:
        lines.append(f"no glint: no panel normal for --profile {args.profile}")
    if estimate is not None:
        lines.append(f"glint-to-glint period {estimate[0]:.6g} ± {estimate[1]:.2g} s")
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        atomic_write_json(args.out / "glints.json", json_ready(summary))
        rows = [
            {**entry, **dict(zip(NORMAL_BODY_COLUMNS, entry.get("normal_body", ()), strict=False))}
            for entry in json_ready(summary["glints"])
        ]
        body_columns = [*NORMAL_BODY_COLUMNS, "panel"] if args.profile is not None else []
        table = pd.DataFrame(
            rows,
            columns=[
                "mjd",
                "time_s",
                "sigma_time_s",
                "amplitude_mag",
                "significance",
                "duration_s",
                "pab_lon_deg",
                "pab_lat_deg",
                *body_columns,
            ],
        )
        atomic_write_table(table, args.out / "glints.csv")
    print("\n".join(lines))
    return 0
