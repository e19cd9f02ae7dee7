"""Speed of the inversion against a baseline revision of the code, side by side. Prints JSON.

    python -m benchmarks.inversion_speed [--baseline REV] [--repeats 2] [--seed 0]
        [--jobs box_wing_tumbling,rocket_body_tumbling,box_tumbling_ccd,ukf-search]

Jobs: a file of ``data/observations`` (the README main job on that file: MMAE over the six
satellites, no prior, ``invert(observations, shapes, method="mmae")``), and ``ukf-search``:
a UKF inversion of a 300-epoch box-wing light curve (the inversion studies' scenario,
:mod:`benchmarks.inversion_study`, 5 min at 1 Hz, truth from
``numpy.random.default_rng([seed, 0])``) with the known shape and no prior, so that the
global search finds the initial state.

Every job runs in a fresh process on one thread (``OMP_NUM_THREADS=1``), once with the code
of this checkout and once with the code of ``--baseline`` (exported by ``git archive`` into
a cache folder, kept for later runs), alternately, ``--repeats`` times; each process first
runs a small inversion so that compiled kernels are loaded (or built) before the timing.
The figures are CPU seconds of the job (``time.process_time``), best of the repeats, and
their ratio; the summaries (shape, probability, ``none_fits``, errors against the truth)
of both codes are printed for comparison.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
#: The README main job's candidate shapes.
BANK = ("box_wing", "rocket_body", "box", "cylinder", "plate", "cube")
DEFAULT_JOBS = "box_wing_tumbling,rocket_body_tumbling,box_tumbling_ccd,ukf-search"
_RUN_SCRIPT = (
    "import runpy, sys; sys.argv = sys.argv[1:]; runpy.run_path(sys.argv[0], run_name='__main__')"
)


def _warm_up() -> None:
    """A small inversion: compiles or loads every kernel the timed job calls."""
    import numpy as np

    from benchmarks.inversion_study import Scenario, draw_truth, simulate_run
    from lightcurve.inversion import invert
    from shapes import get_library

    library = get_library()
    scenario = Scenario(duration_s=60.0)
    rng = np.random.default_rng([1, 0])
    observations = simulate_run(scenario, library.load("box_wing"), draw_truth(scenario, rng), rng)
    light = {"global_candidates": 500, "refine_keep": (8, 2), "hypotheses": 2}
    invert(observations, {n: library.load(n) for n in BANK[:2]}, method="mmae", **light)


def _run_job(job: str, seed: int) -> dict[str, Any]:
    """One job in this process: CPU and wall time and the result's summary."""
    import numpy as np
    import torch

    from benchmarks.inversion_study import Scenario, draw_truth, simulate_run
    from lightcurve import io
    from lightcurve.inversion import invert, shape_symmetry
    from shapes import get_library

    torch.set_num_threads(1)
    library = get_library()
    _warm_up()
    if job == "ukf-search":
        scenario = Scenario(duration_s=300.0)
        rng = np.random.default_rng([seed, 0])
        shape = library.load("box_wing")
        observations = simulate_run(scenario, shape, draw_truth(scenario, rng), rng)
        shapes, method, truth = {"box_wing": shape}, "ukf", "box_wing"
    else:
        observations = io.read(ROOT / "data" / "observations" / f"{job}.csv")
        shapes, method = {n: library.load(n) for n in BANK}, "mmae"
        truth = observations.meta["shape"]
    wall, cpu = time.perf_counter(), time.process_time()
    result = invert(observations, shapes, method=method)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    group = shape_symmetry(shapes[truth])
    return {
        "job": job,
        "epochs": len(observations),
        "cpu_s": cpu,
        "wall_s": wall,
        **summary(result, observations, group),
    }


def summary(result: Any, observations: Any, group: Any) -> dict[str, Any]:
    """Shape, its probability, ``none_fits``, residual rms and the errors against the
    truth columns (:func:`benchmarks.inversion_study.final_errors`) of an inversion."""
    from benchmarks.inversion_study import final_errors

    return {
        "shape": result.shape,
        "probability": result.shape_probabilities[result.shape],
        "none_fits": result.none_fits,
        "residual_rms_mag": result.residual_rms_mag,
        **final_errors(result, observations, group),
    }


def baseline_checkout(revision: str) -> Path:
    """The code of ``revision`` in a cache folder (exported once by ``git archive``)."""
    commit = subprocess.run(
        ["git", "rev-parse", "--verify", f"{revision}^{{commit}}"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    cache = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache"))
    folder = cache / "space-lightcurves" / "baseline" / commit
    if not (folder / "pyproject.toml").exists():
        folder.parent.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(dir=folder.parent))
        archive = subprocess.run(
            ["git", "archive", commit], cwd=ROOT, capture_output=True, check=True
        ).stdout
        subprocess.run(["tar", "-x", "-C", str(staging)], input=archive, check=True)
        staging.replace(folder)
    return folder


def _child(code: Path, job: str, seed: int) -> dict[str, Any]:
    """Run one job in a fresh process with the library of ``code`` first on the path."""
    env = dict(os.environ, OMP_NUM_THREADS="1", PYTHONPATH=str(code))
    out = subprocess.run(
        # Run by path without putting benchmarks/ first on sys.path (its modules shapes.py,
        # brdf.py … would hide the packages).
        [sys.executable, "-c", _RUN_SCRIPT, *_script_arguments(job, seed)],
        cwd=code,
        env=env,
        capture_output=True,
        text=True,
    )
    if out.returncode != 0:
        raise RuntimeError(f"{job} with the code of {code} failed:\n{out.stderr[-2000:]}")
    return json.loads(out.stdout)


def _script_arguments(job: str, seed: int) -> list[str]:
    """This script's path and the arguments of a child running ``job``."""
    return [str(Path(__file__).resolve()), "--child", job, "--seed", str(seed)]


def compare(jobs: list[str], baseline: str, repeats: int, seed: int) -> dict[str, Any]:
    """Every job with this checkout's code and the baseline's, alternately."""
    from benchmarks._machine import machine_info

    codes = {"current": ROOT, "baseline": baseline_checkout(baseline)}
    runs: dict[str, dict[str, list[dict]]] = {j: {c: [] for c in codes} for j in jobs}
    loads = [os.getloadavg()[0]]
    for _ in range(repeats):
        for job in jobs:
            for label, code in codes.items():
                runs[job][label].append(_child(code, job, seed))
                loads.append(os.getloadavg()[0])
    rows = []
    for job in jobs:
        best = {c: min(runs[job][c], key=lambda r: r["cpu_s"]) for c in codes}
        rows.append(
            {
                "job": job,
                "cpu_s": {c: best[c]["cpu_s"] for c in codes},
                "cpu_s_all": {c: [r["cpu_s"] for r in runs[job][c]] for c in codes},
                "ratio": best["current"]["cpu_s"] / best["baseline"]["cpu_s"],
                "current": best["current"],
                "baseline": best["baseline"],
                "same_summary": _same_summary(best["current"], best["baseline"]),
            }
        )
    return {
        "study": "inversion-speed",
        "baseline": baseline,
        "repeats": repeats,
        "seed": seed,
        "load_average_1min": {"min": min(loads), "max": max(loads)},
        "rows": rows,
        "machine": machine_info(),
    }


def _same_summary(a: dict[str, Any], b: dict[str, Any]) -> bool:
    """Same shape, none_fits, and probability and errors to 10⁻⁹."""
    if a["shape"] != b["shape"] or a["none_fits"] != b["none_fits"]:
        return False
    keys = ("probability", "residual_rms_mag", "attitude_error_deg", "rate_error_deg_s")
    return all(math.isclose(a[k], b[k], rel_tol=1e-9, abs_tol=1e-12) for k in keys)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--baseline", default="HEAD", help="git revision of the baseline code")
    parser.add_argument("--jobs", default=DEFAULT_JOBS, help="comma-separated jobs")
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--seed", type=int, default=0, help="seed of the ukf-search scenario")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    parser.add_argument("--out", help="also write the JSON here")
    args = parser.parse_args(argv)
    if args.child:
        print(json.dumps(_run_job(args.child, args.seed)))
        return 0
    # Imported after the child's branch: a child runs this file on the baseline's code,
    # which may predate the module.
    from benchmarks._report import emit_report

    result = compare(args.jobs.split(","), args.baseline, args.repeats, args.seed)
    emit_report(result, args.out, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
