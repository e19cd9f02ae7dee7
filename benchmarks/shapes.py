"""Shape benchmarks: visibility-table build time vs facet count, coplanar-merge reduction,
table accuracy against ray casting, and table interpolation throughput.

Run ``python benchmarks/shapes.py [--quick] [--sections build,merge,accuracy,interpolation]``;
prints one JSON document. ``--quick`` uses smaller grids and fewer directions (a smoke run);
the default reproduces the figures of docs/shapes.md (about 10 minutes on one core, most of it
the 5120-facet table build). Seed 20261122 for every random draw.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

# This script is named like the package: put the repository, not its own folder, on the path.
_HERE = Path(__file__).resolve().parent
sys.path[:] = [str(_HERE.parent)] + [p for p in sys.path if Path(p or ".").resolve() != _HERE]

import numpy as np  # noqa: E402
import torch  # noqa: E402

import shapes  # noqa: E402
from benchmarks._machine import machine_info  # noqa: E402
from shapes import primitives  # noqa: E402
from shapes.raycast import has_embree  # noqa: E402
from shapes.visibility import DEFAULT_RESOLUTION, DEFAULT_SAMPLES  # noqa: E402

SEED = 20261122


def bumpy_sphere(subdivisions: int) -> shapes.FacetModel:
    """A non-convex rock: an icosphere with seeded low-order radial relief (±25 %)."""
    base = primitives.icosphere(100.0, subdivisions)
    rng = np.random.default_rng(SEED)
    u = base.vertices / np.linalg.norm(base.vertices, axis=1, keepdims=True)
    waves = rng.normal(size=(6, 3))
    relief = sum(np.sin(3.0 * u @ w + k) for k, w in enumerate(waves)) / len(waves)
    return base.replace(vertices=base.vertices * (1.0 + 0.5 * relief)[:, None], name="bumpy")


def build_times(resolution: int, samples: int, sizes: list[int]) -> list[dict]:
    library = shapes.get_library(shapes.builtin_library_path())
    models = [bumpy_sphere(s) for s in sizes] + [library.load(n) for n in ("itokawa", "bennu")]
    rows = []
    for model in models:
        compiled = model.compiled()
        shadowable = int(compiled.can_be_shadowed.sum())
        start = time.perf_counter()
        table = shapes.build_visibility_table(compiled, resolution=resolution, samples=samples)
        seconds = time.perf_counter() - start
        rays = len(table.grid) * shadowable * samples  # approximately (rounded subdivisions)
        rows.append(
            {
                "shape": model.name,
                "facets": len(model.faces),
                "effective_facets": len(compiled),
                "shadowable_facets": shadowable,
                "directions": len(table.grid),
                "samples_per_facet": samples,
                "rays": rays,
                "seconds": round(seconds, 2),
                "mrays_per_s": round(rays / seconds / 1e6, 2),
            }
        )
    return rows


def merge_reduction() -> list[dict]:
    library = shapes.get_library(shapes.builtin_library_path())
    models = [library.load(name, build_visibility=False) for name in library.names()]
    models.append(primitives.box_wing(subdivisions=7, name="box_wing (CAD, subdivisions=7)"))
    rows = []
    for model in models:
        compiled = model.compiled()
        rows.append(
            {
                "shape": model.name,
                "facets": len(model.faces),
                "effective_facets": len(compiled),
                "reduction": round(len(model.faces) / len(compiled), 2),
                "convex": model.is_convex,
            }
        )
    return rows


def table_accuracy(n_directions: int) -> list[dict]:
    library = shapes.get_library(shapes.builtin_library_path())
    rng = np.random.default_rng(SEED)
    d = rng.normal(size=(n_directions, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    rows = []
    for name in ("box_wing", "itokawa"):
        compiled = library.load(name).compiled()
        table = compiled.visibility
        start = time.perf_counter()
        exact = shapes.visible_fraction(compiled, d, samples=table.samples)
        seconds = time.perf_counter() - start
        error = np.abs(table.interpolate(d) - exact)
        relevant = (d @ compiled.normals.T > 0) & compiled.can_be_shadowed
        e = error[relevant]
        rows.append(
            {
                "shape": name,
                "directions": n_directions,
                "seed": SEED,
                "samples_per_facet": table.samples,
                "pairs_compared": int(relevant.sum()),
                "mean_abs_error": round(float(e.mean()), 5),
                "p99_abs_error": round(float(np.quantile(e, 0.99)), 4),
                "max_abs_error": round(float(e.max()), 4),
                "mean_abs_error_all_front_facing": round(
                    float(error[d @ compiled.normals.T > 0].mean()), 5
                ),
                "exact_ray_casting_seconds": round(seconds, 2),
            }
        )
    return rows


def interpolation_throughput(chunk: int, repeats: int) -> list[dict]:
    """Best-of-``repeats`` time of one renderer-sized chunk of directions (Itokawa, K = 768)."""
    library = shapes.get_library(shapes.builtin_library_path())
    table = library.load("itokawa").compiled().visibility
    d = np.random.default_rng(SEED).normal(size=(chunk, 3))
    rows = []
    cases = [("numpy", "float32", None), ("numpy", "float64", None)]
    cases += [("torch", "float32", 1), ("torch", "float32", torch.get_num_threads())]
    for kind, dtype, threads in cases:
        x = d.astype(dtype) if kind == "numpy" else torch.as_tensor(d, dtype=getattr(torch, dtype))
        saved = torch.get_num_threads()
        if threads:
            torch.set_num_threads(threads)
        table.interpolate(x[:10])  # warm the caches
        seconds = np.inf
        for _ in range(repeats):  # best of several: the machine is shared
            start = time.perf_counter()
            table.interpolate(x)
            seconds = min(seconds, time.perf_counter() - start)
        torch.set_num_threads(saved)
        rows.append(
            {
                "array": kind,
                "dtype": dtype,
                "torch_threads": threads,
                "directions": chunk,
                "facets": table.n_facets,
                "milliseconds": round(1e3 * seconds, 2),
                "m_facet_directions_per_s": round(chunk * table.n_facets / seconds / 1e6, 1),
            }
        )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small grids, few directions")
    parser.add_argument(
        "--sections",
        default="build,merge,accuracy,interpolation",
        help="comma-separated subset of build, merge, accuracy, interpolation",
    )
    args = parser.parse_args()
    sections = set(args.sections.split(","))
    resolution = 10 if args.quick else DEFAULT_RESOLUTION
    result: dict = {
        "machine": {**machine_info(), "ray_backend": "embree" if has_embree else "trimesh"}
    }
    if "build" in sections:
        sizes = [1, 2] if args.quick else [1, 2, 3, 4]
        result["visibility_build"] = build_times(resolution, DEFAULT_SAMPLES, sizes)
    if "merge" in sections:
        result["merge_reduction"] = merge_reduction()
    if "accuracy" in sections:
        result["table_accuracy"] = table_accuracy(200 if args.quick else 1000)
    if "interpolation" in sections:
        result["interpolation"] = interpolation_throughput(4096, 3 if args.quick else 10)
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
