"""The convex shape of an object the library lacks, from its light curves and attitudes:
the extended Gaussian image (EGI) and Minkowski's reconstruction.

Without --attitude (joint mode, tumbling objects): shape and attitude together. The first
round searches each file's torque-free state from random states, each scored by the best
EGI for its trajectory (no start shape); the lowest minima and the lowest one's mirror (the
half turn about the normal of the Sun–observer plane, with the mirror-image shape) are the
hypotheses, picked by χ², listed in summary.json (joint.hypotheses) and flagged
(joint.ambiguous, and a warning) when one within Δχ² = 9 has another attitude. Further
rounds (--rounds, default 1), or all of them with --start NAME (a library shape, or
"ellipsoid"), invert the attitude on the current shape and refine it against the best EGI;
they stop when χ² falls by less than 1 %. The joint mode needs the material (--brdf KIND
--param …); shape.obj and the attitudes (DIR/attitudes.csv) are then in the principal frame
of the fitted inertia, defined up to the shape's symmetries and the mirror (docs/shape.md).

With the attitude known at every epoch (--attitude truth: the files' truth columns q1..q4;
--attitude RESULT_DIR: the per-epoch estimates of a `lightcurve invert` result folder, one
input's folder or the batch folder holding <file stem>/), the flux is linear in the areas
of facets over a near-uniform grid of --normals normals; a non-negative least-squares fit
gives the EGI and the Minkowski reconstruction the convex polyhedron (docs/shape.md).

Material: --brdf KIND --param KEY=VALUE … fixes it; --brdf KIND alone (phong,
ashikhmin-shirley or cook-torrance) fits the specular weight rs and the lobe's exponent with
rd held at --albedo, and without --brdf both Ashikhmin–Shirley and Phong (whose rs = 0 is
Lambert's model) are tried and the lower χ² kept; other models alone take their registry
defaults. The absolute size rests on the albedo, assumed or given.

Smoothing (known attitudes): --smoothing auto (the default) adds a small Tikhonov
smoothness weight when the body-frame Sun–observer bisectors stay near one plane (a
stabilised object: the data see its normals along one band, and the fit could otherwise put
area of any size where it hardly sees), and none otherwise (docs/shape.md).

Faces: --faces auto (the default) simplifies the fitted EGI of a tumbling object to the
fewest facets the data need: merges of nearby facets and removals of small ones, each kept
when the χ² rises by less than the Bayesian information criterion credits for the
parameters saved; --faces all keeps every fitted facet, --faces fewest simplifies a
stabilised object's fit too (docs/shape.md).

Writes DIR/shape.obj (metres, principal frame; the rotation from the attitudes' body frame
in its comments), DIR/summary.json, DIR/egi.csv (normals, areas, 1σ), DIR/fit.csv and
DIR/fit.png. `lightcurve shapes add NAME DIR/shape.obj --brdf … --param …` takes the shape
with the material of summary.json.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from lightcurve.commands._args import add_observation_files, add_output_folder, brdf_parameters

NAME = "shape"
HELP = "convex shape from light curves, attitudes known or fitted (EGI + Minkowski, shape OBJ)"
ORDER = 43

#: Default grid of normals: on the first arcs of benchmarks.shape_recovery 1 000 and 2 000
#: normals predicted the held-out arc equally well (docs/shape.md), at half the time.
DEFAULT_NORMALS = 1000


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_observation_files(parser)
    add_output_folder(parser)
    parser.add_argument(
        "--attitude",
        metavar="truth|RESULT_DIR",
        help="attitudes: the files' truth columns, or an inversion result folder "
        "(default: fitted with the shape, joint mode)",
    )
    parser.add_argument(
        "--start",
        metavar="NAME",
        help="joint mode: start the inversion rounds from this library shape or 'ellipsoid' "
        "(default: the search, no start shape)",
    )
    parser.add_argument(
        "--rounds",
        type=int,
        default=1,
        help="joint mode: rounds at most, the search then inversion rounds (default: 1)",
    )
    parser.add_argument(
        "--normals", type=int, default=DEFAULT_NORMALS, metavar="N", help="grid normals"
    )
    parser.add_argument(
        "--brdf",
        metavar="KIND",
        help="registry BRDF; without --param its rs and lobe exponent are fitted "
        "(default: ashikhmin-shirley and phong fitted, the better kept)",
    )
    parser.add_argument(
        "--param",
        metavar="KEY=VALUE",
        action="append",
        default=[],
        help="BRDF parameter (repeatable): the material is then fixed",
    )
    parser.add_argument(
        "--albedo", type=float, default=0.2, help="assumed diffuse albedo rd of a fitted material"
    )
    parser.add_argument(
        "--smoothing",
        type=_smoothing,
        default="auto",
        metavar="WEIGHT",
        help="relative Tikhonov smoothness weight, or 'auto' (default): a small weight when "
        "the data see the normals along one band (a stabilised object), else none",
    )
    parser.add_argument(
        "--faces",
        choices=("auto", "fewest", "all"),
        default="auto",
        help="fewest: simplify the EGI to the fewest facets the data need (merges and "
        "removals judged by the BIC); all: keep every fitted facet; auto (default): fewest "
        "when the data see the normals from all sides (a tumbling object), else all",
    )
    parser.add_argument(
        "--bootstrap", type=int, default=8, help="bootstrap refits for the axis ratios' 1σ"
    )
    parser.add_argument(
        "--seed", type=int, default=0, help="seed of the bootstrap and of the joint mode's search"
    )


def _smoothing(text: str) -> str | float:
    """``--smoothing``: ``auto`` or a finite weight ≥ 0."""
    if text == "auto":
        return text
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value >= 0.0):
        raise argparse.ArgumentTypeError(f"'auto' or a finite number ≥ 0, got {text!r}")
    return value


def _attitudes(observations, source: str):
    from lightcurve.analysis.egi.epochs import result_attitudes, truth_attitudes

    if source == "truth":
        return [truth_attitudes(obs) for obs in observations]
    folder = Path(source)
    if not folder.is_dir():
        raise FileNotFoundError(f"--attitude {source}: neither 'truth' nor a result folder")
    return [result_attitudes(obs, folder) for obs in observations]


def _joint(args: argparse.Namespace, observations):
    """The joint fit (module docstring): its EGI fit, epochs, rounds and attitudes."""
    import brdf
    from lightcurve.joint_shape import fit_joint_shape

    if not args.brdf or not args.param:
        raise ValueError("without --attitude (joint mode) give the material: --brdf KIND --param …")
    material = brdf.get(brdf.describe(args.brdf).name, **brdf_parameters(args.param))
    options = {key: getattr(args, key) for key in ("normals", "start", "rounds", "seed")}
    joint = fit_joint_shape(observations, material, **options)
    return joint, f"material given ({material.name}); the size holds for its reflectances"


def _fit(args: argparse.Namespace, epochs):
    import brdf
    from lightcurve.analysis.egi import fit_egi, fit_material
    from lightcurve.analysis.egi.fit import FITTED_FAMILIES, LOBES, default_smoothing

    if args.param and not args.brdf:
        raise ValueError("--param needs --brdf KIND")
    kind = brdf.describe(args.brdf).name if args.brdf else None
    if args.smoothing == "auto":
        args.smoothing = default_smoothing(epochs)
    if args.param or (kind is not None and kind not in LOBES):
        material = brdf.get(kind, **brdf_parameters(args.param))
        fit = fit_egi(epochs, material, normals=args.normals, smoothing=args.smoothing)
        note = f"material given ({kind}); the size holds for its reflectances"
        return fit, note
    fit = fit_material(
        epochs,
        FITTED_FAMILIES if kind is None else (kind,),
        normals=args.normals,
        albedo=args.albedo,
        smoothing=args.smoothing,
    )
    note = f"diffuse albedo rd = {args.albedo:g} assumed; rs and the lobe fitted"
    return fit, note


def _attitude_columns(epochs, attitudes) -> dict:
    """The fitted attitudes per epoch as columns (file, mjd, q1..q4)."""
    import numpy as np

    q = np.concatenate(attitudes)
    return {
        "file": epochs.source,
        "mjd": epochs.mjd,
        **{f"q{i + 1}": q[:, i] for i in range(4)},
    }


def run(args: argparse.Namespace) -> int:
    import sys

    import numpy as np

    from lightcurve import io
    from lightcurve.analysis.egi import FitEpochs, bootstrap_areas, convex_solid
    from lightcurve.analysis.egi.plots import plot_egi_fit
    from lightcurve.analysis.egi.simplify import choose_faces
    from lightcurve.io.atomic import atomic_write_csv, atomic_write_json, json_ready
    from shapes import write_obj

    if args.normals < 4:
        raise ValueError(f"--normals must be at least 4, got {args.normals}")
    if args.bootstrap < 0:
        raise ValueError(f"--bootstrap must be ≥ 0, got {args.bootstrap}")
    observations = [io.read(path) for path in args.files]
    for obs in observations:
        if not obs.has_magnitudes:
            raise ValueError(f"{obs.source}: no mag/mag_err columns: a geometry file, no data")
    joint = None
    if args.attitude is None:
        joint, scale_note = _joint(args, observations)
        fit, epochs = joint.fit, joint.epochs
    else:
        if args.start is not None:
            raise ValueError("--start applies to the joint mode (without --attitude)")
        attitudes = _attitudes(observations, args.attitude)
        epochs = FitEpochs.from_observations(observations, attitudes)
        fit, scale_note = _fit(args, epochs)
    facets_fitted = int(np.count_nonzero(fit.areas))
    fit = choose_faces(fit, epochs, args.faces)
    samples = bootstrap_areas(epochs, fit, samples=args.bootstrap, seed=args.seed)
    solid = convex_solid(fit.normals, fit.areas, samples=samples if args.bootstrap > 1 else None)
    args.out.mkdir(parents=True, exist_ok=True)
    axes = solid.principal_axes
    write_obj(
        solid.model,
        args.out / "shape.obj",
        unit="m",
        comments=[
            "convex shape from light curves (lightcurve shape, EGI + Minkowski), metres",
            "principal frame: v = P^T (v_body - c), v_body in the attitudes' body frame",
            "P rows: " + "; ".join(" ".join(f"{v:.9f}" for v in row) for row in axes),
            "c (m): " + " ".join(f"{v:.9f}" for v in solid.centroid),
        ],
    )
    rms = fit.residual_rms_mag(epochs)
    summary = {
        "method": "egi" if joint is None else "joint",
        "attitude_source": args.attitude or "joint",
        "files": [str(p) for p in args.files],
        "n_epochs": len(epochs),
        "n_normals": len(fit.normals),
        "n_facets": solid.n_facets,
        "residual_rms_mag": rms,
        "mag_err_rms": float(np.sqrt(np.mean(epochs.mag_err**2))),
        "chi2": fit.chi2,
        "material": {"brdf": fit.material.name, "params": fit.material.params},
        "scale_note": scale_note,
        "smoothing": fit.smoothing,
        "faces": {
            "mode": args.faces,
            "fitted_facets": facets_fitted,
            "kept_facets": int(np.count_nonzero(fit.areas)),
        },
        "surface_area_m2": float(fit.areas.sum()),
        "volume_m3": float(solid.model.volume),
        "axis_ratios": {"a/b": float(solid.axis_ratios[0]), "b/c": float(solid.axis_ratios[1])},
        "axis_ratio_sigma": {
            "a/b": float(solid.axis_ratio_sigma[0]),
            "b/c": float(solid.axis_ratio_sigma[1]),
        },
        "bootstrap": {"samples": args.bootstrap, "seed": args.seed},
        "principal_axes_body": axes,
        "centroid_body_m": solid.centroid,
    }
    if joint is not None:
        summary["joint"] = {
            "rounds": [vars(r) for r in joint.rounds],
            "best_round": joint.best_round,
            "inertia_ratios": joint.inertia_ratios,
            "start": args.start or "search",
            "hypotheses": [vars(h) for h in joint.hypotheses],
            "ambiguous": joint.ambiguous,
            "reduced_chi2": joint.reduced_chi2,
            "misfit": joint.misfit,
        }
        atomic_write_csv(_attitude_columns(epochs, joint.attitudes), args.out / "attitudes.csv")
    atomic_write_json(args.out / "summary.json", json_ready(summary))
    atomic_write_csv(
        {
            "nx": fit.normals[:, 0],
            "ny": fit.normals[:, 1],
            "nz": fit.normals[:, 2],
            "area_m2": fit.areas,
            "sigma_m2": fit.area_sigma,
        },
        args.out / "egi.csv",
    )
    atomic_write_csv(
        {
            "file": epochs.source,
            "mjd": epochs.mjd,
            "mag": epochs.mag,
            "mag_err": epochs.mag_err,
            "fitted_mag": fit.model_mag,
        },
        args.out / "fit.csv",
    )
    plot_egi_fit(epochs, fit, args.out / "fit.png", [Path(p).name for p in args.files])
    if joint is not None and joint.ambiguous:
        chi2 = ", ".join(
            f"{h.label} {h.chi2:.1f} ({h.angle_to_best_deg:.0f}°)" for h in joint.hypotheses
        )
        print(
            f"lightcurve shape: warning: attitudes that differ fit alike (χ², angle to the "
            f"best: {chi2}): the attitude, and the shape, are not determined by these data",
            file=sys.stderr,
        )
    if joint is not None and joint.misfit:
        print(
            f"lightcurve shape: warning: no state found fits the light curve (reduced χ² "
            f"{joint.reduced_chi2:.1f}): the attitude and the shape are not an answer",
            file=sys.stderr,
        )
    if not args.quiet:
        params = " ".join(f"--param {k}={v:.6g}" for k, v in fit.material.params.items())
        print(
            f"shape {args.out / 'shape.obj'}: {solid.n_facets} facets, "
            f"{fit.areas.sum():.4g} m², axis ratios a/b {solid.axis_ratios[0]:.3f}, "
            f"b/c {solid.axis_ratios[1]:.3f}; residual rms {rms:.4f} mag; material "
            f"--brdf {fit.material.name} {params}"
        )
    return 0
