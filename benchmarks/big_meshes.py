"""Shape models of 10⁴–10⁵ facets: ``shapes add`` (with the visibility table), ``simulate`` of
10⁴ epochs with ``--shadows table``, peak memory, and the table's accuracy.

Meshes: a noisy sphere of 5 120 facets (:func:`benchmarks.shapes.bumpy_sphere`), Itokawa at
12 288 facets and Eros at 49 152 (the Gaskell models shipped in ``data/shapes``, in km;
``--meshes DIR`` for another folder), and the 20 480-facet non-convex blob of
:mod:`benchmarks.simulate`. Each command runs as a subprocess of its own, timed from process
start to exit, with its own peak RSS (``ru_maxrss``).

Baseline, same run: the table built the former way — every point toward every direction,
one thread (``refine=False, workers=1``) — on the 5 120-facet sphere (``--baseline``: the
meshes it is timed on), with the ratio to the coarse-to-fine build on all threads.

Accuracy: the table's joint lit-and-seen fraction and visible fraction at random directions
against exact ray casting with the table's own sampling (:func:`shapes.joint_visible_fraction`),
for the coarse-to-fine table and the every-ray table of the same shape, and the share of
their bits that differ: the box-wing and Itokawa (768 facets) of the built-in library and
Itokawa at 12 288 facets. Seed 20261206 for every draw; phase angles uniform in 0–120°.

    python -m benchmarks.big_meshes [--meshes DIR] [--sections build,accuracy]
        [--directions 2000] [--epochs 10000] [--baseline sphere_5120] [--out FILE]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

import shapes
from benchmarks._machine import machine_info
from benchmarks._report import add_sections_argument, emit_report
from benchmarks.shapes import bumpy_sphere
from benchmarks.simulate import blob_mesh, geometry_file, run
from shapes.visibility import build_visibility_table

SEED = 20261206
Q0 = "0.2,-0.4,0.1,0.888819"
OMEGA0 = "1.5,-0.8,2.2"  # deg/s


def _sphere(path: Path) -> str:
    shapes.write_obj(bumpy_sphere(4), path)
    return "m"


def _blob(path: Path) -> str:
    blob_mesh(path)
    return "m"


def _shipped(name: str, folder: Path) -> Callable[[Path], str]:
    def write(path: Path) -> str:
        path.write_bytes((folder / f"{name}.obj").read_bytes())
        return "km"

    return write


def meshes(folder: Path) -> dict[str, Callable[[Path], str]]:
    """Case name → writer of its OBJ file (returns the file's length unit)."""
    return {
        "sphere_5120": _sphere,
        "itokawa_12288": _shipped("itokawa_32", folder),
        "blob_20480": _blob,
        "eros_49152": _shipped("eros_64", folder),
    }


def add_and_simulate(name: str, write: Callable[[Path], str], work: Path, epochs: int) -> dict:
    """Time and peak memory of ``shapes add`` and of ``simulate --shadows table``."""
    mesh = work / f"{name}.obj"
    unit = write(mesh)
    library = work / "library"
    cli = [sys.executable, "-m", "lightcurve.cli"]
    add = [*cli, "shapes", "add", name, str(mesh), "--units", unit, "--library", str(library)]
    add_s, add_mib = run([*add, "-q"])
    geometry = work / "geometry.csv"
    if not geometry.exists():
        geometry_file(geometry, epochs)
    simulate = [
        *cli, "simulate", str(geometry), "--shape", name, "--library", str(library),
        "--q0", Q0, "--omega0", OMEGA0, "--shadows", "table", "--out", str(work / "sim.csv"),
    ]  # fmt: skip
    simulate_s, simulate_mib = run(simulate)
    model = shapes.ShapeLibrary(library).load(name)
    table = model.visibility
    return {
        "shape": name,
        "facets": len(model.faces),
        "effective_facets": len(model.compiled()),
        "sample_points": table.n_points,
        "directions": len(table.grid),
        "add_seconds": round(add_s, 1),
        "add_peak_mib": round(add_mib),
        "simulate_epochs": epochs,
        "simulate_seconds": round(simulate_s, 1),
        "simulate_peak_mib": round(simulate_mib),
        "table_mib": round(table.bits.nbytes / 2**20, 1),
    }


def build_ratio(compiled: shapes.CompiledFacets) -> dict:
    """Build time of the former way (every ray, one thread) and of the coarse-to-fine build
    on every core, with the share of bits that differ."""
    start = time.perf_counter()
    every = build_visibility_table(compiled, refine=False, workers=1)
    every_s = time.perf_counter() - start
    start = time.perf_counter()
    refined = build_visibility_table(compiled)
    refined_s = time.perf_counter() - start
    return {
        "every_ray_one_thread_seconds": round(every_s, 1),
        "refined_seconds": round(refined_s, 1),
        "speed_up": round(every_s / refined_s, 2),
        "differing_bits": _differing(refined, every),
    }


def _differing(a: shapes.VisibilityTable, b: shapes.VisibilityTable) -> float:
    return float(np.unpackbits((a.bits ^ b.bits).view(np.uint8)).sum() / a.bits.size / 64)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def accuracy(
    compiled: shapes.CompiledFacets, n_directions: int, *, seed: int = SEED, **options
) -> dict:
    """Errors against exact ray casting of the coarse-to-fine and the every-ray tables.

    ``options`` go to :func:`build_visibility_table` (e.g. a small ``resolution``).
    """
    refined = build_visibility_table(compiled, **options)
    every = build_visibility_table(compiled, refine=False, **options)
    rng = np.random.default_rng(seed)
    light = _unit(rng.normal(size=(n_directions, 3)))
    axis = _unit(np.cross(light, rng.normal(size=light.shape)))
    phase = np.radians(rng.uniform(0.0, 120.0, n_directions))[:, None]
    view = light * np.cos(phase) + np.cross(axis, light) * np.sin(phase)
    samples = refined.samples
    exact = shapes.visible_fraction(compiled, light, samples=samples, spacing=refined.spacing)
    joint = shapes.joint_visible_fraction(
        compiled, light, view, samples=samples, spacing=refined.spacing
    )
    front = (light @ compiled.normals.T > 0) & compiled.can_be_shadowed
    both = front & (view @ compiled.normals.T > 0)
    row: dict = {"directions": n_directions, "seed": seed, "sample_points": refined.n_points}
    for label, table in (("refined", refined), ("every_ray", every)):
        error = np.abs(table.interpolate(light) - exact)[front]
        joint_error = np.abs(table.joint(light, view) - joint)[both]
        row[label] = {
            "mean_abs_error": round(float(error.mean()), 5),
            "p99_abs_error": round(float(np.quantile(error, 0.99)), 4),
            "joint_mean_abs_error": round(float(joint_error.mean()), 5),
            "joint_p99_abs_error": round(float(np.quantile(joint_error, 0.99)), 4),
        }
    row["differing_bits"] = _differing(refined, every)
    return row


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--meshes", type=Path, default=Path("data/shapes"), metavar="DIR")
    parser.add_argument("--directions", type=int, default=2000)
    parser.add_argument("--epochs", type=int, default=10_000)
    parser.add_argument("--baseline", default="sphere_5120", metavar="NAME[,NAME…]")
    parser.add_argument("--cases", default=None, metavar="NAME[,NAME…]", help="default: all")
    parser.add_argument("--out", default=None)
    add_sections_argument(parser, ("build", "accuracy"))
    args = parser.parse_args(argv)
    cases = meshes(args.meshes)
    chosen = args.cases.split(",") if args.cases else list(cases)
    report: dict = {
        "machine": machine_info(),
        "load_average_before": os.getloadavg(),
        "seed": SEED,
    }
    if "build" in args.sections:
        rows = []
        with tempfile.TemporaryDirectory() as folder:
            for name in chosen:
                row = add_and_simulate(name, cases[name], Path(folder), args.epochs)
                if name in args.baseline.split(","):
                    model = shapes.ShapeLibrary(Path(folder) / "library").load(
                        name, visibility=False
                    )
                    row["baseline"] = build_ratio(model.compiled())
                rows.append(row)
        report["build"] = rows
    if "accuracy" in args.sections:
        library = shapes.get_library(shapes.builtin_library_path())
        models = {name: library.load(name, visibility=False) for name in ("box_wing", "itokawa")}
        models["itokawa_12288"] = shapes.load(args.meshes / "itokawa_32.obj", unit="km")
        report["accuracy"] = {
            name: accuracy(model.compiled(), args.directions if "12288" not in name else 300)
            for name, model in models.items()
        }
    report["load_average_after"] = os.getloadavg()
    emit_report(report, args.out)


if __name__ == "__main__":
    main()
