"""Renderer throughput: the fused kernels against the torch path and the numpy reference.

One run measures, each with its baseline and the ratio (best of ``--repeats``):

* every BRDF on 1280 facets (an icosphere) × 10⁴ epochs, float32 and float64: the default
  (fused numba) path vs the torch path (``backend="torch"``, what every call used before)
  and the straightforward numpy reference (``lightcurve.photometry.reference``); each BRDF's rate
  relative to Lambert's;
* Ashikhmin–Shirley on 20 480 facets and in the particle-filter shape (10⁴ attitudes × one
  epoch), relative to the 1280-facet rate;
* every BRDF on one thread in CPU time (``time.thread_time``: what other processes take
  of a shared machine's cores is left out), with Lambert's rate over each;
* with ``--against REV``: the fused kernels of git revision ``REV``
  (``lightcurve/photometry/kernels/`` as it was there, imported under another name) against
  the current ones, every BRDF, one thread, CPU time of the facet sums alone, alternated
  repeats (the before/after of a kernel change measured in one run);
* the one-off cost of the first call in a fresh process (kernel compilation, or loading it
  from numba's on-disk cache) measured in a subprocess;
* the cost of a small call (13 sigma points × one epoch of a 24-facet cylinder, the UKF's),
  µs per call, fused vs torch;
* table vs exact shadowing accuracy, and batch vs single calls.

Prints JSON with the machine and its load.

    python -m benchmarks.render [--epochs 10000] [--repeats 3] [--threads N] [--against REV]
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import pathlib
import subprocess
import sys
import tempfile
import time

import numpy as np
import torch

from benchmarks._machine import machine_info
from benchmarks._timing import best_time
from filters.attitude import random_quaternion
from lightcurve.photometry.kernels import get_num_threads, set_num_threads
from lightcurve.photometry.reference import reference_flux
from lightcurve.photometry.render import Renderer
from shapes import Material, get_library, primitives

MATERIALS = {
    "lambert": {"rd": 0.5},
    "phong": {"rd": 0.3, "rs": 0.4, "n": 50.0},
    "cook-torrance": {"rd": 0.3, "rs": 0.5, "m": 0.2, "f0": 0.9},
    "ashikhmin-shirley": {"rd": 0.3, "rs": 0.4, "nu": 100.0, "nv": 100.0},
    "anisotropic": {"rd": 0.3, "rs": 0.4, "nu": 10.0, "nv": 1000.0},
    "lommel-seeliger": {"w": 0.2, "c": 0.1, "a": 0.5, "d": 0.1, "k": -0.5},
    "two-lobe": {"rd": 0.2, "rb": 0.3, "ab": 0.3, "fb": 0.9, "rn": 0.3, "mn": 0.1, "fn": 0.04},
}


def workload(n_epochs: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    q = random_quaternion(n_epochs, rng)
    sun = np.tile([1.496e11, 0.0, 0.0], (n_epochs, 1))
    obs = rng.normal(size=(n_epochs, 3))
    obs *= 4e7 / np.linalg.norm(obs, axis=1, keepdims=True)
    return q, sun, obs


def shadow_table_accuracy(n: int = 2000, seed: int = 20261122) -> dict:
    """``table`` vs ``exact`` shadowing, mag, over ``n`` random attitudes and geometries."""
    rng = np.random.default_rng(seed)
    q = random_quaternion(n, rng)
    sun = rng.normal(size=(n, 3))
    sun *= 1.496e11 / np.linalg.norm(sun, axis=1, keepdims=True)
    obs = rng.normal(size=(n, 3))
    obs *= 4e7 / np.linalg.norm(obs, axis=1, keepdims=True)
    out = {}
    for name in ("box_wing", "itokawa"):
        shape = get_library().load(name)
        table = Renderer(shape, shadows="table").magnitude(q, sun, obs)
        exact = Renderer(shape, shadows="exact").magnitude(q, sun, obs)
        both = np.isfinite(table) & np.isfinite(exact)
        diff = table[both] - exact[both]
        out[name] = {
            "geometries": n,
            "lit_and_seen": int(both.sum()),
            "dark_mismatch": int(np.sum(np.isfinite(table) != np.isfinite(exact))),
            "rms_mag": float(np.sqrt(np.mean(diff**2))),
            "max_abs_mag": float(np.max(np.abs(diff))),
            "seed": seed,
        }
    return out


def batch_equals_single_calls(n: int = 10_000, seed: int = 1) -> dict:
    """A batch of ``n`` attitudes gives the same magnitudes as ``n`` single calls."""
    rng = np.random.default_rng(seed)
    renderer = Renderer(get_library().load("box_wing"))
    q = random_quaternion(n, rng)
    sun, obs = np.array([1.496e11, 0.0, 0.0]), np.array([3.0e7, 2.0e7, 1.0e6])
    start = time.perf_counter()
    batch = renderer.flux(q, sun, obs)
    batch_s = time.perf_counter() - start
    start = time.perf_counter()
    single = np.array([renderer.flux(qi, sun, obs) for qi in q])
    single_s = time.perf_counter() - start
    return {
        "attitudes": n,
        "max_relative_difference": float(np.max(np.abs(single - batch) / np.max(batch))),
        "batch_seconds": batch_s,
        "single_calls_seconds": single_s,
    }


def material_shape(base, name: str):
    """``base`` with every group of BRDF ``name`` (MATERIALS)."""
    brdf_name = "ashikhmin-shirley" if name == "anisotropic" else name
    return base.with_materials({g: Material(brdf_name, MATERIALS[name]) for g in base.group_names})


def rate(renderer: Renderer, q, sun, obs, repeats: int) -> float:
    """Facet-epochs per second of ``renderer.flux`` (after one warm-up call)."""
    renderer.flux(q[:64], sun[:64] if sun.ndim > 1 else sun, obs[:64] if obs.ndim > 1 else obs)
    seconds = best_time(lambda: renderer.flux(q, sun, obs), repeats)
    return renderer.n_facets * len(q) / seconds


def cpu_rate(renderer: Renderer, q, sun, obs, repeats: int) -> float:
    """Facet-epochs per CPU-second of ``renderer.flux`` on the calling thread alone.

    CPU time of the calling thread (``time.thread_time``) rather than wall time: on a shared
    machine, the time other processes hold the core is left out.
    """
    renderer.flux(q[:64], sun[:64] if sun.ndim > 1 else sun, obs[:64] if obs.ndim > 1 else obs)
    set_num_threads(1)
    try:
        best = np.inf
        for _ in range(repeats):
            start = time.thread_time()
            renderer.flux(q, sun, obs)
            best = min(best, time.thread_time() - start)
    finally:
        set_num_threads(None)  # back to following torch's thread count
    return renderer.n_facets * len(q) / best


def single_thread_cpu_rates(sphere, q, sun, obs, repeats: int) -> dict:
    """Every BRDF on one thread, in CPU time, with Lambert's rate over each (per dtype)."""
    out = {}
    for dtype in (torch.float32, torch.float64):
        key = str(dtype).split(".")[-1]
        rates = {
            name: cpu_rate(
                Renderer(material_shape(sphere, name), dtype=dtype), q, sun, obs, repeats
            )
            for name in MATERIALS
        }
        out[key] = {
            name: {
                "facet_epochs_per_cpu_second": value,
                "lambert_over_this": rates["lambert"] / value,
            }
            for name, value in rates.items()
        }
    return out


def kernels_at(revision: str):
    """The fused kernels of git ``revision``, imported as a package of another name.

    The kernels live in ``lightcurve/photometry/kernels/``; revisions before the rooms of
    ``lightcurve`` had them in ``lightcurve/photometry/kernels/``.
    """
    root = pathlib.Path(__file__).resolve().parents[1]

    def git(*args: str) -> str:
        return subprocess.run(
            ["git", *args], cwd=root, check=True, capture_output=True, text=True
        ).stdout

    name = "kernels_" + git("rev-parse", "--short", revision).strip()
    folder = pathlib.Path(tempfile.mkdtemp(prefix="render-kernels-")) / name
    folder.mkdir()
    for package in ("lightcurve/photometry/kernels", "lightcurve/kernels"):
        paths = git("ls-tree", "--name-only", revision, package + "/").split()
        if paths:
            break
    for path in paths:
        if path.endswith(".py"):
            text = git("show", f"{revision}:{path}").replace(package.replace("/", "."), name)
            (folder / pathlib.Path(path).name).write_text(text)
    sys.path.insert(0, str(folder.parent))
    return importlib.import_module(name)


def fused_flux(kernels, renderer: Renderer):
    """``renderer``'s facets and materials as a ``FusedFlux`` of the package ``kernels``."""
    compiled, order = renderer.compiled, renderer._order
    dtype = renderer._numpy_dtype
    table = kernels.facet_table(
        compiled.normals[order], compiled.areas[order], compiled.tangents[order], dtype
    )
    blocks = []
    for block in renderer._blocks:
        kind, row = kernels.block_parameters(
            block.model.name, block.model.params, block.model.anisotropic
        )
        blocks.append((kind, block.start, block.stop, row))
    return kernels.FusedFlux(table, blocks, dtype)


def against_revision(revision: str, sphere, q, sun, obs, repeats: int) -> dict:
    """Facet sums of every BRDF by the kernels of ``revision`` and by the current ones: one
    thread, CPU time, best of ``repeats`` alternated runs, with Lambert's rate over each."""
    previous = kernels_at(revision)
    out = {"revision": revision}
    for dtype in (torch.float32, torch.float64):
        key = str(dtype).split(".")[-1]
        seconds = {}
        for name in MATERIALS:
            renderer = Renderer(material_shape(sphere, name), dtype=dtype)
            if any(block.model.name not in previous.KINDS for block in renderer._blocks):
                continue  # no fused kernel for this BRDF at that revision
            pair = {"previous": fused_flux(previous, renderer), "current": renderer._fused_flux()}
            light, view, _ = pair["current"].geometry(q, sun, obs, 0.0)
            sums = {tag: flux.sums(light, view) for tag, flux in pair.items()}  # compiles
            best = dict.fromkeys(pair, np.inf)
            previous.set_num_threads(1)
            set_num_threads(1)
            try:
                for _ in range(repeats):
                    for tag, flux in pair.items():
                        start = time.thread_time()
                        flux.sums(light, view)
                        best[tag] = min(best[tag], time.thread_time() - start)
            finally:
                previous.set_num_threads(None)
                set_num_threads(None)
            scale = np.max(np.abs(sums["previous"]))
            seconds[name] = best | {
                "max_relative_difference": float(
                    np.max(np.abs(sums["current"] - sums["previous"])) / scale
                )
            }
        facet_epochs = len(sphere.compiled()) * len(q)
        out[key] = {
            name: {
                "previous_facet_epochs_per_cpu_second": facet_epochs / value["previous"],
                "current_facet_epochs_per_cpu_second": facet_epochs / value["current"],
                "speedup": value["previous"] / value["current"],
                "lambert_over_this_previous": value["previous"] / seconds["lambert"]["previous"],
                "lambert_over_this_current": value["current"] / seconds["lambert"]["current"],
                "max_relative_difference": value["max_relative_difference"],
            }
            for name, value in seconds.items()
        }
    return out


def first_call_seconds(dtype: str) -> dict:
    """Fresh-process cost of the first fused call: import, compile or cache load, render."""
    code = (
        "import time, numpy as np; t0 = time.perf_counter();"
        "from lightcurve.photometry.render import Renderer;"
        "from shapes import primitives, Material;"
        "s = primitives.icosphere(1.0, subdivisions=3);"
        "s = s.with_materials({g: Material('ashikhmin-shirley', {'rd': 0.3, 'rs': 0.4,"
        " 'nu': 100.0, 'nv': 100.0}) for g in s.group_names});"
        f"import torch; r = Renderer(s, dtype=torch.{dtype}); t1 = time.perf_counter();"
        "r.flux(np.array([0, 0, 0, 1.0]), np.array([1.5e11, 0, 0]), np.array([4e7, 1e7, 0]));"
        "t2 = time.perf_counter(); print(t1 - t0, t2 - t1)"
    )
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True)
    setup, first = (float(v) for v in out.stdout.split())
    return {"imports_and_shape_seconds": setup, "first_call_seconds": first}


def small_calls(repeats: int) -> dict:
    """µs per call for 13 attitudes × one epoch of a 24-facet cylinder (a UKF's sigma points)."""
    shape = primitives.cylinder(sections=22)
    q = random_quaternion(13, np.random.default_rng(2))
    sun, obs = np.array([1.496e11, 0.0, 0.0]), np.array([3.0e7, 2.0e7, 1.0e6])
    out = {"facets": len(shape.compiled()), "rows": 13}
    calls = 200
    for backend in ("auto", "torch"):
        renderer = Renderer(shape, backend=backend)
        renderer.flux(q, sun, obs)
        seconds = best_time(lambda r=renderer: [r.flux(q, sun, obs) for _ in range(calls)], repeats)
        out[f"{'fused' if backend == 'auto' else 'torch'}_us_per_call"] = seconds / calls * 1e6
    out["speedup"] = out["torch_us_per_call"] / out["fused_us_per_call"]
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--epochs", type=int, default=10_000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument(
        "--threads", type=int, help="torch intra-op threads (default: torch's own choice)"
    )
    parser.add_argument(
        "--against", metavar="REV", help="also time the fused kernels of git revision REV"
    )
    args = parser.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    first_calls = {dtype: first_call_seconds(dtype) for dtype in ("float32", "float64")}
    sphere = primitives.icosphere(1.0, subdivisions=3)  # 1280 facets
    q, sun, obs = workload(args.epochs)
    results = []
    for name in MATERIALS:
        shape = material_shape(sphere, name)
        row = {"brdf": name, "facets": len(shape.compiled()), "epochs": args.epochs}
        n_base = max(1, args.epochs // 20)  # the baselines are slow: time a twentieth
        sub = (q[:n_base], sun[:n_base], obs[:n_base])
        for dtype in (torch.float32, torch.float64):
            key = str(dtype).split(".")[-1]
            fused = rate(Renderer(shape, dtype=dtype), q, sun, obs, args.repeats)
            eager = rate(Renderer(shape, dtype=dtype, backend="torch"), *sub, args.repeats)
            start = time.perf_counter()
            reference_flux(shape, *sub, dtype=np.dtype(key).type)
            numpy_rate = row["facets"] * n_base / (time.perf_counter() - start)
            row[f"fused_{key}"] = fused
            row[f"torch_path_{key}"] = eager
            row[f"numpy_reference_{key}"] = numpy_rate
            row[f"fused_vs_torch_path_{key}"] = fused / eager
            row[f"fused_vs_numpy_{key}"] = fused / numpy_rate
        results.append(row)
    lambert = results[0]
    for row in results:
        for key in ("float32", "float64"):
            row[f"lambert_rate_over_this_{key}"] = lambert[f"fused_{key}"] / row[f"fused_{key}"]
    ashikhmin = next(row for row in results if row["brdf"] == "ashikhmin-shirley")
    # Ashikhmin–Shirley at 20 480 facets and in the particle-filter shape.
    large = material_shape(primitives.icosphere(1.0, subdivisions=5), "ashikhmin-shirley")
    particles = random_quaternion(10_000, np.random.default_rng(1))
    scaling = {}
    for dtype in (torch.float32, torch.float64):
        key = str(dtype).split(".")[-1]
        n_large = max(1, args.epochs // 4)
        big = rate(Renderer(large, dtype=dtype), q[:n_large], sun[:n_large], obs[:n_large], 2)
        pf = rate(
            Renderer(material_shape(sphere, "ashikhmin-shirley"), dtype=dtype),
            particles,
            sun[0],
            obs[0],
            args.repeats,
        )
        scaling[key] = {
            "facets_20480": big,
            "facets_20480_over_1280": big / ashikhmin[f"fused_{key}"],
            "particle_filter_10k_particles_one_epoch": pf,
            "particle_filter_over_epochs": pf / ashikhmin[f"fused_{key}"],
        }
    print(
        json.dumps(
            {
                "benchmark": "render",
                "unit": "facet-epochs per second",
                "results": results,
                "ashikhmin_shirley_scaling": scaling,
                "single_thread_cpu_time": single_thread_cpu_rates(
                    sphere, q, sun, obs, max(args.repeats, 5)
                ),
                "previous_kernels": (
                    against_revision(args.against, sphere, q, sun, obs, max(args.repeats, 5))
                    if args.against
                    else None
                ),
                "first_call_fresh_process": first_calls,
                "small_calls": small_calls(args.repeats),
                "shadow_table_vs_exact": shadow_table_accuracy(),
                "batch_vs_single_calls": batch_equals_single_calls(),
                "load_average": os.getloadavg(),
                "machine": machine_info(),
                "kernel_threads": get_num_threads(),
            },
            indent=2,
        )
    )


if __name__ == "__main__":
    main()
