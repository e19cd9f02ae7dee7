"""Speed of the BRDF cosine forms: evaluations per second per model, numpy vs torch, f32 vs f64.

Each model's cosine form (the renderer's hot path) is evaluated on 10⁴ epochs × 10³ facets =
10⁷ facet-epochs of random cosines (seeded), in four ways per dtype:

* ``numpy``: one call on the whole (10⁴, 10³) arrays;
* ``torch``: one eager call on the whole tensors;
* ``torch_chunked``: eager calls on chunks of 256 epochs (cache-sized), written into one output;
* ``torch_compiled`` (with ``--compile``): ``torch.compile`` of the same cosine form, chunked.

Reported figures: millions of evaluations per second of wall-clock time and per second of
process CPU time (best of ``--repeats`` runs each; on a shared, loaded machine the CPU-time
figure with ``--threads 1`` is the stable one). Also reported: the machine (processor, cores,
load average at start), library versions and torch's thread count. Prints JSON.

Usage (from the repository root): ``python -m benchmarks.brdf [--epochs 10000] [--facets 1000]
[--repeats 3] [--compile] [--threads N]``
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from functools import partial

import numpy as np
import torch

import brdf
from benchmarks._machine import machine_info

MODELS = {
    "lambert": {"rd": 0.5},
    "phong": {"rd": 0.4, "rs": 0.5, "n": 50.0},
    "cook-torrance": {"rd": 0.2, "rs": 0.6, "m": 0.3, "f0": 0.9},
    "ashikhmin-shirley": {"rd": 0.3, "rs": 0.2, "nu": 200.0, "nv": 200.0},
    "ashikhmin-shirley-anisotropic": {"rd": 0.3, "rs": 0.2, "nu": 20.0, "nv": 2000.0},
    "lommel-seeliger": {"w": 0.8, "c": 0.1, "a": 0.5, "d": 0.1, "k": -0.5},
}
CHUNK = 256


def random_cosines(epochs: int, facets: int, seed: int) -> dict[str, np.ndarray]:
    """Cosines of random unit vectors: normals (F), Sun and observer directions (E)."""
    rng = np.random.default_rng(seed)

    def unit(count: int) -> np.ndarray:
        x = rng.normal(size=(count, 3))
        return x / np.linalg.norm(x, axis=-1, keepdims=True)

    normals, suns, observers, tangents = unit(facets), unit(epochs), unit(epochs), unit(facets)
    tangents -= np.sum(tangents * normals, -1, keepdims=True) * normals
    tangents /= np.linalg.norm(tangents, axis=-1, keepdims=True)
    bitangents = np.cross(normals, tangents)
    half = suns + observers
    half /= np.linalg.norm(half, axis=-1, keepdims=True)
    return {
        "nl": suns @ normals.T,
        "nv": observers @ normals.T,
        "lv": np.sum(suns * observers, -1, keepdims=True),
        "hu": half @ tangents.T,
        "hv": half @ bitangents.T,
    }


def best_time(function, repeats: int) -> tuple[float, float]:
    """Smallest wall-clock and smallest process CPU time (s) of ``repeats`` calls."""
    function()  # warm-up (allocation, compilation)
    wall, cpu = [], []
    for _ in range(repeats):
        start, start_cpu = time.perf_counter(), time.process_time()
        function()
        wall.append(time.perf_counter() - start)
        cpu.append(time.process_time() - start_cpu)
    return min(wall), min(cpu)


def chunked(evaluate, inputs: dict, out: torch.Tensor):
    def run():
        for start in range(0, out.shape[0], CHUNK):
            part = {k: v[start : start + CHUNK] for k, v in inputs.items()}
            out[start : start + CHUNK] = evaluate(**part)

    return run


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--epochs", type=int, default=10_000)
    parser.add_argument("--facets", type=int, default=1_000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--compile", action="store_true", help="also time torch.compile")
    parser.add_argument("--threads", type=int, default=0, help="torch threads (0: default)")
    args = parser.parse_args(argv)
    if args.threads:
        torch.set_num_threads(args.threads)
    count = args.epochs * args.facets
    cosines64 = random_cosines(args.epochs, args.facets, args.seed)
    report: dict = {
        "machine": {**machine_info(), "load_average_at_start": os.getloadavg()},
        "evaluations": count,
        "shape": [args.epochs, args.facets],
        "seed": args.seed,
        "repeats": args.repeats,
        "unit": "million evaluations per second (wall clock; *_per_cpu_second: CPU time)",
        "models": {},
    }
    for label, params in MODELS.items():
        name = label.removesuffix("-anisotropic")
        model = brdf.get(name, **params)
        keys = ("nl", "nv", "lv", "hu", "hv") if model.anisotropic else ("nl", "nv", "lv")
        rates = {}
        for dtype_name, np_dtype, torch_dtype in (
            ("float32", np.float32, torch.float32),
            ("float64", np.float64, torch.float64),
        ):
            arrays = {k: cosines64[k].astype(np_dtype) for k in keys}
            tensors = {k: torch.from_numpy(v) for k, v in arrays.items()}
            out = torch.empty((args.epochs, args.facets), dtype=torch_dtype)
            timings = {
                "numpy": best_time(partial(model.from_cosines, **arrays), args.repeats),
                "torch": best_time(partial(model.from_cosines, **tensors), args.repeats),
                "torch_chunked": best_time(chunked(model.from_cosines, tensors, out), args.repeats),
            }
            if args.compile:
                # Every BRDF shares the code of `BRDF.from_cosines`: start each model and dtype
                # from a clean cache so that dynamo's recompile limit is never reached.
                torch.compiler.reset()
                compiled = torch.compile(model.from_cosines, dynamic=False)
                start = time.perf_counter()
                compiled(**{k: v[:CHUNK] for k, v in tensors.items()})
                rates[f"compile_seconds_{dtype_name}"] = time.perf_counter() - start
                timings["torch_compiled"] = best_time(chunked(compiled, tensors, out), args.repeats)
                reference = model.from_cosines(**tensors)
                rates[f"compiled_max_relative_difference_{dtype_name}"] = float(
                    ((out - reference).abs() / reference.abs().clamp(min=1e-30)).max()
                )
            for way, (wall, cpu) in timings.items():
                rates[f"{way}_{dtype_name}"] = count / wall / 1e6
                rates[f"{way}_{dtype_name}_per_cpu_second"] = count / cpu / 1e6
        report["models"][label] = rates
    json.dump(report, sys.stdout, indent=2)
    print()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
