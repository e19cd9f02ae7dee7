"""Convex shapes of objects the library lacks, from light curves with known attitudes.

Objects (convex, none in the shape library): boxes 3 × 2 × 1 m, 4 × 1.2 × 1 m and
1.5 × 1.5 × 1 m, a triangular prism (circumradius 1 m, length 3 m), a chiral polyhedron
(a triangular prism with its top turned by 40°, the convex hull of the six corners) and a
32-sided cylinder (radius 0.6 m, length 2.5 m), all of one Ashikhmin–Shirley material
(rd 0.35, rs 0.25, nu = nv 40: not the fit's assumed rd 0.2, so the fit must find the
specular weight and the lobe). Being convex, they are rendered without shadows (the renderer
with ``shadows="none"`` is exact for them).

Scenarios (geometry of :mod:`benchmarks.mismatch_study`: Mount Lemmon, 2024 Jan–Feb):

``geo_tumbling``
    a 40-minute geostationary arc at 2 s, the object tumbling torque-free (uniform random
    attitude, rates of uniform direction, 0.3–1.5 °/s);
``geo_two_nights``
    two such arcs of the same object on two nights (another start state each), fitted
    together;
``geo_night``
    a stabilised (nadir-pointing, fixed random offset) object over a 6-hour night at 30 s.

Each run draws the object's state and the noise (0.02–0.05 mag, uniform) from
``default_rng([seed, run, k])``; a second arc of the same object (another night, another
start state for the tumbling case) is the held-out light curve. The shape is fitted by
:func:`lightcurve.analysis.egi.fit_material` (the CLI default: Ashikhmin–Shirley and Phong
tried, rd held at 0.2) and, as a check of the fit alone, with the true material given
(``known``). Printed per run and summarised per scenario:

* ``heldout_ratio``: rms of (held-out measured − predicted) over the noise rms, the
  prediction rendered by the project's renderer from the reconstructed mesh with the
  reported material at the true attitudes (target ≤ 1.3);
* ``axis_ratio_error``: largest relative error of a/b and b/c of the equivalent ellipsoid
  against the true mesh's (target ≤ 10 %);
* ``normal_error_deg``: for each true face carrying ≥ 10 % of the area, the angle between its
  normal and the area-weighted mean of the fitted normals within 10° of it (target ≤ 5°);
* ``fit_s``, ``reconstruction_s``: wall times.

``speed``: one EGI fit of 2 000 normals × 1 200 epochs (the 40-minute arc) with the material
given, best of 3: the grid fit alone (design matrix + NNLS) and the full fit (two cluster
refinements and polishes); and the **baseline** measured in the same run: the plain grid fit's
held-out ratio and normal errors on the first ``geo_tumbling`` runs against the full fit's.

    python -m benchmarks.shape_recovery [--runs 2] [--seed 34] [--sections geo_tumbling,...]
        [--normals 2000] [--out FILE]
"""

from __future__ import annotations

import argparse
import math
import time
from typing import Any

import numpy as np

import brdf
from benchmarks._machine import machine_info
from benchmarks._report import add_sections_argument, emit_report
from benchmarks._timing import best_time
from benchmarks.mismatch_study import geo_geometry
from filters.attitude import random_quaternion
from lightcurve.analysis.convex.minkowski import equivalent_ellipsoid
from lightcurve.analysis.egi import FitEpochs, convex_solid, fit_egi, fit_material, normal_grid
from lightcurve.analysis.egi.epochs import truth_attitudes
from lightcurve.analysis.egi.fit import design_matrix
from lightcurve.io.observations import Observations
from lightcurve.photometry.render import Renderer
from lightcurve.photometry.simulate import GaussianNoise, simulate
from shapes import FacetModel, Material, primitives

MATERIAL = Material("ashikhmin-shirley", {"rd": 0.35, "rs": 0.25, "nu": 40, "nv": 40})
SCENARIOS = ("geo_tumbling", "geo_two_nights", "geo_night")
RATE_DEG_S = (0.3, 1.5)
NOISE_MAG = (0.02, 0.05)
NIGHT_S, NIGHT_CADENCE_S = 6 * 3600.0, 30.0
BIG_FACE_SHARE = 0.10
FACE_CONE_DEG = 10.0


def objects() -> dict[str, FacetModel]:
    """The convex test objects (module docstring), with the benchmark's material."""
    boxes = {
        f"box_{'x'.join(f'{v:g}' for v in size)}": primitives.box(size, materials=MATERIAL)
        for size in ((3.0, 2.0, 1.0), (4.0, 1.2, 1.0), (1.5, 1.5, 1.0))
    }
    turn = np.radians([90.0, 210.0, 330.0])
    bottom = np.column_stack([np.cos(turn), np.sin(turn), np.full(3, -1.5)])
    top = np.column_stack([np.cos(turn + 0.7), np.sin(turn + 0.7), np.full(3, 1.5)])
    import trimesh

    hull = trimesh.convex.convex_hull(np.vstack([bottom, top]))
    return {
        **boxes,
        "prism": primitives.cylinder(1.0, 3.0, sections=3, materials=MATERIAL, name="prism"),
        "chiral": FacetModel(hull.vertices, hull.faces, materials=MATERIAL, name="chiral"),
        "cylinder32": primitives.cylinder(
            0.6, 2.5, sections=32, materials=MATERIAL, name="cylinder32"
        ),
    }


def observe(
    shape: FacetModel, scenario: str, rng: np.random.Generator, noise_mag: float
) -> Observations:
    """One simulated arc of ``scenario`` (module docstring)."""
    if scenario != "geo_night":
        geometry, _ = geo_geometry(rng)
        omega = rng.standard_normal(3)
        omega *= math.radians(rng.uniform(*RATE_DEG_S)) / np.linalg.norm(omega)
        q0 = random_quaternion((), rng)
        kwargs: dict[str, Any] = {"q0": q0, "omega0": omega}
    else:
        geometry, _ = geo_geometry(rng, NIGHT_S, NIGHT_CADENCE_S)
        kwargs = {"profile": "nadir", "offset_deg": rng.uniform(-180.0, 180.0, 3)}
    return simulate(
        geometry,
        shape,
        noise=GaussianNoise(noise_mag),
        shadows="none",
        seed=rng.integers(2**31),
        **kwargs,
    )


def _epochs(obs: Observations) -> FitEpochs:
    return FitEpochs.from_observations([obs], [truth_attitudes(obs)])


def _true_material() -> brdf.BRDF:
    return brdf.get(MATERIAL.brdf, **MATERIAL.params)


def predicted(fit, solid, held_out: Observations) -> np.ndarray:
    """Magnitudes of the reconstructed mesh (back in the body frame) with the fit's material,
    rendered at the held-out arc's true attitudes."""
    body = solid.model.vertices @ solid.principal_axes.T + solid.centroid
    material = Material(fit.material.name, fit.material.params)
    model = FacetModel(body, solid.model.faces, materials=material)
    q = truth_attitudes(held_out)
    return Renderer(model, shadows="none").magnitude(
        q, held_out.sun_vectors, held_out.observer_vectors
    )


def face_errors(shape: FacetModel, normals: np.ndarray, areas: np.ndarray) -> list[float]:
    """Angle (deg) between each big true face and the fitted normals' weighted mean near it."""
    compiled = shape.compiled()
    share = compiled.areas / compiled.areas.sum()
    errors = []
    for normal in compiled.normals[share >= BIG_FACE_SHARE]:
        near = normals @ normal >= math.cos(math.radians(FACE_CONE_DEG))
        mean = areas[near] @ normals[near]
        size = np.linalg.norm(mean)
        errors.append(math.degrees(math.acos(min(1.0, mean @ normal / size))) if size else 180.0)
    return errors


def score(shape, fit, held_out: Observations, noise_mag: float) -> dict[str, Any]:
    """Held-out ratio, axis-ratio and face-normal errors of one fit, and its reconstruction."""
    start = time.perf_counter()
    solid = convex_solid(fit.normals, fit.areas)
    seconds = time.perf_counter() - start
    a, b, c = equivalent_ellipsoid(shape)
    truth = np.array([a / b, b / c])
    residual = held_out.magnitudes - predicted(fit, solid, held_out)
    errors = face_errors(shape, fit.normals, fit.areas)
    return {
        "material": {"brdf": fit.material.name, "params": fit.material.params},
        "heldout_rms_mag": float(np.sqrt(np.mean(residual**2))),
        "heldout_ratio": float(np.sqrt(np.mean(residual**2)) / noise_mag),
        "axis_ratios": solid.axis_ratios.tolist(),
        "true_axis_ratios": truth.tolist(),
        "axis_ratio_error": float(np.max(np.abs(solid.axis_ratios / truth - 1.0))),
        "normal_error_deg": errors,
        "n_facets": solid.n_facets,
        "reconstruction_s": seconds,
    }


def run_case(name: str, shape: FacetModel, scenario: str, run: int, args) -> dict[str, Any]:
    """Fit one object in one scenario (fitted and known material) and score both."""
    k = SCENARIOS.index(scenario)
    rng = np.random.default_rng([args.seed, run, k, sorted(objects()).index(name)])
    noise_mag = float(rng.uniform(*NOISE_MAG))
    arcs = [observe(shape, scenario, rng, noise_mag)]
    if scenario == "geo_two_nights":
        arcs.append(observe(shape, scenario, rng, noise_mag))
    held_out = observe(shape, scenario, rng, noise_mag)
    epochs = FitEpochs.from_observations(arcs, [truth_attitudes(arc) for arc in arcs])
    record: dict[str, Any] = {
        "object": name,
        "scenario": scenario,
        "run": run,
        "noise_mag": noise_mag,
        "epochs": len(epochs),
    }
    for label, fitter in (
        ("fitted", lambda: fit_material(epochs, normals=args.normals)),
        ("known", lambda: fit_egi(epochs, _true_material(), normals=args.normals)),
    ):
        start = time.perf_counter()
        try:
            fit = fitter()
            seconds = time.perf_counter() - start
            record[label] = {
                "fit_s": seconds,
                "fit_rms_mag": fit.residual_rms_mag(epochs),
                **score(shape, fit, held_out, noise_mag),
            }
        except (ValueError, RuntimeError) as exc:  # a failed fit is a result
            record[label] = {"error": f"{type(exc).__name__}: {exc}"[:300]}
    return record


def speed(args) -> dict[str, Any]:
    """Timing of one fit of ``args.normals`` normals × 1 200 epochs, and the grid-only
    baseline's accuracy against the full fit's on the first tumbling runs."""
    shapes = objects()
    rng = np.random.default_rng([args.seed, 0, 99])
    arc = observe(shapes["box_3x2x1"], "geo_tumbling", rng, 0.03)
    epochs = _epochs(arc).subset(np.arange(len(arc)) < 1200)
    material = _true_material()
    grid = best_time(lambda: fit_egi(epochs, material, normals=args.normals, refinements=0), 3)
    full = best_time(lambda: fit_egi(epochs, material, normals=args.normals), 3)
    design = best_time(
        lambda: design_matrix(normal_grid(args.normals), epochs, material),
        3,
    )
    comparison = []
    for name in sorted(shapes)[: args.baseline_objects]:
        rng = np.random.default_rng([args.seed, 0, 0, sorted(shapes).index(name)])
        noise_mag = float(rng.uniform(*NOISE_MAG))
        fitted_on = observe(shapes[name], "geo_tumbling", rng, noise_mag)
        held_out = observe(shapes[name], "geo_tumbling", rng, noise_mag)
        row = {"object": name}
        for label, rounds in (("baseline_grid", 0), ("full", 2)):
            fit = fit_egi(_epochs(fitted_on), material, normals=args.normals, refinements=rounds)
            scored = score(shapes[name], fit, held_out, noise_mag)
            row[label] = {
                key: scored[key]
                for key in ("heldout_ratio", "axis_ratio_error", "normal_error_deg")
            }
        comparison.append(row)
    return {
        "epochs": len(epochs),
        "normals": args.normals,
        "design_matrix_s": design,
        "grid_fit_s": grid,
        "full_fit_s": full,
        "full_over_grid": full / grid,
        "accuracy_baseline_vs_full": comparison,
    }


def summarise(records: list[dict[str, Any]]) -> dict[str, Any]:
    """Per scenario and material mode: medians, worst values and the fractions on target."""
    out: dict[str, Any] = {}
    for scenario in SCENARIOS:
        for label in ("fitted", "known"):
            rows = [
                r[label] for r in records if r["scenario"] == scenario and "error" not in r[label]
            ]
            failed = sum(1 for r in records if r["scenario"] == scenario and "error" in r[label])
            if not rows and not failed:
                continue
            ratio = np.array([r["heldout_ratio"] for r in rows])
            axes = np.array([r["axis_ratio_error"] for r in rows])
            normal = np.array([max(r["normal_error_deg"], default=0.0) for r in rows])
            out[f"{scenario}/{label}"] = {
                "runs": len(rows),
                "failed": failed,
                "heldout_ratio_median": float(np.median(ratio)) if rows else None,
                "heldout_ratio_le_1_3": float(np.mean(ratio <= 1.3)) if rows else None,
                "axis_ratio_error_median": float(np.median(axes)) if rows else None,
                "axis_ratio_error_le_10pct": float(np.mean(axes <= 0.10)) if rows else None,
                "worst_normal_error_deg_median": float(np.median(normal)) if rows else None,
                "normal_error_le_5deg": float(np.mean(normal <= 5.0)) if rows else None,
                "fit_s_median": float(np.median([r["fit_s"] for r in rows])) if rows else None,
            }
    return out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_sections_argument(parser, (*SCENARIOS, "speed"))
    parser.add_argument("--runs", type=int, default=2, help="runs per object and scenario")
    parser.add_argument("--seed", type=int, default=34)
    parser.add_argument("--normals", type=int, default=2000)
    parser.add_argument("--objects", default="", help="comma-separated subset of the objects")
    parser.add_argument("--baseline-objects", type=int, default=3)
    parser.add_argument("--out", default=None, help="also write the JSON here")
    args = parser.parse_args(argv)
    shapes = objects()
    chosen = [n for n in args.objects.split(",") if n] or sorted(shapes)
    records = []
    for scenario in SCENARIOS:
        if scenario not in args.sections:
            continue
        for name in chosen:
            for run in range(args.runs):
                records.append(run_case(name, shapes[name], scenario, run, args))
    report = {
        "benchmark": "shape_recovery",
        "machine": machine_info(),
        "seed": args.seed,
        "runs_per_object": args.runs,
        "normals": args.normals,
        "summary": summarise(records),
        "records": records,
    }
    if "speed" in args.sections:
        report["speed"] = speed(args)
    emit_report(report, args.out)


if __name__ == "__main__":
    main()
