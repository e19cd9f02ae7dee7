"""Invert observation files for attitude, rates and shape, in batch.

INPUT is any number of observation files (CSV, Parquet, DAMIT text) or folders of them. For
each input the result goes to DIR/<input stem>/: summary.json (shape, probabilities,
attitude and rates at the last epoch with 1-sigma, PF modes, residual rms, status) and
estimates.parquet (per-epoch estimates, covariance diagonal, predicted magnitude, residual,
model probabilities). DIR/summary.csv has one row per input, failures included.

The candidate shapes come from --shape, --shapes or --all-shapes; without them each file's
'# shape: NAME' header names its shape, and a header naming a shape the library does not
have makes that input an error (with candidates given, the header's shape is not used).

The batch is resumable: inputs whose summary says "ok" are skipped unless --overwrite; all
outputs are written atomically and a bad input is recorded as an error without stopping
the batch. --estimate chooses the model adjustments (inertia, principal-axis tilt,
albedo-area scale, stretch, materials) fitted with the state on the whole arc by ukf and
mmae; summary.json then holds them under 'parameters' with their 1-sigma, the rms model
error ('model_error_mag'), the fraction of measurements the filters' gate rejected and
whether the candidate is consistent with the data. --modes adds the attitude mode
(stabilised profile or tumbling, its probability and the fitted offsets;
docs/inversion.md). A big shape is rendered through its level-of-detail proxy when the
proxy's light-curve error is below the data's noise (--full-mesh: never); summary key
'shape_model' names the model used. --workers runs inputs in parallel processes;
--scheduler sends the same work to a Dask distributed cluster (workers must see the same
file system).
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from lightcurve.commands._args import (
    add_progress_option,
    adjustment_list,
    float_vector,
    show_progress,
    unit_quaternion,
)

NAME = "invert"
HELP = "invert observation files for attitude, rates and shape (batch, resumable)"
ORDER = 30


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("inputs", nargs="+", metavar="INPUT", help="files or folders")
    parser.add_argument(
        "--library",
        metavar="DIR",
        help="shape library folder (default: $LIGHTCURVE_LIBRARY or built-in)",
    )
    which = parser.add_mutually_exclusive_group()
    which.add_argument(
        "--shape", help="one candidate shape (default: the shape each file's header names)"
    )
    which.add_argument(
        "--shapes", metavar="A,B,…", help="comma-separated candidate shapes (default: as --shape)"
    )
    which.add_argument("--all-shapes", action="store_true", help="every shape of the library")
    parser.add_argument(
        "--method",
        choices=("ukf", "mmae", "pf"),
        required=True,
        help="ukf: one shape, attitude UKF; mmae: a bank of UKFs, one per shape; pf: particle "
        "filter over attitude, rates and shape",
    )
    parser.add_argument(
        "--q0",
        type=unit_quaternion,
        metavar="q1,q2,q3,q4",
        help="initial attitude guess at the first epoch, inertial→body (default: searched "
        "over all attitudes)",
    )
    parser.add_argument(
        "--omega0",
        type=float_vector(3),
        metavar="wx,wy,wz",
        help="initial body-rate guess, deg/s (default: searched within --omega-max)",
    )
    parser.add_argument(
        "--attitude-sigma-deg",
        type=float,
        metavar="S",
        help="1-sigma of the initial attitude guess, deg (default: 20)",
    )
    parser.add_argument(
        "--omega-sigma",
        type=float,
        metavar="S",
        help="1-sigma of the initial rate guess, deg/s (default: 0.2)",
    )
    parser.add_argument(
        "--omega-max",
        type=float,
        metavar="W",
        help="bound on |omega| for the PF / global search, deg/s (default: 5)",
    )
    parser.add_argument(
        "--init",
        choices=("search", "none"),
        default="search",
        help="search: find the initial state (around --q0/--omega0 when given, else "
        "globally); none (ukf, mmae): start the filters at --q0 and --omega0 (zero rates "
        "without it) with their 1-sigma",
    )
    parser.add_argument(
        "--modes",
        action="store_true",
        help="also weigh stabilised attitude profiles (inertial, nadir, nadir yaw-steering, "
        "sun-pointing, each with fitted offsets) against tumbling: summary keys "
        "attitude_mode, attitude_mode_probability, attitude_offsets_deg",
    )
    parser.add_argument(
        "--mode-weak-sigma",
        type=float,
        metavar="DEG",
        help="with --modes: a direction of a fitted offset whose 1-sigma exceeds DEG is "
        "reported as a weak axis with its 95%% interval, deg (default: 1)",
    )
    parser.add_argument(
        "--estimate",
        type=adjustment_list,
        metavar="LIST",
        help="ukf, mmae: model adjustments fitted with the state on the whole arc, "
        "comma-separated from inertia, tilt, scale, stretch, material, or 'none' (default: "
        "inertia,scale); summary key 'parameters' holds them with 1-sigma",
    )
    parser.add_argument(
        "--model-tolerance",
        type=float,
        metavar="MAG",
        help="ukf, mmae: rms model error (mag, beyond the measurement errors) above which a "
        "candidate does not fit (default: 0.03)",
    )
    parser.add_argument(
        "--rescue",
        type=int,
        metavar="N",
        help="ukf, mmae: when no candidate fits, continue the N best initial fits of each "
        "candidate to the whole arc again with the --rescue-estimate adjustments; slower "
        "(10-60 s per candidate) (default: 0, off)",
    )
    parser.add_argument(
        "--rescue-estimate",
        type=adjustment_list,
        metavar="LIST",
        help="ukf, mmae: the adjustments of the rescue fit, as --estimate (default: "
        "inertia,scale,material)",
    )
    parser.add_argument(
        "--particles", type=int, metavar="N", help="particle count (pf) (default: 2000)"
    )
    parser.add_argument("--seed", type=int, default=0, help="random seed")
    parser.add_argument("--workers", type=int, default=1, metavar="N", help="parallel processes")
    parser.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="Dask distributed scheduler address, e.g. tcp://host:8786 (default: local processes)",
    )
    parser.add_argument(
        "--full-mesh",
        action="store_true",
        help="render every candidate with its full mesh (default: a shape's level-of-detail "
        "proxy when its stored light-curve error is below the file's median mag_err; "
        "summary key shape_model says which)",
    )
    parser.add_argument("--overwrite", action="store_true", help="redo finished inputs")
    parser.add_argument(
        "--drop-bad-rows",
        action="store_true",
        help="drop invalid rows of an input instead of failing it",
    )
    add_progress_option(parser, "the files and of the steps inside each (one worker)")
    parser.add_argument("--out", required=True, metavar="DIR", help="result folder")


def run(args: argparse.Namespace) -> int:
    from lightcurve.batch import run_batch
    from lightcurve.inversion import InversionOptions
    from lightcurve.pipeline import (
        SUMMARY_KEYS,
        InvertJob,
        check_request,
        invert_file,
        resolve_shapes,
    )

    names = resolve_shapes(
        args.library, args.shape, args.shapes and args.shapes.split(","), args.all_shapes
    )
    if not args.workers > 0:
        raise ValueError(f"--workers must be positive, got {args.workers}")
    deg = np.deg2rad
    job = InvertJob(
        method=args.method,
        shape_names=names,
        library=args.library,
        q0=args.q0,
        omega0_rad_s=None if args.omega0 is None else deg(args.omega0),
        attitude_sigma_deg=args.attitude_sigma_deg,
        omega_sigma_rad_s=None if args.omega_sigma is None else float(deg(args.omega_sigma)),
        omega_max_rad_s=None if args.omega_max is None else float(deg(args.omega_max)),
        particles=args.particles,
        seed=args.seed,
        modes=args.modes,
        drop_bad_rows=args.drop_bad_rows,
        full_mesh=args.full_mesh,
    )
    # Options left unset keep the library's defaults.
    tuning = {
        "init": args.init,
        "mode_weak_sigma_deg": args.mode_weak_sigma,
        "estimate": args.estimate,
        "model_tolerance_mag": args.model_tolerance,
        "rescue_starts": args.rescue,
        "rescue_estimate": args.rescue_estimate,
    }
    options = InversionOptions(**{k: v for k, v in tuning.items() if v is not None})
    # The library's own checks of the request, at start rather than once per input.
    check_request(job, options)
    template = dict.fromkeys(SUMMARY_KEYS)
    template.update(method=args.method, shape_probabilities={}, modes=[])
    table = run_batch(
        invert_file,
        args.inputs,
        args.out,
        options={"job": job, "options": options},
        overwrite=args.overwrite,
        workers=args.workers,
        scheduler=args.scheduler,
        progress=show_progress(args),
        job_progress=True,
        summary_columns=SUMMARY_KEYS,
        error_template=template,
    )
    ok = int((table["status"] == "ok").sum()) if len(table) else 0
    if not args.quiet:
        print(f"{args.out}: {ok} of {len(table)} input(s) inverted", file=sys.stderr)
    for _, row in table[table["status"] != "ok"].iterrows():
        print(f"  {row['input']}: {row['error']}", file=sys.stderr)
    return 0 if ok == len(table) else 1
