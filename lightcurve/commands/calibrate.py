"""Calibrate a library shape's photometry on observations of an object with a known profile.

FILE… are observation files of one object, or of a family of identical objects, whose
attitude follows a stabilised --profile (inertial at --q0, nadir with or without
--yaw-steering, or sun-pointing; nadir needs the obj_* columns of `lightcurve geometry` or
`import`). --fit chooses what is fitted: scale (a magnitude offset, the albedo–area
product), material (the BRDF parameters of every material, or those named by --parameters
GROUP.NAME,…), articulation (the joint offset of every moving part of an articulated shape,
e.g. how far a Sun-tracking array points from the Sun), offsets (a fixed roll, pitch, yaw of
the body from its profile). Below 27 970 km the model includes the Earth's reflected light
when the files carry the obj_* columns (--earthshine auto; off drops it). The fit is
robust (soft-L1 loss) with a prior about the library's values, so that a parameter the data
do not constrain stays there and is reported as unconstrained. --folds K cross-validates by
night (the nights of the files' sites, shuffled with --seed).

Writes OUT/summary.json (train_rms_mag, cv_rms_mag, cv_bias_mag, per-fold figures, the
parameters with 1σ, prior and whether the data constrain them, their correlations) and
OUT/calibration.json, which `lightcurve simulate --calibration FILE` applies.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from lightcurve.commands._args import (
    add_earthshine_option,
    add_observation_files,
    add_output_folder,
    unit_quaternion,
)

NAME = "calibrate"
HELP = "fit a shape's scale, materials and pointing offsets to observations with a profile"
ORDER = 25

#: What ``--fit`` may name.
FIT_ITEMS = ("scale", "material", "articulation", "offsets")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_observation_files(parser)
    parser.add_argument("--shape", required=True, help="library shape")
    parser.add_argument(
        "--profile",
        required=True,
        choices=("inertial", "nadir", "sun-pointing"),
        help="the attitude profile the object holds",
    )
    parser.add_argument(
        "--yaw-steering", action="store_true", help="nadir profile with yaw steering"
    )
    parser.add_argument(
        "--q0",
        type=unit_quaternion,
        metavar="Q1,Q2,Q3,Q4",
        help="reference attitude of --profile inertial (default the identity)",
    )
    parser.add_argument(
        "--fit",
        default="scale,material",
        metavar="ITEM,…",
        help=f"what to fit, of {', '.join(FIT_ITEMS)} (default scale,material)",
    )
    parser.add_argument(
        "--parameters",
        metavar="GROUP.NAME,…",
        help="the BRDF parameters fitted with --fit material (default: every parameter of "
        "every material; GROUP.* for one material's)",
    )
    parser.add_argument(
        "--folds", type=int, default=0, help="cross-validate by night in K folds (0: none)"
    )
    parser.add_argument(
        "--starts",
        type=int,
        default=6,
        help="starts of the fit: the library's values and draws from the priors (default 6)",
    )
    parser.add_argument(
        "--seed", type=int, default=0, help="seed of the folds' shuffle and of the starts"
    )
    parser.add_argument(
        "--loss-scale",
        type=float,
        default=3.0,
        help="residual (in 1σ of the observations) where the robust loss turns linear",
    )
    parser.add_argument(
        "--shadows",
        choices=("auto", "none", "table", "exact"),
        default="auto",
        help="self-shadowing of the shape",
    )
    add_earthshine_option(parser)
    parser.add_argument("--library", help="shape library folder (default: the user's)")
    add_output_folder(parser)


def run(args: argparse.Namespace) -> int:
    from lightcurve.io.atomic import atomic_write_json, json_ready
    from lightcurve.photometry.calibration import calibrate, cross_validate
    from shapes import get_library
    from shapes.articulation import ArticulatedModel

    fit = _fit_items(args.fit)
    if "material" not in fit and args.parameters:
        raise ValueError("--parameters goes with --fit material")
    if args.q0 is not None and args.profile != "inertial":
        raise ValueError("--q0 applies to --profile inertial only")
    if args.yaw_steering and args.profile != "nadir":
        raise ValueError("--yaw-steering applies to --profile nadir only")
    shape = get_library(args.library).load(
        args.shape, visibility=args.shadows != "none", articulated=True
    )
    articulated = isinstance(shape, ArticulatedModel)
    moving = [p.name for p in shape.articulation.moving] if articulated else []
    if "articulation" in fit and not moving:
        raise ValueError(f"--fit articulation: {shape.name} has no moving parts")
    observations, q, nights, note = _load(args, shape)
    if "material" not in fit:
        parameters: list[str] = []
    elif args.parameters:
        parameters = [p.strip() for p in args.parameters.split(",") if p.strip()]
    else:
        parameters = [f"{group}.*" for group in shape.materials]
    options: dict[str, Any] = {
        "parameters": parameters,
        "offset": "scale" in fit,
        "attitude_offsets": "offsets" in fit,
        "joint_offsets": moving if "articulation" in fit else [],
        "loss_scale": args.loss_scale,
        "shadows": args.shadows,
        "earthshine": args.earthshine,
        "starts": args.starts,
    }
    summary: dict[str, Any] = {
        "files": [str(p) for p in args.files],
        "shape": shape.name,
        "profile": args.profile,
        "yaw_steering": bool(args.yaw_steering),
        "fit": sorted(fit),
        "n_observations": len(observations),
        "earthshine": None,
        "nights": len(np.unique(nights)),
        "notes": [note] if note else [],
    }
    if args.folds:
        result = cross_validate(
            shape, q, observations, nights, folds=args.folds, seed=args.seed, **options
        )
        calibration = result["calibration"]
        summary.update(
            cv_rms_mag=result["cv_rms_mag"],
            cv_bias_mag=result["cv_bias_mag"],
            folds=result["folds"],
            seed=args.seed,
        )
    else:
        calibration = calibrate(shape, q, observations, seed=args.seed, **options)
    names = list(calibration.parameters)
    summary["earthshine"] = calibration.earthshine
    summary.update(
        train_rms_mag=calibration.train_rms_mag,
        parameters=calibration.parameters,
        unconstrained=[
            n for n, v in calibration.parameters.items() if v.get("constrained") is False
        ],
        correlation={"parameters": names, "matrix": calibration.correlation.tolist()},
    )
    args.out.mkdir(parents=True, exist_ok=True)
    atomic_write_json(args.out / "summary.json", json_ready(summary))
    atomic_write_json(
        args.out / "calibration.json",
        json_ready(
            {
                "shape": shape.name,
                "profile": args.profile,
                "yaw_steering": bool(args.yaw_steering),
                **calibration.to_json(),
            }
        ),
    )
    cv = (
        f", cross-validated {summary['cv_rms_mag']:.3f} mag (bias {summary['cv_bias_mag']:+.3f})"
        if args.folds
        else ""
    )
    print(
        f"{args.out}: {len(observations)} observations, {summary['nights']} nights; "
        f"rms {calibration.train_rms_mag:.3f} mag{cv}; "
        f"{len(summary['unconstrained'])} parameter(s) unconstrained"
    )
    return 0


def _fit_items(text: str) -> set[str]:
    """The ``--fit`` items, checked."""
    items = {item.strip() for item in text.split(",") if item.strip()}
    unknown = sorted(items - set(FIT_ITEMS))
    if unknown or not items:
        raise ValueError(f"--fit: unknown item(s) {', '.join(unknown)}; use {', '.join(FIT_ITEMS)}")
    return items


def _load(args: argparse.Namespace, shape: Any) -> tuple[Any, np.ndarray, np.ndarray, str]:
    """The files' observations as one set (magnitudes of a declared band taken back to V;
    the object's positions when every file has them; the columns of ``shape``'s scheduled
    joints), the profile's attitudes, each observation's night and a note on how nights
    were dated."""
    import pandas as pd

    from lightcurve import io
    from lightcurve.io.observations import (
        OBJECT_POSITION_COLUMNS,
        OBSERVER_COLUMNS,
        SUN_COLUMNS,
        Observations,
        validate_table,
    )
    from lightcurve.photometry.bands import header_offset
    from lightcurve.photometry.calibration import night_index
    from lightcurve.photometry.profiles import profile_states
    from lightcurve.sky.sites import site_from_label
    from shapes.articulation import ArticulatedModel

    frames, attitudes, nights = [], [], []
    note = ""
    parts = shape.articulation.parts if isinstance(shape, ArticulatedModel) else ()
    scheduled = [p.joint.column for p in parts if p.joint.column is not None]
    readings = [io.read(path) for path in args.files]
    with_positions = all(c in o.table for o in readings for c in OBJECT_POSITION_COLUMNS)
    positions = list(OBJECT_POSITION_COLUMNS) if with_positions else []
    for path, observations in zip(args.files, readings, strict=True):
        missing = [c for c in scheduled if c not in observations.table]
        if missing:
            raise ValueError(
                f"{path}: no column {', '.join(missing)}, the angle of a scheduled joint "
                f"of {shape.name}"
            )
        q = profile_states(
            observations, args.profile, reference=args.q0, yaw_steering=args.yaw_steering
        )[:, :4]
        columns = ["mjd", "mag", "mag_err", *SUN_COLUMNS, *OBSERVER_COLUMNS]
        frame = observations.table[columns + positions + scheduled].copy()
        frame["mag"] = frame["mag"] - header_offset(observations.meta)
        frames.append(frame)
        attitudes.append(q)
        if "site" in observations.meta:
            longitude = site_from_label(observations.meta["site"]).longitude_deg
        else:
            longitude = 0.0
            note = f"{Path(path).name} names no site: its nights are UTC dates"
        nights.append(night_index(observations.mjd, longitude))
    table = pd.concat(frames, ignore_index=True)
    order = np.argsort(table["mjd"].to_numpy(), kind="stable")
    meta = {"duplicate_epochs": "allowed"}
    combined = Observations(
        validate_table(table.iloc[order].reset_index(drop=True), "calibration", meta), meta
    )
    return combined, np.concatenate(attitudes)[order], np.concatenate(nights)[order], note
