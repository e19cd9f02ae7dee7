"""Shape benchmarks: visibility-table build time and memory vs facet count, coplanar-merge
reduction, table accuracy against ray casting, lookup throughput, and rendering speed with
tables against rendering without shadows.

Run ``python benchmarks/shapes.py [--quick] [--sections build,merge,accuracy,lookup,render,
breakdown]``;
prints one JSON document with the machine and its load. ``--quick`` uses smaller grids and
fewer directions (a smoke run); the default reproduces the figures of docs/shapes.md (about
15 minutes on one core, most of it the 5120-facet table build). Seed 20261122 for every
random draw.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from functools import partial
from pathlib import Path

# This script is named like the package: put the repository, not its own folder, on the path.
_HERE = Path(__file__).resolve().parent
sys.path[:] = [str(_HERE.parent)] + [p for p in sys.path if Path(p or ".").resolve() != _HERE]

import numpy as np  # noqa: E402
import torch  # noqa: E402

import shapes  # noqa: E402
from benchmarks._machine import machine_info  # noqa: E402
from benchmarks._report import add_sections_argument  # noqa: E402
from benchmarks._timing import best_time  # noqa: E402
from filters.attitude import random_quaternion  # noqa: E402
from lightcurve.photometry.render import Renderer  # noqa: E402
from shapes import primitives  # noqa: E402
from shapes.visibility import DEFAULT_RESOLUTION, DEFAULT_SAMPLES, DEFAULT_SPACING  # noqa: E402
from shapes.visibility.raycast import has_embree  # noqa: E402

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
    """Build time, rays, in-memory size (the bits and the lookup's per-cell entries, with the
    time to derive the latter when a table is loaded) and file size of the tables."""
    library = shapes.get_library(shapes.builtin_library_path())
    models = [bumpy_sphere(s) for s in sizes] + [library.load(n) for n in ("itokawa", "bennu")]
    rows = []
    for model in models:
        compiled = model.compiled()
        shadowable = int(compiled.can_be_shadowed.sum())
        start = time.perf_counter()
        table = shapes.build_visibility_table(compiled, resolution=resolution, samples=samples)
        seconds = time.perf_counter() - start
        rays = len(table.grid) * table.n_points
        table.joint(np.eye(3)[:1], np.eye(3)[:1])  # load the kernels
        fresh = table.rotated(np.eye(3))  # same table, nothing derived yet
        cpu = time.process_time()
        fresh.joint(np.eye(3)[:1], np.eye(3)[:1])
        lookup_cpu_seconds = time.process_time() - cpu
        with tempfile.TemporaryDirectory() as folder:
            path = Path(folder) / "table.visibility.npz"
            table.save(path)
            file_bytes = path.stat().st_size
        rows.append(
            {
                "shape": model.name,
                "facets": len(model.faces),
                "effective_facets": len(compiled),
                "shadowable_facets": shadowable,
                "directions": len(table.grid),
                "samples_per_facet": samples,
                "spacing": DEFAULT_SPACING,
                "sample_points": table.n_points,
                "rays": rays,
                "seconds": round(seconds, 2),
                "mrays_per_s": round(rays / seconds / 1e6, 2),
                "lookup_build_cpu_seconds": round(lookup_cpu_seconds, 2),
                "bits_mib": round(table.bits.nbytes / 2**20, 2),
                "memory_mib": round(table.nbytes / 2**20, 2),
                "file_mib": round(file_bytes / 2**20, 2),
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
    """Table lookups against ray casting with the table's own sampling: the visible fraction
    of one direction and the joint (lit and seen) fraction of pairs at phase angles 0–120°."""
    library = shapes.get_library(shapes.builtin_library_path())
    rng = np.random.default_rng(SEED)
    d = _unit(rng.normal(size=(n_directions, 3)))
    axis = _unit(np.cross(d, rng.normal(size=d.shape)))
    phase = np.radians(rng.uniform(0.0, 120.0, n_directions))[:, None]
    view = d * np.cos(phase) + np.cross(axis, d) * np.sin(phase)
    rows = []
    for name in ("box_wing", "itokawa"):
        compiled = library.load(name).compiled()
        table = compiled.visibility
        start = time.perf_counter()
        exact = shapes.visible_fraction(compiled, d)
        seconds = time.perf_counter() - start
        error = np.abs(table.interpolate(d) - exact)
        front = d @ compiled.normals.T > 0
        relevant = front & compiled.can_be_shadowed
        start = time.perf_counter()
        joint_exact = shapes.joint_visible_fraction(compiled, d, view)
        joint_seconds = time.perf_counter() - start
        joint_error = np.abs(table.joint(d, view) - joint_exact)
        both = front & (view @ compiled.normals.T > 0) & compiled.can_be_shadowed
        rows.append(
            {
                "shape": name,
                "directions": n_directions,
                "seed": SEED,
                "samples_per_facet": table.samples,
                "sample_points": table.n_points,
                "pairs_compared": int(relevant.sum()),
                "mean_abs_error": round(float(error[relevant].mean()), 5),
                "p99_abs_error": round(float(np.quantile(error[relevant], 0.99)), 4),
                "max_abs_error": round(float(error[relevant].max()), 4),
                "mean_abs_error_all_front_facing": round(float(error[front].mean()), 5),
                "exact_ray_casting_seconds": round(seconds, 2),
                "joint_pairs_compared": int(both.sum()),
                "joint_mean_abs_error": round(float(joint_error[both].mean()), 5),
                "joint_p99_abs_error": round(float(np.quantile(joint_error[both], 0.99)), 4),
                "joint_max_abs_error": round(float(joint_error[both].max()), 4),
                "joint_exact_ray_casting_seconds": round(joint_seconds, 2),
            }
        )
    return rows


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def lookup_throughput(chunk: int, repeats: int) -> list[dict]:
    """Best-of-``repeats`` time of the joint lookup of one chunk of random ``(L, V)`` pairs
    (Itokawa, K = 768): numpy (compiled kernel) and torch (differentiable)."""
    library = shapes.get_library(shapes.builtin_library_path())
    table = library.load("itokawa").compiled().visibility
    rng = np.random.default_rng(SEED)
    light, view = _unit(rng.normal(size=(chunk, 3))), _unit(rng.normal(size=(chunk, 3)))
    rows = []
    for kind, dtype in (("numpy", "float32"), ("numpy", "float64"), ("torch", "float64")):
        if kind == "numpy":
            args = (light.astype(dtype), view.astype(dtype))
        else:
            args = tuple(torch.as_tensor(v, dtype=getattr(torch, dtype)) for v in (light, view))
        table.joint(args[0][:10], args[1][:10])  # compile or load the kernels
        seconds = best_time(lambda args=args: table.joint(*args), repeats)
        rows.append(
            {
                "array": kind,
                "dtype": dtype,
                "pairs": chunk,
                "facets": table.n_facets,
                "milliseconds": round(1e3 * seconds, 2),
                "m_facet_pairs_per_s": round(chunk * table.n_facets / seconds / 1e6, 1),
            }
        )
    return rows


def _light_curve(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A pass of a tumbling object: 120 s spin about a fixed (seeded) axis, 0.5 s cadence,
    the phase angle sweeping from 10° to 90°; returns ``q, sun, observer``."""
    rng = np.random.default_rng(SEED)
    axis = _unit(rng.normal(size=3))
    t = 0.5 * np.arange(n)
    angle = 2.0 * np.pi * t / 120.0
    q = np.column_stack([np.outer(np.sin(angle / 2), axis), np.cos(angle / 2)])
    sun = np.tile([1.496e11, 0.0, 0.0], (n, 1))
    phase = np.radians(np.linspace(10.0, 90.0, n))
    observer = 4e7 * np.column_stack([np.cos(phase), np.sin(phase), np.zeros(n)])
    return q, sun, observer


#: Materials the render speed is measured with: the shapes' own, and every distinct material
#: replaced by a Lambert or an Ashikhmin–Shirley one (albedos 0.01 apart, so that materials
#: stay distinct and the compiled facets, hence the tables, are unchanged).
MATERIALS = {
    "lambert": ("lambert", {"rd": 0.3}),
    "ashikhmin-shirley": ("ashikhmin-shirley", {"rd": 0.2, "rs": 0.5, "nu": 10.0, "nv": 10.0}),
}


def with_material(model: shapes.FacetModel, kind: str) -> shapes.FacetModel:
    """``model`` with its own materials (``"builtin"``) or those of :data:`MATERIALS`."""
    if kind == "builtin":
        return model
    brdf, params = MATERIALS[kind]
    distinct, index = model.distinct_materials
    replaced = [
        shapes.Material(brdf, {**params, "rd": params["rd"] + 0.01 * i})
        for i in range(len(distinct))
    ]
    return model.with_materials(
        {group: replaced[i] for group, i in zip(model.group_names, index, strict=True)}
    )


def _per_row(func, rows: int, clock) -> float:
    """Time of ``func()`` per row, µs."""
    start = clock()
    func()
    return 1e6 * (clock() - start) / rows


def render_speed(epochs: int, repeats: int, exact_epochs: int) -> list[dict]:
    """Per-row cost of ``Renderer(shadows=...)`` for "none", "table" and "exact" on the same
    epochs, best of ``repeats`` alternated rounds: CPU time of one thread (the kernels and
    torch set to one thread) and, for the shapes' own materials, wall time on two threads.
    Workloads: random attitudes (every epoch in other grid cells: the worst case for the
    lookup's caches) and a light curve; "exact" (ray casting) on the first ``exact_epochs``.
    """
    from lightcurve.photometry.kernels import set_num_threads

    library = shapes.get_library(shapes.builtin_library_path())
    rng = np.random.default_rng(SEED)
    observer = 4e7 * _unit(rng.normal(size=(epochs, 3)))
    workloads = {
        "random_attitudes": (
            random_quaternion(epochs, rng),
            np.tile([1.496e11, 0.0, 0.0], (epochs, 1)),
            observer,
        ),
        "light_curve": _light_curve(epochs),
    }
    settings = [("builtin", torch.float64, 1), ("builtin", torch.float32, 1)]
    settings += [(kind, torch.float64, 1) for kind in MATERIALS]
    settings += [("builtin", torch.float64, 2)]
    threads_before = torch.get_num_threads()
    rows = []
    for name in ("box_wing", "itokawa", "bennu"):
        for material, dtype, threads in settings:
            shape = with_material(library.load(name), material)
            modes = MODES if threads == 1 and dtype == torch.float64 else MODES[:2]
            renderers = {mode: Renderer(shape, shadows=mode, dtype=dtype) for mode in modes}
            torch.set_num_threads(threads)
            set_num_threads(threads)
            clock = time.process_time if threads == 1 else time.perf_counter
            for workload, (q, sun, obs) in workloads.items():
                size = {mode: exact_epochs if mode == "exact" else epochs for mode in modes}
                per_row = dict.fromkeys(modes, np.inf)
                for renderer in renderers.values():
                    renderer.flux(q[:10], sun[:10], obs[:10])  # compile or load the kernels
                for _ in range(repeats):
                    for mode, renderer in renderers.items():
                        k = size[mode]
                        run = lambda r=renderer, g=(q[:k], sun[:k], obs[:k]): r.flux(*g)  # noqa: E731
                        per_row[mode] = min(per_row[mode], _per_row(run, k, clock))
                row = {
                    "shape": name,
                    "facets": len(shape.compiled()),
                    "material": material,
                    "dtype": str(dtype).removeprefix("torch."),
                    "clock": "cpu, 1 thread" if threads == 1 else f"wall, {threads} threads",
                    "workload": workload,
                    "epochs": size,
                    **{f"{mode}_us_per_row": round(per_row[mode], 3) for mode in modes},
                    "table_over_none": round(per_row["table"] / per_row["none"], 2),
                }
                if "exact" in modes:
                    row["exact_over_none"] = round(per_row["exact"] / per_row["none"], 1)
                rows.append(row)
                print(json.dumps(rows[-1]), file=sys.stderr, flush=True)
    torch.set_num_threads(threads_before)
    set_num_threads(None)
    return rows


MODES = ("none", "table", "exact")


def table_breakdown(epochs: int, repeats: int) -> list[dict]:
    """Where the time of ``shadows="table"`` goes, per row (CPU time, one thread, float64,
    best of ``repeats`` alternated rounds): the unshadowed facet sums (what ``"none"``
    computes), the joint lookup that writes the dense (rows × facets) factor, and the facet
    sums that multiply that factor in; with the share of rows whose pair of grid cells
    (around ``L`` and around ``V``) an earlier row of the workload already visited."""
    from lightcurve.photometry.kernels import set_num_threads
    from lightcurve.photometry.render import AU_M

    library = shapes.get_library(shapes.builtin_library_path())
    rng = np.random.default_rng(SEED)
    workloads = {
        "random_attitudes": (
            random_quaternion(epochs, rng),
            np.tile([1.496e11, 0.0, 0.0], (epochs, 1)),
            4e7 * _unit(rng.normal(size=(epochs, 3))),
        ),
        "light_curve": _light_curve(epochs),
    }
    threads_before = torch.get_num_threads()
    torch.set_num_threads(1)
    set_num_threads(1)
    clock = time.process_time
    rows = []
    for name in ("box_wing", "itokawa", "bennu"):
        for material in MATERIALS:
            renderer = Renderer(with_material(library.load(name), material), shadows="table")
            renderer.flux(*(v[:10] for v in workloads["light_curve"]))  # load the kernels
            fused, table, slots = (
                renderer._fused_flux(),
                renderer.compiled.visibility,
                renderer._table_slots,
            )
            for workload, (q, sun, obs) in workloads.items():
                light, view, _ = fused.geometry(q, sun, obs, AU_M)
                factor = np.empty((epochs, fused.n_slots), fused.dtype)
                parts = {
                    "sums_unshadowed": partial(fused.sums, light, view),
                    "joint_lookup": partial(
                        table.joint, light, view, order=slots, facing=False, out=factor
                    ),
                    "sums_with_factor": partial(fused.sums, light, view, factor, per_slot=True),
                    "table_flux": partial(renderer.flux, q, sun, obs),
                }
                per_row = dict.fromkeys(parts, np.inf)
                for _ in range(repeats):
                    for part, run in parts.items():
                        per_row[part] = min(per_row[part], _per_row(run, epochs, clock))
                cells = [table.grid.locate(v)[0] for v in (light, view)]
                pairs = np.unique(np.column_stack([np.sort(c, axis=1) for c in cells]), axis=0)
                rows.append(
                    {
                        "shape": name,
                        "facets": len(renderer.compiled),
                        "material": material,
                        "workload": workload,
                        "epochs": epochs,
                        **{f"{part}_us_per_row": round(v, 3) for part, v in per_row.items()},
                        "revisited_cell_pairs": round(1.0 - len(pairs) / epochs, 3),
                    }
                )
                print(json.dumps(rows[-1]), file=sys.stderr, flush=True)
    torch.set_num_threads(threads_before)
    set_num_threads(None)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small grids, few directions")
    add_sections_argument(parser, ("build", "merge", "accuracy", "lookup", "render", "breakdown"))
    args = parser.parse_args()
    sections = args.sections
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
    if "lookup" in sections:
        result["joint_lookup"] = lookup_throughput(4096, 3 if args.quick else 10)
    if "render" in sections:
        result["render_speed"] = render_speed(
            1000 if args.quick else 10_000, 3 if args.quick else 7, 20 if args.quick else 200
        )
    if "breakdown" in sections:
        result["table_breakdown"] = table_breakdown(
            1000 if args.quick else 10_000, 3 if args.quick else 7
        )
    result["load_average"] = os.getloadavg()
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
