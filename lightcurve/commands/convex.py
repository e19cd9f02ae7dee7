"""Convex shape and spin inversion of asteroid light curves (Kaasalainen & Torppa 2001).

Fits a convex Gaussian image (exp of spherical harmonics on a fixed triangulated sphere),
the pole (λ, β, ecliptic J2000 for DAMIT files) and the sidereal period to relative and
calibrated light curves together, with Lommel–Seeliger + c·Lambert scattering and the
three-parameter phase function (DAMIT's convexinv defaults). Starting points:
--pole/--period; without --pole, --poles N starts spread over the sphere (batched);
--period-range A B scans the period (every trial period from every pole start; hopeless fits
stopped early) and refines the deepest minima with the full model; the scan's progress shows
on stderr (--progress, or -v for a log line per batch).

Writes OUT/summary.json (``solutions``: best first, each with lambda_deg, beta_deg,
period_h, rms, chi2, uncertainties), OUT/shape.obj (the best convex polyhedron, Minkowski
reconstruction, volume 1 m³ — `lightcurve shapes add NAME OUT/shape.obj` accepts it),
OUT/fit.csv (observed and model brightness) and, after a scan, OUT/scan.csv; with --plots
also OUT/shape.png and OUT/fit.png.
"""

from __future__ import annotations

import argparse
import dataclasses
import math

from lightcurve.commands._args import (
    add_observation_files,
    add_output_folder,
    add_progress_option,
    float_vector,
    show_progress,
)

NAME = "convex"
HELP = "convex shape + spin inversion (pole, sidereal period, shape OBJ)"
ORDER = 42


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_observation_files(parser)
    parser.add_argument(
        "--pole",
        type=float_vector(2),
        metavar="LAMBDA,BETA",
        help="starting pole, deg (default: --poles starts over the sphere)",
    )
    parser.add_argument(
        "--period",
        type=float,
        metavar="HOURS",
        help="starting period, h (default: scan --period-range)",
    )
    parser.add_argument(
        "--period-range",
        nargs=2,
        type=float,
        metavar=("A", "B"),
        help="scan periods, h (used without --period)",
    )
    parser.add_argument(
        "--poles", type=int, default=6, metavar="N", help="pole starts without --pole"
    )
    parser.add_argument("--epoch", type=float, metavar="MJD", help="t0 (default: first epoch)")
    parser.add_argument("--degree", type=int, default=6, help="harmonics degree = order")
    parser.add_argument("--rows", type=int, default=8, help="Gaussian-sphere rows (8: 512 facets)")
    parser.add_argument(
        "--iterations", type=int, default=100, help="Levenberg-Marquardt iterations at most"
    )
    parser.add_argument(
        "--engine",
        choices=("numba", "torch"),
        default="numba",
        help="model: compiled CPU kernels (numba) or torch (CUDA when available)",
    )
    parser.add_argument(
        "--compile",
        action="store_true",
        help="with --engine torch: torch.compile its kernel (~30 s of compilation)",
    )
    add_progress_option(parser, "the period scan (--period-range)")
    parser.add_argument(
        "--convexity", type=float, default=0.1, help="convexity regularisation weight"
    )
    parser.add_argument(
        "--phase",
        type=float_vector(3),
        default=(0.5, 0.1, -0.5),
        metavar="A,D,K",
        help="phase function a, d (rad), k (1/rad)",
    )
    parser.add_argument("--lambert", type=float, default=0.1, help="Lambert weight c")
    parser.add_argument(
        "--free",
        default="",
        metavar="a,d,k,c",
        help="also fit these scattering parameters (default: none, all fixed)",
    )
    parser.add_argument(
        "--dark-facet", action="store_true", help="close the shape with the dark facet"
    )
    parser.add_argument("--refine", type=int, default=5, help="scan minima refined")
    parser.add_argument(
        "--plots",
        action="store_true",
        help="also draw DIR/shape.png and DIR/fit.png (matplotlib: about 1 s more)",
    )
    add_output_folder(parser)


def _settings(args: argparse.Namespace):
    from lightcurve.analysis.convex import ConvexSettings

    extra = tuple(v.strip() for v in args.free.split(",") if v.strip())
    unknown = set(extra) - {"a", "d", "k", "c"}
    if unknown:
        raise ValueError(f"--free accepts a, d, k, c; got {', '.join(sorted(unknown))}")
    for name, value, low in (("--degree", args.degree, 1), ("--rows", args.rows, 2)):
        if value < low:
            raise ValueError(f"{name} must be at least {low}, got {value}")
    if args.iterations < 1 or args.poles < 1:
        raise ValueError("--iterations and --poles must be positive")
    if args.compile and args.engine != "torch":
        raise ValueError("--compile needs --engine torch")
    return ConvexSettings(
        degree=args.degree,
        order=args.degree,
        nrows=args.rows,
        convexity_weight=args.convexity,
        phase=tuple(float(v) for v in args.phase),
        lambert=args.lambert,
        free=("lambda", "beta", "rate", *extra),
        max_iter=args.iterations,
        engine=args.engine,
        compile=args.compile,
    )


def run(args: argparse.Namespace) -> int:
    from lightcurve.analysis.convex import Photometry, fibonacci_poles, fit, period_scan
    from lightcurve.analysis.convex.scan import SCAN_SETTINGS, refine
    from lightcurve.analysis.spin import SpinState
    from lightcurve.io.atomic import atomic_write_csv, atomic_write_json, json_ready

    if args.period is None and args.period_range is None:
        raise ValueError("give --period HOURS or --period-range A B")
    if args.period is not None and not args.period > 0:
        raise ValueError(f"--period must be positive hours, got {args.period}")
    settings = _settings(args)
    data = Photometry.read(args.files)
    epoch = float(data.mjd.min()) if args.epoch is None else args.epoch
    poles = (
        [tuple(math.radians(v) for v in args.pole)]
        if args.pole is not None
        else fibonacci_poles(args.poles)
    )
    args.out.mkdir(parents=True, exist_ok=True)
    scan = None
    if args.period_range is not None:
        scan = period_scan(
            data,
            tuple(args.period_range),
            poles,
            dataclasses.replace(SCAN_SETTINGS, engine=args.engine, compile=args.compile),
            epoch_mjd=epoch,
            progress=show_progress(args),
        )
        solutions = refine(scan.local_minima(args.refine), data, settings)
        atomic_write_csv(
            {"period_h": scan.periods_h, "chi2": scan.chi2, "rejected": scan.rejected},
            args.out / "scan.csv",
        )
    else:
        starts = [SpinState(lam, beta, args.period * 3600.0, 0.0, epoch) for lam, beta in poles]
        solutions = fit(data, starts, settings)
    solutions = _distinct(solutions)
    best = solutions[0]
    _write_shape(best, args)
    atomic_write_csv(
        {
            "mjd": data.mjd,
            "lightcurve": data.curve,
            "relative": data.relative[data.curve],
            "observed": data.brightness,
            "sigma": data.sigma,
            "model": best.model,
        },
        args.out / "fit.csv",
    )
    if args.plots:
        from lightcurve.analysis.convex.plots import plot_fit

        plot_fit(data, best.model, args.out / "fit.png")
    summary = {
        "files": [str(p) for p in args.files],
        "frame": "ecliptic J2000 (DAMIT files) or the files' inertial frame",
        "settings": {
            "degree": settings.degree,
            "rows": settings.nrows,
            "facets": settings.sphere.n_facets,
            "convexity_weight": settings.convexity_weight,
            "phase": list(settings.phase),
            "lambert": settings.lambert,
            "free": list(settings.free),
            "iterations": settings.max_iter,
        },
        "n_points": len(data),
        "n_lightcurves": data.n_curves,
        "solutions": [s.summary() for s in solutions],
    }
    if scan is not None:
        summary["scan"] = {
            "periods": len(scan.periods_h),
            "pole_starts": len(poles),
            "seconds": scan.seconds,
            "minimum_period_h": scan.minimum().spin.period_h,
            "periods_rejected_early": int(scan.rejected.sum()),
        }
    atomic_write_json(args.out / "summary.json", json_ready(summary))
    s = best.summary()
    print(
        f"pole ({s['lambda_deg']:.2f}, {s['beta_deg']:.2f}) deg, period {s['period_h']:.8f} h, "
        f"rms {s['rms']:.4f}, chi2 {s['chi2']:.1f}; {len(solutions)} distinct solution(s); "
        f"shape {args.out / 'shape.obj'}"
    )
    return 0


def _distinct(solutions, pole_deg: float = 5.0, period_rel: float = 1e-6):
    """Drop solutions (sorted by χ²) within ``pole_deg`` and ``period_rel`` of a better one."""
    from lightcurve.analysis.spin import pole_distance

    kept = []
    for s in solutions:
        if not any(
            math.degrees(
                float(
                    pole_distance(
                        s.spin.lambda_rad, s.spin.beta_rad, k.spin.lambda_rad, k.spin.beta_rad
                    )
                )
            )
            < pole_deg
            and abs(s.spin.period_s / k.spin.period_s - 1) < period_rel
            for k in kept
        ):
            kept.append(s)
    return kept


def _write_shape(solution, args: argparse.Namespace) -> None:
    from lightcurve.analysis.convex.minkowski import minkowski_polyhedron
    from shapes import FacetModel, write_obj

    vertices, faces = minkowski_polyhedron(
        solution.normals, solution.areas, dark_facet=args.dark_facet
    )
    model = FacetModel(
        vertices,
        faces,
        name="convex_model",
        provenance={"source": "lightcurve convex", "files": [str(p) for p in args.files]},
    )
    write_obj(model, args.out / "shape.obj")
    if args.plots:
        from lightcurve.analysis.convex.plots import plot_shape

        plot_shape(vertices, faces, args.out / "shape.png", title=model.name)
