"""Feng et al.'s Monte Carlo tables 4–7 for the stereo relative-state and inertia EKF.

Runs the nominal scenario (table 4) and the three sweeps of the paper — feature count
3/4/6/9/12 (table 5), target size 0.2–3 m (table 6), angular noise 1–8e-5 rad at 0.6 m
(table 7) — with ``--runs`` Monte Carlo runs each (batched), and prints one JSON document:
RTMSE over the final window with Monte Carlo standard errors, NEES against its 95 % band,
whether each sweep follows the paper's trend within Monte Carlo error, wall times and the
machine.

    python -m benchmarks.stereo [--runs 200] [--seed 0] [--out stereo.json]
    python -m benchmarks.stereo --runs 20 --duration 600 --window 300   # quick look
    python -m benchmarks.stereo --sweeps none --figure docs/figures/stereo_nominal.png
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
import time
from pathlib import Path

from benchmarks._machine import machine_info
from lightcurve.io.atomic import atomic_path, atomic_write_json
from lightcurve.scenarios.stereo import load_stereo_scenario
from lightcurve.studies.stereo import QUANTITIES, StereoScenario, run_monte_carlo

NOMINAL = Path(__file__).resolve().parents[1] / "data" / "scenarios" / "stereo_nominal.toml"

# (table, swept field, values, fixed fields) as in Feng et al., sec. 3.
SWEEPS = (
    ("table5_features", "feature_count", (3, 4, 6, 9, 12),
     {"target_size": 1.0, "angle_noise": 1e-5}),
    ("table6_size", "target_size", (0.2, 0.6, 1.0, 2.0, 3.0),
     {"feature_count": 4, "angle_noise": 1e-5}),
    ("table7_noise", "angle_noise", (1e-5, 2e-5, 4e-5, 6e-5, 8e-5),
     {"feature_count": 4, "target_size": 0.6}),
)  # fmt: skip
# The paper's trend of the errors as the swept value grows.
TREND = {"table5_features": "decreasing", "table6_size": "decreasing", "table7_noise": "increasing"}
ACCEPTANCE = {
    "attitude_deg": 0.1,
    "omega_rad_s": 6e-5,
    "position_m": 0.010,
    "velocity_m_s": 10e-6,
    "inertia_k": 0.02,
}


def follows_trend(rows: list[dict], quantity: str, direction: str, z: float = 2.0) -> bool:
    """Whether consecutive RTMSEs move in ``direction`` or stay within ``z`` standard errors."""
    sign = 1.0 if direction == "decreasing" else -1.0
    for a, b in itertools.pairwise(rows):
        step = sign * (b["rtmse"][quantity] - a["rtmse"][quantity])
        tolerance = (
            z
            * (a["rtmse_standard_error"][quantity] ** 2 + b["rtmse_standard_error"][quantity] ** 2)
            ** 0.5
        )
        if step > tolerance:
            return False
    return True


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawTextHelpFormatter
    )
    parser.add_argument("--scenario", type=Path, default=NOMINAL)
    parser.add_argument("--runs", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--duration", type=float, help="override the simulated time (s)")
    parser.add_argument("--window", type=float, help="override the RTMSE window (s)")
    parser.add_argument("--out", type=Path, help="also write the JSON here")
    parser.add_argument(
        "--sweeps", choices=("all", "none"), default="all", help="run tables 5-7 or only table 4"
    )
    parser.add_argument("--figure", type=Path, help="plot the nominal errors vs time here (PNG)")
    args = parser.parse_args()

    base = load_stereo_scenario(args.scenario)
    if args.duration is not None:
        base = base.with_(duration=args.duration, window=args.window or args.duration / 2)
    elif args.window is not None:
        base = base.with_(window=args.window)
    start = time.perf_counter()
    cache: dict[tuple, dict] = {}
    histories: dict[tuple, dict] = {}

    def study(scenario: StereoScenario) -> dict:
        key = (scenario.feature_count, scenario.target_size, scenario.angle_noise)
        if key not in cache:
            result = run_monte_carlo(scenario, args.runs, seed=args.seed)
            histories[key] = result.history
            cache[key] = {
                "feature_count": key[0],
                "target_size_m": key[1],
                "angle_noise_rad": key[2],
                **result.summary(),
            }
            print(
                f"N={key[0]} size={key[1]} m noise={key[2]:.0e} rad: "
                f"{result.elapsed_s:.0f} s, RTMSE {result.rtmse}",
                file=sys.stderr,
            )
        return cache[key]

    nominal = study(base)
    tables = {"table4_nominal": nominal}
    trends = {}
    for table, field, values, fixed in SWEEPS if args.sweeps == "all" else ():
        rows = [study(base.with_(**fixed, **{field: v})) for v in values]
        tables[table] = rows
        trends[table] = {q: follows_trend(rows, q, TREND[table]) for q in QUANTITIES} | {
            "expected": TREND[table]
        }
    acceptance = {q: nominal["rtmse"][q] <= limit for q, limit in ACCEPTANCE.items()}
    acceptance["nees_inside_band"] = nominal["nees"]["inside_band"]
    report = {
        "benchmark": "stereo_monte_carlo",
        "scenario": str(args.scenario),
        "runs": args.runs,
        "seed": args.seed,
        "duration_s": base.duration,
        "window_s": base.window,
        "acceptance_limits": ACCEPTANCE,
        "acceptance": acceptance,
        **tables,
        "trends_within_2_standard_errors": trends,
        "elapsed_s": time.perf_counter() - start,
        "machine": machine_info(),
    }
    print(json.dumps(report, indent=2))
    if args.out is not None:
        atomic_write_json(args.out, report)
    if args.figure is not None:
        key = (base.feature_count, base.target_size, base.angle_noise)
        plot_history(histories[key], base.window, args.runs, args.figure)


def plot_history(history: dict, window: float, runs: int, path: Path) -> None:
    """Run-RMS error and run-RMS filter 1σ of each quantity vs time (the paper's figs. 5-9)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    labels = {
        "attitude_deg": "attitude (deg)",
        "omega_rad_s": "rate (rad/s)",
        "inertia_k": "inertia k",
        "position_m": "position (m)",
        "velocity_m_s": "velocity (m/s)",
    }
    t = history["time_s"] / 60
    fig, axes = plt.subplots(len(labels), 1, figsize=(7, 10), sharex=True)
    for ax, (name, label) in zip(axes, labels.items(), strict=True):
        ax.semilogy(t, history[name], label="RMS error")
        ax.semilogy(t, history[f"sigma_{name}"], "--", label="filter 1σ")
        ax.axvspan((t[-1] * 60 - window) / 60, t[-1], color="0.9")
        ax.set_ylabel(label)
    axes[0].legend(loc="upper right")
    axes[0].set_title(f"Stereo EKF, nominal scenario, {runs} runs (shaded: RTMSE window)")
    axes[-1].set_xlabel("time (min)")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path, suffix=".png") as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)


if __name__ == "__main__":
    main()
