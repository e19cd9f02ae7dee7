"""``lightcurve simulate`` end to end against the straightforward numpy script, same job.

Job: a 20 480-facet non-convex blob (an icosphere of 5 subdivisions whose radius carries a
seeded smooth perturbation: twelve cosine lobes about random axes, deep enough to make
concavities), Ashikhmin–Shirley material, added to a temporary shape library (the library
API behind ``lightcurve shapes add``, with a coarse visibility table: ``--shadows none`` does
not use it); 40 000 epochs of a synthetic geometry file at 1 s cadence (Sun at 1 AU, observer
at GEO range circling the object); a tumbling attitude; ``--shadows none``. Both programs
run as subprocesses, timed from process start to file written: ``lightcurve simulate`` and
``benchmarks/simulate_numpy.py`` (one Python loop over epochs vectorised over facets, scipy
DOP853 truth at rtol = atol = 1e-12). Their magnitudes are compared; each program's peak
memory is its ``ru_maxrss``. ``--memory-epochs N`` also runs ``lightcurve simulate`` alone on
``N`` epochs (e.g. 10⁶) for its peak memory. Prints JSON.

    python -m benchmarks.simulate [--epochs 40000] [--repeats 2] [--memory-epochs 1000000]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from benchmarks._machine import machine_info
from shapes import FacetModel, Material, ShapeLibrary, primitives, write_obj

MATERIAL = {"rd": 0.3, "rs": 0.4, "nu": 100.0}
Q0 = "0.2,-0.4,0.1,0.888819"
OMEGA0 = "1.5,-0.8,2.2"  # deg/s
INERTIA = "1.0,1.3,1.7"
SEED = 20261201


def blob_mesh(path: Path, seed: int = SEED) -> int:
    """Write the blob as OBJ; returns its facet count."""
    sphere = primitives.icosphere(1.0, subdivisions=5)
    v = sphere.vertices / np.linalg.norm(sphere.vertices, axis=1, keepdims=True)
    rng = np.random.default_rng(seed)
    radius = np.ones(len(v))
    for _ in range(12):  # smooth lobes: products of low-order polynomials of the direction
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        order = rng.integers(2, 5)
        radius += rng.uniform(0.05, 0.15) * np.cos(order * np.arccos(np.clip(v @ axis, -1, 1)))
    blob = FacetModel(v * radius[:, None], sphere.faces, name="blob")
    write_obj(blob, path)
    return len(sphere.faces)


def geometry_file(path: Path, epochs: int) -> None:
    """A geometry file (``mjd``, object → Sun and object → observer, km), 1 s cadence."""
    t = np.arange(epochs, dtype=float)
    turn = 2 * np.pi * t / 86400.0 / 365.25
    sun = 1.495978707e8 * np.stack([np.cos(turn), np.sin(turn), 0.2 * np.ones_like(t)], axis=1)
    phase = 2 * np.pi * t / 86164.0
    obs = 3.6e4 * np.stack([np.cos(phase), 0.3 + np.sin(phase), 0.1 * np.ones_like(t)], axis=1)
    table = pd.DataFrame(
        {
            "mjd": 60400.0 + t / 86400.0,
            **{f"sun_{k}": sun[:, i] for i, k in enumerate("xyz")},
            **{f"obs_{k}": obs[:, i] for i, k in enumerate("xyz")},
        }
    )
    table.to_csv(path, index=False, float_format="%.12g")


_MEASURE = (
    "import resource, subprocess, sys; subprocess.run(sys.argv[1:], check=True, "
    "stdout=subprocess.DEVNULL); print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)"
)


def run(command: list[str]) -> tuple[float, float]:
    """Wall time (s) of a subprocess, process start to exit, and its peak RSS (MiB).

    The command runs under a small Python parent that reports its only child's
    ``ru_maxrss`` (so every measured program has its own figure).
    """
    start = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-c", _MEASURE, *command], check=True, capture_output=True, text=True
    )
    seconds = time.perf_counter() - start
    return seconds, int(done.stdout.split()[-1]) / 1024


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--epochs", type=int, default=40_000)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--memory-epochs", type=int, default=0)
    args = parser.parse_args()
    root = Path(__file__).resolve().parent
    with tempfile.TemporaryDirectory() as folder:
        work = Path(folder)
        mesh = work / "blob.obj"
        facets = blob_mesh(mesh)
        library = work / "library"
        # The library API rather than `lightcurve shapes add`: the same entry, with a coarse
        # visibility table (it is not used with --shadows none and full-size costs minutes).
        ShapeLibrary(library).add(
            "blob",
            mesh,
            materials=Material("ashikhmin-shirley", {**MATERIAL, "nv": MATERIAL["nu"]}),
            resolution=2,
            samples=1,
        )
        geometry = work / "geometry.csv"
        geometry_file(geometry, args.epochs)
        common = ["--q0", Q0, "--omega0", OMEGA0, "--inertia", INERTIA]
        toolkit_cmd = [
            sys.executable, "-m", "lightcurve.cli", "simulate", str(geometry), "--shape", "blob",
            "--library", str(library), *common, "--shadows", "none",
            "--out", str(work / "toolkit.csv"),
        ]  # fmt: skip
        numpy_cmd = [
            sys.executable, str(root / "simulate_numpy.py"), str(geometry), str(mesh), *common,
            *(f"--{k}={v}" for k, v in MATERIAL.items()), "--out", str(work / "numpy.csv"),
        ]  # fmt: skip
        toolkit_runs = [run(toolkit_cmd) for _ in range(args.repeats)]
        toolkit_s, toolkit_rss = min(toolkit_runs)
        numpy_s, numpy_rss = run(numpy_cmd)  # the baseline is slow: one run
        ours = pd.read_csv(work / "toolkit.csv", comment="#")
        theirs = pd.read_csv(work / "numpy.csv")
        same_epochs = np.array_equal(ours["mjd"].to_numpy(), theirs["mjd"].to_numpy())
        difference = np.abs(ours["mag"].to_numpy() - theirs["mag"].to_numpy())
        result = {
            "benchmark": "simulate",
            "job": {
                "facets": facets,
                "epochs": args.epochs,
                "brdf": "ashikhmin-shirley",
                "shadows": "none",
                "shape_seed": SEED,
            },
            "toolkit_seconds": toolkit_s,
            "numpy_script_seconds": numpy_s,
            "speedup": numpy_s / toolkit_s,
            "same_epochs": same_epochs,
            "max_abs_magnitude_difference": float(np.max(difference)) if same_epochs else None,
            "toolkit_runs_seconds": [seconds for seconds, _ in toolkit_runs],
            "toolkit_peak_rss_mib": toolkit_rss,
            "numpy_script_peak_rss_mib": numpy_rss,
        }
        if args.memory_epochs:
            big = work / "geometry_big.csv"
            geometry_file(big, args.memory_epochs)
            command = [*toolkit_cmd[:4], str(big), *toolkit_cmd[5:]]
            command[-1] = str(work / "big.parquet")
            seconds, rss = run(command)
            result["memory_job"] = {
                "epochs": args.memory_epochs,
                "seconds": seconds,
                "peak_rss_mib": rss,
            }
    result["load_average"] = os.getloadavg()
    result["machine"] = machine_info()
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
