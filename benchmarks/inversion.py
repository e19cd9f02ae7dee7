"""Monte Carlo studies of the photometric inversion (UKF, MMAE bank, particle filter) and the
particle-filter speed study. Prints JSON.

    python -m benchmarks.inversion ukf  [--runs 50] [--seed 0]        # UKF, known shape
    python -m benchmarks.inversion mmae [--runs 30] [--seed 0]        # MMAE, truth in the bank
    python -m benchmarks.inversion mmae-outside [--runs 30] [--seed 0] [--extra itokawa,bennu]
    python -m benchmarks.inversion pf   [--runs 20] [--seed 0] [--shape itokawa]  # PF, no prior
    python -m benchmarks.inversion pf-box [--runs 10] [--seed 0]      # PF, box symmetry modes
    python -m benchmarks.inversion pf-shapes [--runs 20] [--bank itokawa,box_wing,box]  # and shape
    python -m benchmarks.inversion speed                               # PF speed
    python -m benchmarks.inversion main-job [--files box_wing_tumbling,...]  # README job
    python -m benchmarks.inversion propagation                         # RK4 kernels

Scenarios (:mod:`benchmarks.inversion_study`): a geostationary object seen from Mount
Lemmon on 2024-06-21 from 04:00 UTC, 1 Hz, Gaussian noise 0.05 mag, 20 min; run ``i``
draws its truth and prior from ``numpy.random.default_rng([seed, i])``. ``--out FILE``
also writes the JSON (atomically).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time

import numpy as np
import torch

from benchmarks._machine import machine_info
from benchmarks.inversion_study import (
    Scenario,
    draw_truth,
    mmae_study,
    pf_study,
    simulate_run,
    ukf_study,
)
from filters.attitude import quaternion_multiply, rotation_vector_to_quaternion
from filters.particle import AttitudeParticleFilter
from lightcurve.io.atomic import atomic_write_json, json_ready
from lightcurve.photometry.measurement import PhotometricModel
from shapes import get_library

#: Bank of the MMAE study: six library satellites; truths outside it are the two asteroids
#: (scaled models would still be far off) and each satellite left out in turn is tested by
#: ``mmae-outside`` against the other five plus the asteroids.
BANK = ("cube", "box", "plate", "cylinder", "rocket_body", "box_wing")


def speed(particles: list[int], updates: int, seed: int, components: int = 12) -> dict:
    """Time of one PF update (likelihood, tempering, resampling and roughening included)
    against one render of all particles, for several particle counts; the particles form
    ``components`` mixture components, as :func:`lightcurve.inversion.invert` seeds them
    around its 12 search candidates by default."""
    scenario = Scenario(duration_s=120.0)
    shape = get_library().load("box_wing")
    rng = np.random.default_rng(seed)
    truth = draw_truth(scenario, rng)
    observations = simulate_run(scenario, shape, truth, rng)
    model = PhotometricModel(observations, shape)
    rows = []
    for n in particles:
        spread = rng.standard_normal((n, 6)) * np.radians([2, 2, 2, 0.05, 0.05, 0.05])
        q = quaternion_multiply(rotation_vector_to_quaternion(spread[:, :3]), truth.q0)
        pf = AttitudeParticleFilter(
            q,
            truth.omega0 + spread[:, 3:],
            [shape.inertia],
            components=np.arange(n) % components,
            seed=seed,
            dtype=torch.float64,
        )
        render_times, update_times, stages, resampled = [], [], 0, 0
        for j in range(updates):
            if j:
                pf.predict(model.times[j] - model.times[j - 1])

            def measure(qs: torch.Tensor, s: torch.Tensor, j: int = j) -> torch.Tensor:
                return model.magnitude_by_shape(qs, j, s)

            start = time.perf_counter()
            measure(pf.q, pf.shape)
            render_times.append(time.perf_counter() - start)
            start = time.perf_counter()
            info = pf.update(model.magnitudes[j], model.errors[j] ** 2, measure)
            update_times.append(time.perf_counter() - start)
            stages += info.stages
            resampled += info.resampled
        render = float(np.median(render_times))
        update = float(np.median(update_times))
        rows.append(
            {
                "particles": n,
                "render_s": render,
                "update_s": update,
                "update_over_render": update / render,
                "mean_update_s": float(np.mean(update_times)),
                "mean_stages": stages / updates,
                "resampling_events": resampled,
            }
        )
    n = np.log([r["particles"] for r in rows])
    slope = float(np.polyfit(n, np.log([r["update_s"] for r in rows]), 1)[0])
    return {
        "study": "pf-speed",
        "shape": "box_wing",
        "updates_per_size": updates,
        "components": components,
        "seed": seed,
        "rows": rows,
        "log_log_slope_update_vs_particles": slope,
        "max_update_over_render": max(r["update_over_render"] for r in rows),
        "note": "median over the updates; the update includes its own render",
    }


def main_job(files: list[str]) -> dict:
    """The README main job file by file in this process (one torch thread): CPU and wall
    time, shape, probability and the errors against the files' truth columns."""
    from benchmarks.inversion_speed import summary
    from lightcurve import io
    from lightcurve.inversion import invert, shape_symmetry

    library = get_library()
    shapes = {
        n: library.load(n) for n in ("box_wing", "rocket_body", "box", "cylinder", "plate", "cube")
    }
    rows = []
    for name in files:
        observations = io.read(f"data/observations/{name}.csv")
        wall, cpu = time.perf_counter(), time.process_time()
        result = invert(observations, shapes, method="mmae")
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        truth = observations.meta["shape"]
        group = shape_symmetry(shapes[truth])
        rows.append(
            {"file": name, "cpu_s": cpu, "wall_s": wall, **summary(result, observations, group)}
        )
    return {"study": "main-job", "rows": rows}


def propagation(states: int = 3072, epochs: int = 90, repeats: int = 3) -> dict:
    """A search window's trajectory (``states`` × ``epochs`` 3.3 s apart) by
    :func:`filters.attitude.torque_free_trajectory` against the baseline, a chain of the
    core's RK4 steps (:func:`filters.attitude.rk4_step`), in the same run."""
    from filters.attitude import (
        random_quaternion,
        rk4_step,
        torque_free_derivative,
        torque_free_trajectory,
    )

    rng = np.random.default_rng(0)
    q = random_quaternion(states, rng)
    omega = rng.normal(0.0, 0.03, (states, 3))
    inertia = np.array([[0.85, 0.13, 0.17], [0.13, 1.37, -0.11], [0.17, -0.11, 1.0]])
    offsets = 3.3 * np.arange(1, epochs + 1)

    def baseline() -> np.ndarray:
        x, f, out = np.concatenate([q, omega], axis=1), torque_free_derivative(inertia), []
        for _ in offsets:
            x = rk4_step(f, x, 3.3)
            out.append(x[:, :4])
        return np.stack(out, axis=1)

    def fast() -> np.ndarray:
        return torque_free_trajectory(q, omega, offsets, inertia, 4.0)[0]

    times = {}
    for label, run in (("baseline_rk4_step_chain", baseline), ("torque_free_trajectory", fast)):
        best = math.inf
        for _ in range(repeats):
            start = time.process_time()
            run()
            best = min(best, time.process_time() - start)
        times[label] = best
    difference = float(np.max(np.abs(baseline() - fast())))
    return {
        "study": "propagation",
        "states": states,
        "epochs": epochs,
        "cpu_s": times,
        "speed_up": times["baseline_rk4_step_chain"] / times["torque_free_trajectory"],
        "max_abs_difference": difference,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "study",
        choices=[
            "ukf",
            "mmae",
            "mmae-outside",
            "pf",
            "pf-box",
            "pf-shapes",
            "speed",
            "main-job",
            "propagation",
        ],
    )
    parser.add_argument("--runs", type=int, help="Monte Carlo runs (default per study)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--first-run",
        type=int,
        default=0,
        help="index of the first run (a study split in parts gives the same records)",
    )
    parser.add_argument("--shape", default=None, help="truth shape (ukf, pf)")
    parser.add_argument("--components", type=int, default=12, help="PF mixture components (speed)")
    parser.add_argument("--particles", type=int, default=2000, help="PF particles")
    parser.add_argument("--duration", type=float, default=1200.0, help="arc length (s)")
    parser.add_argument(
        "--extra",
        default="itokawa,bennu",
        help="mmae-outside: shapes added to the five other satellites (comma-separated)",
    )
    parser.add_argument(
        "--files",
        default="box_wing_tumbling,rocket_body_tumbling,box_tumbling_ccd",
        help="main-job: files of data/observations (stems, comma-separated)",
    )
    parser.add_argument(
        "--bank",
        default="itokawa,box_wing,box",
        help="pf-shapes: candidate shapes, each the truth in turn (comma-separated)",
    )
    parser.add_argument(
        "--truths", help="pf-shapes: truth shapes taken in turn (default: the bank)"
    )
    parser.add_argument("--out", help="also write the JSON here")
    parser.add_argument("-v", "--verbose", action="store_true", help="print every run")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    progress = (lambda m: print(m, file=sys.stderr, flush=True)) if args.verbose else None
    start = time.perf_counter()
    scenario = Scenario(duration_s=args.duration)
    if args.study == "ukf":
        result = ukf_study(
            args.runs or 50,
            args.seed,
            args.shape or "box_wing",
            scenario,
            progress=progress,
            first=args.first_run,
        )
    elif args.study == "mmae":
        result = mmae_study(
            args.runs or 30,
            args.seed,
            BANK,
            scenario=scenario,
            progress=progress,
            first=args.first_run,
        )
    elif args.study == "mmae-outside":
        # Each bank member in turn is the truth, the bank being the other five plus the
        # library's asteroids (≥ 6 candidates, the truth never among them).
        runs = args.runs or 30
        records = []
        for i in range(args.first_run, args.first_run + runs):
            truth = BANK[i % len(BANK)]
            bank = [b for b in BANK if b != truth] + args.extra.split(",")
            one = mmae_study(1, args.seed * 1000 + i, bank, [truth], scenario, progress=progress)
            records.extend(one["records"])
        result = {
            "study": "mmae-outside",
            "runs": runs,
            "first_run": args.first_run,
            "seed": args.seed,
            "scenario": scenario.__dict__,
            "extra_shapes": args.extra.split(","),
            "none_fits_rate": float(np.mean([r["none_fits"] for r in records])),
            "records": records,
        }
    elif args.study in ("pf", "pf-box"):
        shape = args.shape or ("box" if args.study == "pf-box" else "itokawa")
        pf_scenario = Scenario(duration_s=args.duration, rate_deg_s=(0.5, 5.0))
        result = pf_study(
            args.runs or (20 if args.study == "pf" else 10),
            args.seed,
            shape,
            pf_scenario,
            particles=args.particles,
            progress=progress,
            first=args.first_run,
        )
    elif args.study == "pf-shapes":
        result = pf_study(
            args.runs or 20,
            args.seed,
            scenario=Scenario(duration_s=args.duration, rate_deg_s=(0.5, 5.0)),
            particles=args.particles,
            progress=progress,
            first=args.first_run,
            bank=args.bank.split(","),
            truths=args.truths.split(",") if args.truths else None,
        )
    elif args.study == "main-job":
        result = main_job(args.files.split(","))
    elif args.study == "propagation":
        result = propagation()
    else:
        result = speed([1_000, 3_000, 10_000, 30_000, 100_000], 20, args.seed, args.components)
    result["runtime_s"] = time.perf_counter() - start
    result["machine"] = machine_info()
    result["command"] = "python -m benchmarks.inversion " + " ".join(argv or sys.argv[1:])
    result = json_ready(result)
    print(json.dumps(result, indent=1))
    if args.out:
        atomic_write_json(args.out, result)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
