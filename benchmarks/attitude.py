"""Batched RK4 throughput of the attitude core, numpy vs torch, 10³–10⁵ particles.

Prints JSON: RK4 steps per second (a step advances every particle once) and particle-steps
per second for each backend and batch size, the scaling exponent of time with particle count
(1 = linear), and the machine.

    python benchmarks/attitude.py [--repeats 5]
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
import torch

from benchmarks._machine import machine_info
from filters.attitude import random_quaternion, rk4_step, torque_free_derivative

J_NUTATION = np.array([[0.85, 0.13, 0.17], [0.13, 1.37, -0.11], [0.17, -0.11, 1.0]])


def time_steps(x, derivative, repeats: int) -> float:
    """Best wall time (s) of one RK4 step over ``repeats`` tries."""
    best = np.inf
    x = rk4_step(derivative, x, 0.1)  # warm-up
    for _ in range(repeats):
        start = time.perf_counter()
        rk4_step(derivative, x, 0.1)
        best = min(best, time.perf_counter() - start)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument(
        "--threads", type=int, help="torch intra-op threads (default: torch's own choice)"
    )
    args = parser.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    rng = np.random.default_rng(0)
    results = []
    for backend in ("numpy", "torch"):
        for n in (1_000, 10_000, 100_000):
            x = np.concatenate([random_quaternion(n, rng), rng.normal(0, 0.05, (n, 3))], axis=1)
            inertia = J_NUTATION
            if backend == "torch":
                x, inertia = torch.tensor(x), torch.tensor(J_NUTATION)
            seconds = time_steps(x, torque_free_derivative(inertia), args.repeats)
            results.append(
                {
                    "backend": backend,
                    "dtype": "float64",
                    "particles": n,
                    "seconds_per_step": seconds,
                    "steps_per_second": 1.0 / seconds,
                    "particle_steps_per_second": n / seconds,
                }
            )
    scaling = {}
    for backend in ("numpy", "torch"):
        rows = [r for r in results if r["backend"] == backend]
        slope = np.polyfit(
            np.log([r["particles"] for r in rows]), np.log([r["seconds_per_step"] for r in rows]), 1
        )[0]
        scaling[backend] = {"time_exponent_vs_particles": float(slope)}
    print(
        json.dumps(
            {
                "benchmark": "attitude_rk4",
                "results": results,
                "scaling": scaling,
                "machine": machine_info(),
            },
            indent=2,
        )
    )


if __name__ == "__main__":
    main()
