"""Renderer throughput: facet-epochs per second per BRDF, float32/float64, eager/compiled.

Workload: 10³ facets (an icosphere with random-ish normals) × 10⁴ epochs, one material, for
each BRDF; and the particle-filter shape, 10⁴ attitudes × one epoch. The baseline is the
straightforward numpy implementation of the same formula (``lightcurve.reference``:
explicit vectors, whole (epochs × facets) matrices). Prints JSON.

    python -m benchmarks.render [--epochs 10000] [--no-compile]
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
import torch

from benchmarks._machine import machine_info
from filters.attitude import random_quaternion
from lightcurve.reference import reference_flux
from lightcurve.render import Renderer
from shapes import Material, get_library, primitives

MATERIALS = {
    "lambert": {"rd": 0.5},
    "phong": {"rd": 0.3, "rs": 0.4, "n": 50.0},
    "cook-torrance": {"rd": 0.3, "rs": 0.5, "m": 0.2, "f0": 0.9},
    "ashikhmin-shirley": {"rd": 0.3, "rs": 0.4, "nu": 100.0, "nv": 100.0},
    "lommel-seeliger": {"w": 0.2, "c": 0.1, "a": 0.5, "d": 0.1, "k": -0.5},
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


def best_time(func, repeats: int) -> float:
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        func()
        best = min(best, time.perf_counter() - start)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--epochs", type=int, default=10_000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--no-compile", action="store_true")
    parser.add_argument(
        "--threads", type=int, help="torch intra-op threads (default: torch's own choice)"
    )
    args = parser.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    sphere = primitives.icosphere(1.0, subdivisions=3)  # 1280 facets
    q, sun, obs = workload(args.epochs)
    results = []
    for name, params in MATERIALS.items():
        shape = sphere.with_materials({g: Material(name, params) for g in sphere.group_names})
        n_facets = len(shape.compiled())
        work = n_facets * args.epochs
        row = {"brdf": name, "facets": n_facets, "epochs": args.epochs}
        n_base = max(1, args.epochs // 10)  # the baseline is slow: time a tenth, scale
        sub = (q[:n_base], sun[:n_base], obs[:n_base])
        for dtype in (np.float32, np.float64):
            start = time.perf_counter()
            reference_flux(shape, *sub, dtype=dtype)
            row[f"numpy_baseline_{np.dtype(dtype).name}"] = (
                n_facets * n_base / (time.perf_counter() - start)
            )
        modes = [False] if args.no_compile else [False, True]
        for dtype in (torch.float32, torch.float64):
            for compiled in modes:
                renderer = Renderer(shape, dtype=dtype, compile=compiled)
                renderer.flux(q[:512], sun[:512], obs[:512])  # warm-up / compilation
                seconds = best_time(lambda r=renderer: r.flux(q, sun, obs), args.repeats)
                key = f"torch_{'compiled' if compiled else 'eager'}_{str(dtype).split('.')[-1]}"
                row[key] = work / seconds
        row["speedup_best_vs_numpy_float32"] = (
            max(v for k, v in row.items() if k.startswith("torch_") and k.endswith("float32"))
            / row["numpy_baseline_float32"]
        )
        results.append(row)
    # The particle-filter shape: 10⁴ attitudes against one epoch's geometry.
    shape = sphere.with_materials(
        {
            g: Material("ashikhmin-shirley", MATERIALS["ashikhmin-shirley"])
            for g in sphere.group_names
        }
    )
    particles = random_quaternion(10_000, np.random.default_rng(1))
    pf = {}
    for compiled in [False] if args.no_compile else [False, True]:
        renderer = Renderer(shape, dtype=torch.float32, compile=compiled)
        renderer.flux(particles, sun[0], obs[0])
        seconds = best_time(lambda r=renderer: r.flux(particles, sun[0], obs[0]), args.repeats)
        pf["compiled" if compiled else "eager"] = {
            "seconds_per_update": seconds,
            "facet_particles_per_second": len(shape.compiled()) * len(particles) / seconds,
        }
    print(
        json.dumps(
            {
                "benchmark": "render",
                "unit": "facet-epochs per second",
                "results": results,
                "particle_filter_10k_particles_one_epoch_float32": pf,
                "shadow_table_vs_exact": shadow_table_accuracy(),
                "batch_vs_single_calls": batch_equals_single_calls(),
                "machine": machine_info(),
            },
            indent=2,
        )
    )


if __name__ == "__main__":
    main()
