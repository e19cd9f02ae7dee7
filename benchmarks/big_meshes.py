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

Level of detail (``lod``): the proxy ``shapes add`` builds for Itokawa 12 288 and Eros
49 152 (with the Itokawa regolith of the built-in library), its facet count and its
light-curve error against the full mesh over 10⁴ random geometries (seed of
:mod:`lightcurve.photometry.proxy_error`), read from the manifest. Then ``invert --method ukf``
of one light curve simulated from the full Itokawa 12 288 (``--lod-epochs`` at 1 s, 0.02 mag
noise, seed 1): once with the 12 288-facet shape (which renders its proxy) and once with the
768-facet ``itokawa`` of the built-in library — the in-run baseline — each in its own
process, best of ``--repeats``, with the ratio of the wall times (process start to exit) and
of the summaries' ``runtime_s`` (the inversion alone, the last repeat's).

Accuracy: the table's joint lit-and-seen fraction and visible fraction at random directions
against exact ray casting with the table's own sampling (:func:`shapes.joint_visible_fraction`),
for the coarse-to-fine table and the every-ray table of the same shape, and the share of
their bits that differ: the box-wing and Itokawa (768 facets) of the built-in library and
Itokawa at 12 288 facets. Seed 20261206 for every draw; phase angles uniform in 0–120°.

    python -m benchmarks.big_meshes [--meshes DIR] [--sections build,lod,accuracy]
        [--directions 2000] [--epochs 10000] [--baseline sphere_5120] [--lod-epochs 300]
        [--repeats 2] [--out FILE]
"""

from __future__ import annotations

import argparse
import json
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
from shapes.library import builtin_library_path as builtin_path
from shapes.visibility import build_visibility_table

SEED = 20261206
Q0 = "0.2,-0.4,0.1,0.888819"
OMEGA0 = "1.5,-0.8,2.2"  # deg/s
CLI = [sys.executable, "-m", "lightcurve.cli"]


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
    add = [*CLI, "shapes", "add", name, str(mesh), "--units", unit, "--library", str(library)]
    add_s, add_mib = run([*add, "-q"])
    geometry = work / "geometry.csv"
    if not geometry.exists():
        geometry_file(geometry, epochs)
    simulate = [
        *CLI, "simulate", str(geometry), "--shape", name, "--library", str(library),
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


REGOLITH = ["--brdf", "lommel-seeliger"] + [
    f"--param={p}" for p in ("c=0.1", "a=0.5", "d=0.1", "k=-0.5")
]


def add_with_proxy(name: str, write: Callable[[Path], str], library: Path, work: Path) -> dict:
    """``shapes add`` (table and proxy) timed, with the proxy's record."""
    mesh = work / f"{name}.obj"
    unit = write(mesh)
    add = [*CLI, "shapes", "add", name, str(mesh), "--units", unit, "--library", str(library)]
    seconds, peak = run([*add, *REGOLITH, "-q"])
    return {
        "add_seconds": round(seconds, 1),
        "add_peak_mib": round(peak),
        **proxy_row(library, name),
    }


def proxy_row(library: Path, name: str) -> dict:
    """The facets of a shape and its proxy's record, from the library's manifest."""
    entry = shapes.ShapeLibrary(library).info(name)
    proxy = entry.get("proxy") or {}
    return {
        "shape": name,
        "facets": entry["facets"],
        "proxy_facets": proxy.get("facets"),
        "proxy_rms_mag": proxy.get("rms_mag"),
        "proxy_max_mag": proxy.get("max_mag"),
        "proxy_geometries": proxy.get("geometries"),
        "proxy_seed": proxy.get("seed"),
        "proxy_shadows": proxy.get("shadows"),
    }


def invert_ratio(name: str, library: Path, work: Path, *, epochs: int, repeats: int) -> dict:
    """``invert`` of a light curve of ``name`` with that shape (its proxy) and with the
    768-facet built-in Itokawa, best wall time of ``repeats`` each, and the ratio."""
    geometry = work / "lod_geometry.csv"
    geometry_file(geometry, epochs)
    observations = work / "lod.csv"
    simulate = [
        *CLI, "simulate", str(geometry), "--shape", name, "--library", str(library),
        "--q0", Q0, "--omega0", OMEGA0, "--noise-mag", "0.02", "--seed", "1",
        "--out", str(observations), "-q",
    ]  # fmt: skip
    run(simulate)
    runs = {name: ["--library", str(library)], "itokawa": ["--library", str(builtin_path())]}
    row: dict = {"epochs": epochs, "noise_mag": 0.02, "repeats": repeats}
    for shape, library_option in runs.items():
        out = work / f"invert_{shape}"
        invert = [
            *CLI, "invert", str(observations), "--method", "ukf", "--shape", shape,
            *library_option, "--q0", Q0, "--omega0", OMEGA0, "--out", str(out),
            "--overwrite", "-q",
        ]  # fmt: skip
        times = [run(invert) for _ in range(repeats)]
        summary = json.loads((out / "lod" / "summary.json").read_text())
        row[shape] = {
            "seconds": round(min(t[0] for t in times), 1),
            "peak_mib": round(min(t[1] for t in times)),
            "runtime_s": round(summary["runtime_s"], 1),
            "status": summary["status"],
            "residual_rms_mag": summary["residual_rms_mag"],
            "shape_model": summary["shape_model"],
        }
    row["ratio"] = round(row[name]["seconds"] / row["itokawa"]["seconds"], 2)
    row["runtime_ratio"] = round(row[name]["runtime_s"] / row["itokawa"]["runtime_s"], 2)
    return row


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
    parser.add_argument("--lod-epochs", type=int, default=300)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--cases", default=None, metavar="NAME[,NAME…]", help="default: all")
    parser.add_argument("--out", default=None)
    add_sections_argument(parser, ("build", "lod", "accuracy"))
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
    if "lod" in args.sections:
        with tempfile.TemporaryDirectory() as folder:
            work = Path(folder)
            library = work / "library"
            rows = [
                add_with_proxy(name, cases[name], library, work)
                for name in ("itokawa_12288", "eros_49152")
                if name in chosen
            ]
            report["lod"] = {"proxies": rows, "load_average": os.getloadavg()}
            if "itokawa_12288" in chosen:
                report["lod"]["invert"] = invert_ratio(
                    "itokawa_12288", library, work, epochs=args.lod_epochs, repeats=args.repeats
                )
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
