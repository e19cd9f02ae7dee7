"""Monte Carlo study of stereo relative-state and inertia estimation (Feng et al.).

Runs ``--runs`` seeded truth/filter pairs of the scenario (batched) and writes
``OUT/summary.json`` (RTMSE over the scenario's final window of attitude, rate, position,
velocity and inertia parameters; NEES mean against its 95 % band; run count) and
``OUT/history.csv`` (per frame: run-RMS errors, run-RMS filter sigmas, mean NEES).
The scenario file format is described in ``docs/stereo.md``.
"""

from __future__ import annotations

import argparse

from lightcurve.commands._args import add_scenario_arguments

NAME = "stereo"
HELP = "Monte Carlo of the stereo relative-state and inertia EKF (Feng et al.)"
ORDER = 62


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``lightcurve stereo``."""
    add_scenario_arguments(parser, "scenario TOML file", runs=200, seed=0)


def run(args: argparse.Namespace) -> int:
    """Execute ``lightcurve stereo``."""
    import pandas as pd
    from tqdm import tqdm

    from lightcurve.io.atomic import atomic_write_json, atomic_write_table
    from lightcurve.scenarios.stereo import load_stereo_scenario
    from lightcurve.studies.stereo import run_monte_carlo

    scenario = load_stereo_scenario(args.scenario)
    args.out.mkdir(parents=True, exist_ok=True)
    steps = round(scenario.duration / scenario.step)
    with tqdm(total=steps, desc="stereo", unit="frame", disable=None) as bar:
        result = run_monte_carlo(
            scenario, args.runs, seed=args.seed, progress=lambda _: bar.update(1)
        )
    summary = {
        "scenario": str(args.scenario),
        **result.summary(),
        "window_s": scenario.window,
        "duration_s": scenario.duration,
        "feature_count": scenario.feature_count,
        "target_size_m": scenario.target_size,
        "angle_noise_rad": scenario.angle_noise,
    }
    atomic_write_json(args.out / "summary.json", summary)
    atomic_write_table(pd.DataFrame(result.history), args.out / "history.csv")
    rt = result.rtmse
    print(
        f"{args.runs} runs: RTMSE attitude {rt['attitude_deg']:.3g} deg, rate "
        f"{rt['omega_rad_s']:.3g} rad/s, position {rt['position_m']:.3g} m, velocity "
        f"{rt['velocity_m_s']:.3g} m/s, k {rt['inertia_k']:.3g}; NEES {result.nees_mean:.2f} "
        f"(95 % band {result.nees_band[0]:.2f}-{result.nees_band[1]:.2f})"
    )
    return 0
