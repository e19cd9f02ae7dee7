"""Multi-mode relative navigation with IMU input and robust position fixes.

Simulates the scenario's closed-loop approach, runs the Kalman filter of the selected mode
(cooperative: relative GNSS; non-cooperative: lidar with the binocular backup;
semi-cooperative: lidar and relative GNSS fused) with Huber M-estimation or the plain update,
optionally replacing a fraction of the optical fixes by gross errors, and writes
``OUT/summary.json`` (``position_rms_m``, ``velocity_rms_m_s``, ``ambiguity_fix_rate``,
``wrong_fix_rate``, ``time_to_first_fix_s``, ``mode_time_fractions``, ``outliers_injected``,
``outliers_downweighted`` and more) and ``OUT/errors.csv`` (per IMU epoch: truth,
estimation error, filter sigma and the navigation sub-mode). Format: ``docs/relnav.md``.
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np

from lightcurve.commands._args import add_scenario_arguments

NAME = "relnav"
HELP = "multi-mode relative navigation: IMU + lidar/stereo/relative GNSS, Huber M-estimation"
ORDER = 63


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``lightcurve relnav``."""
    add_scenario_arguments(parser, "scenario TOML file")
    parser.add_argument(
        "--outlier-rate", type=float, default=0.0, help="fraction of optical fixes replaced by "
        "gross errors"
    )  # fmt: skip
    parser.add_argument("--outlier-size", type=float, default=2.0, help="gross error magnitude, m")
    parser.add_argument(
        "--robust", choices=("huber", "none"), default="huber",
        help="measurement update: Huber M-estimation or plain Kalman",
    )  # fmt: skip
    parser.add_argument(
        "--mode",
        help="override the scenario's mode (a name from its [modes]: the shipped scenarios "
        "define cooperative, non-cooperative and semi-cooperative) (default: the scenario's)",
    )
    parser.add_argument(
        "--seed", type=int, help="override the scenario's random seed (default: the scenario's)"
    )


def run(args: argparse.Namespace) -> int:
    """Execute ``lightcurve relnav``."""
    import pandas as pd

    from lightcurve.io.atomic import atomic_write_json, atomic_write_table
    from lightcurve.scenarios.relnav import _AXES, load_relnav_scenario
    from lightcurve.studies.relnav import simulate_approach

    if not 0.0 <= args.outlier_rate <= 1.0:
        raise ValueError(f"--outlier-rate must be between 0 and 1, got {args.outlier_rate}")
    if not args.outlier_size >= 0:
        raise ValueError(f"--outlier-size must be a non-negative length, got {args.outlier_size}")
    scenario, seed = load_relnav_scenario(args.scenario)
    if args.mode is not None:
        if args.mode not in scenario.modes:
            raise ValueError(
                f"--mode {args.mode!r} is not a mode of {args.scenario}: {sorted(scenario.modes)}"
            )
        scenario = dataclasses.replace(scenario, mode=args.mode)
    seed = seed if args.seed is None else args.seed
    result = simulate_approach(
        scenario, args.outlier_rate, args.outlier_size, robust=args.robust, seed=seed
    )
    summary = {
        "scenario": str(args.scenario),
        "mode": scenario.mode,
        "sensors": [s.name for s in scenario.active_sensors],
        "robust": args.robust,
        "outlier_rate": args.outlier_rate,
        "outlier_size_m": args.outlier_size,
        "seed": seed,
        "settle_s": scenario.settle,
        **result.summary(),
    }
    args.out.mkdir(parents=True, exist_ok=True)
    atomic_write_json(args.out / "summary.json", summary)
    table = {"time_s": result.times}
    for j, axis in enumerate(_AXES):
        table[f"true_{axis}"] = result.truth[:, j]
        table[f"error_{axis}"] = result.errors[:, j]
        table[f"sigma_{axis}"] = result.sigmas[:, j]
    table["mode"] = result.modes
    atomic_write_table(pd.DataFrame(table), args.out / "errors.csv")
    gnss = ""
    if result.gnss_epochs:
        first = result.time_to_first_fix
        gnss = (
            f"; ambiguities fixed in {100 * result.ambiguity_fix_rate:.1f} % of "
            f"{result.gnss_epochs} epochs, first fix after "
            + ("never" if first is None else f"{first:.0f} s")
        )
    print(
        f"{scenario.mode} ({', '.join(summary['sensors'])}), {args.robust}: position RMS "
        f"{result.position_rms:.4f} m, velocity RMS {result.velocity_rms:.5f} m/s; "
        f"outliers {result.outliers_injected} injected, {result.outliers_downweighted} "
        f"down-weighted; NEES {result.nees_mean:.2f} (6 expected){gnss}"
    )
    return 0 if np.isfinite(result.position_rms) else 1
