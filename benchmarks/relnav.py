"""Seed 003's relative navigation: accuracy by mode and robustness to gross optical errors.

Runs the approach scenario (6000 s, IMU 0.16 s, fixes 1 s) and prints one JSON document:

* ``modes``: position/velocity RMS and NEES of each mode (cooperative: relative GNSS,
  non-cooperative: lidar, its stereo backup, semi-cooperative: both), Huber update;
* ``outliers``: for ``--seeds`` seeds, clean data vs ``--rate`` of the optical fixes replaced
  by ``--size`` m gross errors, Huber vs plain Kalman, with the degradation ratios (the
  issue's acceptance: Huber ≤ 1.2× its clean RMS, plain > 2×);
* ``rate_sweep``: the same for outlier rates 1–20 % (first seed);
* wall times and the machine.

    python -m benchmarks.relnav [--seeds 10] [--rate 0.05] [--size 2] [--out relnav.json]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

import numpy as np

from benchmarks._machine import machine_info
from filters.relnav import ApproachScenario, simulate_approach
from lightcurve.atomic import atomic_write_json
from lightcurve.scenarios.relnav import load_relnav_scenario

SCENARIO = Path(__file__).resolve().parents[1] / "data" / "scenarios" / "relnav_approach.toml"


def run(scenario: ApproachScenario, rate: float, size: float, robust: str, seed: int) -> dict:
    """One simulation's summary, with its settings."""
    result = simulate_approach(scenario, rate, size, robust=robust, seed=seed)
    print(
        f"{scenario.mode} {robust} rate={rate} seed={seed}: {result.position_rms:.4f} m "
        f"({result.elapsed_s:.1f} s)",
        file=sys.stderr,
    )
    return {"mode": scenario.mode, "robust": robust, "outlier_rate": rate, "seed": seed,
            **result.summary()}  # fmt: skip


def ratio_stats(values: list[float]) -> dict[str, float]:
    """Mean, minimum and maximum of a list of ratios."""
    return {
        "mean": float(np.mean(values)),
        "min": float(np.min(values)),
        "max": float(np.max(values)),
    }


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawTextHelpFormatter
    )
    parser.add_argument("--scenario", type=Path, default=SCENARIO)
    parser.add_argument("--seeds", type=int, default=10, help="seeds of the outlier study")
    parser.add_argument("--rate", type=float, default=0.05, help="outlier rate")
    parser.add_argument("--size", type=float, default=2.0, help="outlier size (m)")
    parser.add_argument("--duration", type=float, help="override the simulated time (s)")
    parser.add_argument("--out", type=Path, help="also write the JSON here")
    args = parser.parse_args()
    start = time.perf_counter()
    base, _ = load_relnav_scenario(args.scenario)
    if args.duration is not None:
        base = dataclasses.replace(
            base,
            duration=args.duration,
            approach_duration=min(base.approach_duration, args.duration / 2),
        )

    modes = [run(dataclasses.replace(base, mode=m), 0.0, args.size, "huber", 0) for m in base.modes]

    study = []
    for seed in range(args.seeds):
        rows = {
            (rate, robust): run(base, rate, args.size, robust, seed)
            for rate in (0.0, args.rate)
            for robust in ("huber", "none")
        }
        study.append(
            {
                "seed": seed,
                "runs": list(rows.values()),
                "huber_ratio": rows[(args.rate, "huber")]["position_rms_m"]
                / rows[(0.0, "huber")]["position_rms_m"],
                "plain_ratio": rows[(args.rate, "none")]["position_rms_m"]
                / rows[(0.0, "none")]["position_rms_m"],
            }
        )
    huber = [s["huber_ratio"] for s in study]
    plain = [s["plain_ratio"] for s in study]
    sweep = [
        run(base, rate, args.size, robust, 0)
        for rate in (0.01, 0.05, 0.10, 0.20)
        for robust in ("huber", "none")
    ]
    report = {
        "benchmark": "relnav",
        "scenario": str(args.scenario),
        "duration_s": base.duration,
        "modes": modes,
        "outliers": {
            "rate": args.rate,
            "size_m": args.size,
            "seeds": args.seeds,
            "per_seed": study,
            "huber_rms_ratio": ratio_stats(huber),
            "plain_rms_ratio": ratio_stats(plain),
            "huber_within_1_2x_every_seed": bool(max(huber) <= 1.2),
            "plain_above_2x_every_seed": bool(min(plain) > 2.0),
        },
        "rate_sweep": sweep,
        "elapsed_s": time.perf_counter() - start,
        "machine": machine_info(),
    }
    print(json.dumps(report, indent=2))
    if args.out is not None:
        atomic_write_json(args.out, report)


if __name__ == "__main__":
    main()
