"""Relative GNSS of a 1 km LEO formation: ambiguity fixing and accuracy over seeded runs.

Each run (:func:`filters.gnss.formation.simulate_formation`) draws the start time within a
day, the target's orbit node and phase and the formation phase; both receivers see the GPS
constellation of ``--almanac`` (default: the real NAVCEN almanac
``data/gnss/gps_week147_yuma.alm``; ``gps_nominal_24slot.alm`` is the sparser nominal
constellation) above a 10° mask with 0.5 m code and 3 mm phase noise at 1 Hz. Prints one
JSON document with the seed and run count, the ratio threshold and success-rate bound, and
the measured figures:

* ``fixed_within_60s_rate``: runs whose first fixed epoch is at most 60 s after the first;
* ``wrong_fix_rate``: runs with any fixed epoch carrying wrong integers;
* time to first fix (mean, median, 99th percentile, max);
* per-axis RMS (target Hill frame: radial, along-track, cross-track) of the epoch-wise fixed,
  raw code (snapshot) and carrier-smoothed code solutions (all epochs, and ``t ≥ 60 s``),
  of the time-differenced carrier-phase velocity, and of the navigation filter
  (``filters.navigation.relnav``) over ``t ≥ 60 s`` fed with the navigator's fixes (fixed, else
  carrier-smoothed), with raw code fixes and with carrier-smoothed code fixes, and their
  mean position NEES (3 for a consistent filter);
* for the two code solutions: the predicted RMS from their covariances, the RMS of the errors
  normalised by the predicted standard deviations (1 when the covariance is right), the mean
  error (bias) and, for the raw one, the dilution of precision per axis (predicted RMS over
  the single-difference code noise ``√2 σ``);
* satellites in common view, wall time and the machine.

    python -m benchmarks.gnss [--runs 200] [--seed 0] [--duration 120] [--ratio 3]
                              [--min-success-rate 0.999] [--window 100] [--almanac FILE]
                              [--out gnss.json]
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
from filters.gnss.constellation import parse_yuma
from filters.gnss.formation import FormationScenario, simulate_formation
from lightcurve.io.atomic import atomic_write_json

ALMANAC = Path(__file__).resolve().parents[1] / "data" / "gnss" / "gps_week147_yuma.alm"
AXES = ("radial", "along_track", "cross_track")


def axis_rms(errors: list[np.ndarray]) -> dict[str, float]:
    """Pooled per-axis RMS over runs and epochs (NaN epochs skipped)."""
    e = np.concatenate(errors)
    rms = np.sqrt(np.nanmean(e**2, axis=0))
    return dict(zip(AXES, rms.tolist(), strict=True))


def finite_or_none(value: float) -> float | None:
    """JSON-safe number: ``None`` for infinities."""
    return float(value) if np.isfinite(value) else None


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawTextHelpFormatter
    )
    parser.add_argument("--runs", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0, help="seed of the first run")
    parser.add_argument("--duration", type=float, default=120.0, help="seconds per run")
    parser.add_argument("--baseline", type=float, default=1000.0, help="baseline length (m)")
    parser.add_argument("--ratio", type=float, default=3.0, help="ratio-test threshold")
    parser.add_argument("--min-success-rate", type=float, default=0.999)
    parser.add_argument("--window", type=float, default=100.0, help="carrier smoothing (s)")
    parser.add_argument("--settle", type=float, default=60.0, help="filter RMS from (s)")
    parser.add_argument("--almanac", type=Path, default=ALMANAC, help="YUMA almanac file")
    parser.add_argument("--out", type=Path, help="also write the JSON here")
    args = parser.parse_args()
    start = time.perf_counter()
    base = FormationScenario(parse_yuma(args.almanac.read_text(), source=str(args.almanac)))
    scenario = dataclasses.replace(
        base,
        duration=args.duration,
        baseline=args.baseline,
        solver=dataclasses.replace(
            base.solver,
            ratio_threshold=args.ratio,
            min_success_rate=args.min_success_rate,
            smoothing_window=args.window,
        ),
    )
    runs = []
    for r in range(args.runs):
        run = simulate_formation(scenario, args.seed + r)
        runs.append(run)
        print(
            f"run {r + 1}/{args.runs} seed {args.seed + r}: first fix "
            f"{run.time_to_first_fix} s, wrong {run.wrong_fix} ({run.elapsed_s:.1f} s)",
            file=sys.stderr,
        )
    ttff = np.array([np.inf if r.time_to_first_fix is None else r.time_to_first_fix for r in runs])
    late = [r.times >= args.settle for r in runs]
    satellites = np.concatenate([r.satellites for r in runs])
    pairs = list(zip(runs, late, strict=True))
    sd_code_sigma = np.sqrt(2.0) * scenario.receiver.code_sigma

    def code_scores(errors: str, std: str, dop: bool) -> dict[str, object]:
        e = [getattr(r, errors) for r in runs]
        s = [getattr(r, std) for r in runs]
        predicted = axis_rms(s)
        scores = {
            "rms_m": axis_rms(e),
            "rms_m_after_settle": axis_rms([x[w] for x, w in zip(e, late, strict=True)]),
            "predicted_rms_m": predicted,
            "normalised_error_rms": axis_rms([x / y for x, y in zip(e, s, strict=True)]),
            "mean_error_m": dict(
                zip(AXES, np.nanmean(np.concatenate(e), axis=0).tolist(), strict=True)
            ),
        }
        if dop:
            scores["dilution_of_precision"] = {k: v / sd_code_sigma for k, v in predicted.items()}
        return scores

    report = {
        "benchmark": "gnss",
        "almanac": str(args.almanac.name),
        "seed": args.seed,
        "runs": args.runs,
        "duration_s": args.duration,
        "baseline_m": args.baseline,
        "code_sigma_m": scenario.receiver.code_sigma,
        "phase_sigma_m": scenario.receiver.phase_sigma,
        "elevation_mask_deg": float(np.degrees(scenario.receiver.elevation_mask)),
        "ratio_threshold": args.ratio,
        "min_success_rate": args.min_success_rate,
        "fixed_within_60s_rate": float(np.mean(ttff <= 60.0)),
        "never_fixed": int(np.sum(~np.isfinite(ttff))),
        "wrong_fix_rate": float(np.mean([r.wrong_fix for r in runs])),
        "wrong_fix_runs": [args.seed + i for i, r in enumerate(runs) if r.wrong_fix],
        "time_to_first_fix_s": {  # null: beyond the run (some run never fixed)
            "mean_of_fixed_runs": float(np.mean(ttff[np.isfinite(ttff)])),
            "median": finite_or_none(np.median(ttff)),
            "p99": finite_or_none(np.percentile(ttff, 99)),
            "max": finite_or_none(np.max(ttff)),
        },
        "fixed_epoch_fraction": float(np.mean(np.concatenate([r.status for r in runs]) == "fixed")),
        "smoothing_window_s": args.window,
        "snapshot_rms_m": {
            "fixed": axis_rms([r.fixed_errors for r in runs]),
            "code_only": axis_rms([r.code_errors for r in runs]),
            "carrier_smoothed": axis_rms([r.smoothed_errors for r in runs]),
        },
        "code_solutions": {
            "raw_snapshot": code_scores("code_errors", "code_std", dop=True),
            "carrier_smoothed": code_scores("smoothed_errors", "smoothed_std", dop=False),
        },
        "velocity_rms_m_s": axis_rms([r.velocity_errors for r in runs]),
        "filtered_rms_m": {
            "best": axis_rms([r.filtered_errors[w] for r, w in zip(runs, late, strict=True)]),
            "code_only": axis_rms(
                [r.filtered_code_errors[w] for r, w in zip(runs, late, strict=True)]
            ),
            "carrier_smoothed": axis_rms(
                [r.filtered_smoothed_errors[w] for r, w in zip(runs, late, strict=True)]
            ),
        },
        "filtered_position_nees_mean": {  # 3 for a consistent filter
            name: float(np.nanmean(np.concatenate([r.filtered_nees[key][w] for r, w in pairs])))
            for name, key in (
                ("best", "best"),
                ("code_only", "code"),
                ("carrier_smoothed", "smoothed"),
            )
        },
        "satellites_in_common_view": {
            "min": int(satellites.min()),
            "mean": float(satellites.mean()),
            "max": int(satellites.max()),
            "fraction_below_5": float(np.mean(satellites < 5)),
        },
        "elapsed_s": time.perf_counter() - start,
        "machine": machine_info(),
    }
    print(json.dumps(report, indent=2))
    if args.out is not None:
        atomic_write_json(args.out, report)


if __name__ == "__main__":
    main()
