"""Monocular attitude, rate and inertia estimation of a tumbling target (Deng et al. 2024).

``lightcurve monocular SCENARIO.toml --out DIR [--runs N] [--seed S] [--measurements CSV]``
simulates the scenario's truth, its relative-attitude measurements (noisy quaternions, or
pixel tracks of a library shape turned into quaternions by the essential-matrix pipeline),
runs the 11-state EKF (or the tanh-form variant), tests observability (Lie-derivative rank
at the true state, Fisher information along the estimated trajectory) and writes
``DIR/estimates.parquet``, ``DIR/summary.json`` and figures like the paper's figs. 3–6.
With ``--measurements`` the EKF runs on external quaternions instead (columns ``t`` in s and
``q1 q2 q3 q4``, attitude relative to the first frame). ``converged`` is decided without the
truth: full observability rank, Cramér–Rao bounds of the inertia parameters below the
tolerance, and inertia estimates that have settled. The file format is in
``docs/monocular.md``.
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

from lightcurve.commands._args import add_scenario_arguments

NAME = "monocular"
HELP = "attitude, rate and inertia of a tumbling target from images (Deng et al. 2024)"
ORDER = 60


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``lightcurve monocular``."""
    add_scenario_arguments(
        parser,
        "scenario TOML file (docs/monocular.md)",
        runs=1,
        seed=0,
        seed_help="seed of every random stream",
    )
    parser.add_argument(
        "--measurements",
        type=Path,
        help="CSV with columns t (s), q1 q2 q3 q4 (attitude relative to the first frame) "
        "(default: simulate the scenario)",
    )
    parser.add_argument("--no-plots", action="store_true", help="skip the figures")


def run(args: argparse.Namespace) -> int:
    """Execute ``lightcurve monocular``."""
    from lightcurve.io.atomic import atomic_write_json, atomic_write_table, json_ready
    from lightcurve.scenarios import ScenarioError
    from lightcurve.scenarios.monocular import load_monocular_scenario, read_measurements
    from lightcurve.studies.monocular import (
        estimates_table,
        print_summary,
        run_study,
        summarize,
        write_figures,
    )

    scenario = load_monocular_scenario(args.scenario)
    external = None
    if args.measurements is not None:
        if args.runs != 1:
            raise ScenarioError("--runs applies to simulated measurements only")
        external = read_measurements(args.measurements)
        scenario = dataclasses.replace(scenario, truth=None)
    study = run_study(scenario, args.runs, args.seed, external)
    summary = summarize(study, args.seed)
    args.out.mkdir(parents=True, exist_ok=True)
    atomic_write_table(estimates_table(study), args.out / "estimates.parquet")
    if not args.no_plots:
        summary["figures"] = [p.name for p in write_figures(study, args.out)]
    atomic_write_json(args.out / "summary.json", json_ready(summary))
    print_summary(summary)
    return 0
