"""Multi-mode relative navigation: accuracy by mode and robustness to gross optical errors.

Runs the approach scenario of Shi et al. (6000 s, IMU 0.16 s, fixes 1 s) and prints one JSON
document:

* ``modes``: position/velocity RMS and NEES of each mode of ``relnav_approach.toml``
  (relative GNSS as position fixes), Huber update;
* ``outliers``: for ``--seeds`` seeds, clean data vs ``--rate`` of the optical fixes replaced
  by ``--size`` m gross errors, Huber vs plain Kalman, with the degradation ratios (Huber
  ≤ 1.2× its clean RMS, plain > 2× is the requirement);
* ``rate_sweep``: the same for outlier rates 1–20 % (first seed);
* ``rgnss_modes``: the three modes of ``relnav_cooperative.toml`` (relative GNSS from raw
  code and carrier phase) for ``--mode-seeds`` paired seeds: the summaries (ambiguity fix
  rate, wrong fixes, time to first fix, sub-mode fractions) and whether semi-cooperative
  fusion is no worse than the better single sensor in every pair;
* wall times and the machine.

    python -m benchmarks.relnav [--seeds 10] [--rate 0.05] [--size 2] [--mode-seeds 5]
                                [--sections modes,outliers,sweep,rgnss] [--out relnav.json]
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
from benchmarks._report import add_sections_argument
from lightcurve.io.atomic import atomic_write_json
from lightcurve.scenarios.relnav import load_relnav_scenario
from lightcurve.studies.relnav import ApproachScenario, simulate_approach

SCENARIOS = Path(__file__).resolve().parents[1] / "data" / "scenarios"
SCENARIO = SCENARIOS / "relnav_approach.toml"
RGNSS_SCENARIO = SCENARIOS / "relnav_cooperative.toml"
GNSS_MODES = ("cooperative", "non-cooperative", "semi-cooperative")


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
    parser.add_argument("--rgnss-scenario", type=Path, default=RGNSS_SCENARIO)
    parser.add_argument("--mode-seeds", type=int, default=5, help="paired seeds per RGNSS mode")
    add_sections_argument(parser, ("modes", "outliers", "sweep", "rgnss"))
    parser.add_argument("--out", type=Path, help="also write the JSON here")
    args = parser.parse_args()
    sections = args.sections
    start = time.perf_counter()
    base, _ = load_relnav_scenario(args.scenario)
    rgnss_base, _ = load_relnav_scenario(args.rgnss_scenario)
    if args.duration is not None:
        base, rgnss_base = (
            dataclasses.replace(
                b,
                duration=args.duration,
                approach_duration=min(b.approach_duration, args.duration / 2),
            )
            for b in (base, rgnss_base)
        )
    report = {"benchmark": "relnav", "scenario": str(args.scenario), "duration_s": base.duration}
    if "modes" in sections:
        report["modes"] = [
            run(dataclasses.replace(base, mode=m), 0.0, args.size, "huber", 0) for m in base.modes
        ]
    if "outliers" in sections:
        report["outliers"] = outlier_study(base, args)
    if "sweep" in sections:
        report["rate_sweep"] = [
            run(base, rate, args.size, robust, 0)
            for rate in (0.01, 0.05, 0.10, 0.20)
            for robust in ("huber", "none")
        ]
    if "rgnss" in sections:
        report["rgnss_modes"] = rgnss_modes(rgnss_base, args.mode_seeds)
    report["elapsed_s"] = time.perf_counter() - start
    report["machine"] = machine_info()
    print(json.dumps(report, indent=2))
    if args.out is not None:
        atomic_write_json(args.out, report)


def rgnss_modes(base: ApproachScenario, seeds: int) -> dict:
    """The three modes with raw-measurement relative GNSS on paired seeds."""
    rows = {
        (mode, seed): run(dataclasses.replace(base, mode=mode), 0.0, 2.0, "huber", seed)
        for seed in range(seeds)
        for mode in GNSS_MODES
    }
    pairs = []
    for seed in range(seeds):
        rms = {mode: rows[(mode, seed)]["position_rms_m"] for mode in GNSS_MODES}
        better = min(rms["cooperative"], rms["non-cooperative"])
        pairs.append({"seed": seed, **rms, "semi_over_better": rms["semi-cooperative"] / better})
    return {
        "scenario": str(RGNSS_SCENARIO.name),
        "seeds": seeds,
        "runs": list(rows.values()),
        "pairs": pairs,
        "semi_no_worse_than_better_every_seed": all(p["semi_over_better"] <= 1.0 for p in pairs),
    }


def outlier_study(base: ApproachScenario, args: argparse.Namespace) -> dict:
    """Clean vs gross optical errors, Huber vs plain Kalman, over ``args.seeds`` seeds."""

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
    return {
        "rate": args.rate,
        "size_m": args.size,
        "seeds": args.seeds,
        "per_seed": study,
        "huber_rms_ratio": ratio_stats(huber),
        "plain_rms_ratio": ratio_stats(plain),
        "huber_within_1_2x_every_seed": bool(max(huber) <= 1.2),
        "plain_above_2x_every_seed": bool(min(plain) > 2.0),
    }


if __name__ == "__main__":
    main()
