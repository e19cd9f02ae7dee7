"""Fisher-information observation planning for small-body landing navigation (Li et al. 2024).

Runs ``--runs`` seeded Monte Carlo descents of the scenario and navigates each with three
image strategies on the same random draws: an image at every step, Li et al.'s criterion
``min tr(F⁻¹)`` and the improved posterior-covariance criterion at the same image budget.
Writes ``OUT/summary.json``: per strategy the images used, the position, velocity and
attitude error standard deviations after the settle time (Monte Carlo mean and spread) and
the observation times; plus their ratios and the paper's table-3 numbers. The scenario file
format is described in ``docs/planner.md``.
"""

from __future__ import annotations

import argparse

from lightcurve.commands._args import add_scenario_arguments

NAME = "plan"
HELP = "plan landmark images of a small-body landing, Fisher information (Li et al. 2024)"
ORDER = 64


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``lightcurve plan``."""
    add_scenario_arguments(parser, "scenario TOML (docs/planner.md)", runs=20, seed=1)


def run(args: argparse.Namespace) -> int:
    """Execute ``lightcurve plan``."""
    from lightcurve.io.atomic import atomic_write_json
    from lightcurve.scenarios.landing import load_scenario
    from lightcurve.studies.landing import run_study, summarize

    scenario = load_scenario(args.scenario)
    summary = summarize(run_study(scenario, args.runs, args.seed))
    summary["scenario"] = str(args.scenario)
    atomic_write_json(args.out / "summary.json", summary)
    comp = summary["comparison"]
    print(
        f"{args.runs} runs: Fisher-trace criterion used "
        f"{comp['fisher_trace_images_fraction']:.1%} of the images, "
        f"position std x{comp['fisher_trace_vs_every_step_position_std']:.2f} of every step; "
        f"improved/Fisher-trace position std {comp['improved_vs_fisher_trace_position_std']:.3f}; "
        f"wrote {args.out / 'summary.json'}"
    )
    return 0
