"""Seed 001 study: planned landmark imaging for an Eros landing, 100 seeded Monte Carlo runs.

Prints JSON with the paper's table 3 rebuilt for the three strategies (images used; position,
velocity and attitude error standard deviations after the settle time, Monte Carlo mean and
spread), their ratios (issue 9 acceptance 1 and 2), the predicted window covariance that the
improved criterion minimises, timings and machine information; saves the figure of the
observation times along the trajectory (like the paper's fig. 10) to
``docs/figures/planner_observation_times.png``.

Run: ``python benchmarks/planner.py [--runs 100] [--seed 2024]``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import torch

from filters.lander import STRATEGIES
from lightcurve.commands.plan import Study, load_scenario, run_study, summarize

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "data" / "scenarios" / "eros_landing.toml"
FIGURE = ROOT / "docs" / "figures" / "planner_observation_times.png"


def table3(study: Study) -> dict:
    """Per strategy: image count and per-axis error stds (mean ± spread over runs)."""
    out = {}
    for name in STRATEGIES:
        stats = study.statistics[name]
        row = {"images_used": [float(stats["images"].mean()), float(stats["images"].std(ddof=1))]}
        for key, unit in (("position", "m"), ("velocity", "m_s"), ("attitude", "deg")):
            axes = stats[f"{key}_std_axes"]
            row[f"{key}_std_axes_{unit}"] = {
                "mean": axes.mean(axis=0).tolist(),
                "spread": axes.std(axis=0, ddof=1).tolist(),
            }
        out[name] = row
    return out


def predicted_window(study: Study) -> dict:
    """Filter-predicted position variance summed over the window (what the rollout minimises)."""
    settle = study.scenario.settle_step
    sums = {
        name: np.trace(run.covariances[settle:, :, :3, :3], axis1=-2, axis2=-1).sum(axis=0)
        for name, run in study.runs.items()
    }
    ratio = sums["improved"] / sums["seed"]
    return {
        "mean_m2_s": {name: float(v.mean()) for name, v in sums.items()},
        "improved_over_seed_mean": float(ratio.mean()),
        "improved_lower_fraction_of_runs": float(np.mean(ratio < 1)),
    }


def paired(study: Study) -> dict:
    """Paired comparison improved vs seed (same draws): mean ratio and its standard error."""
    out = {}
    for key in ("position_std", "position_rms", "attitude_std"):
        ratio = study.statistics["improved"][key] / study.statistics["seed"][key]
        out[key] = {
            "mean_ratio": float(ratio.mean()),
            "standard_error": float(ratio.std(ddof=1) / np.sqrt(len(ratio))),
            "improved_lower_fraction": float(np.mean(ratio < 1)),
        }
    return out


def figure(study: Study, path: Path) -> None:
    """Trajectory of run 0 with the image times of each strategy (cf. seed fig. 10)."""
    scenario = study.scenario
    site = scenario.model.landmarks.site
    truth = site.from_body(study.draws.truth[:, 0, :3])
    t = np.arange(len(truth)) * scenario.model.dt
    fig = plt.figure(figsize=(11, 4.8))
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    ax.plot(*truth.T, color="0.6", lw=1, label="trajectory (run 0)")
    styles = {"seed": ("o", "tab:blue", 40), "improved": ("^", "tab:red", 10)}
    for name, (marker, color, size) in styles.items():
        taken = study.runs[name].taken[:, 0]
        face = "none" if name == "seed" else color
        ax.scatter(
            *truth[taken].T,
            marker=marker,
            s=size,
            edgecolors=color,
            facecolors=face,
            label=f"{name} images",
        )
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.set_zlabel("up (m)")
    ax.legend(loc="upper left", fontsize=8)
    ax.set_title("Observation points along the descent")
    ax2 = fig.add_subplot(1, 2, 2)
    for row, name in enumerate(STRATEGIES):
        taken = study.runs[name].taken[:, 0]
        ax2.eventplot(t[taken], lineoffsets=row, linelengths=0.7, colors="k")
    ax2.axvline(scenario.settle_step * scenario.model.dt, color="tab:green", ls="--", lw=1)
    ax2.set_yticks(
        range(len(STRATEGIES)), [f"{n} ({study.runs[n].taken[:, 0].sum()})" for n in STRATEGIES]
    )
    ax2.set_xlabel("time (s)")
    ax2.set_title("Image times, run 0 (dashed: settle time)")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=100)
    parser.add_argument("--seed", type=int, default=2024)
    args = parser.parse_args()
    scenario = load_scenario(SCENARIO)
    study = run_study(scenario, args.runs, args.seed)
    summary = summarize(study)
    figure(study, FIGURE)
    result = {
        "study": "seed 001 planned landmark imaging, Eros landing",
        "scenario": str(SCENARIO.relative_to(ROOT)),
        "runs": args.runs,
        "seed": args.seed,
        "table3": table3(study),
        "summary": {
            name: {k: v for k, v in entry.items() if k != "observation_times_s"}
            for name, entry in summary["strategies"].items()
        },
        "comparison": summary["comparison"],
        "paired_improved_vs_seed": paired(study),
        "predicted_window_position_variance": predicted_window(study),
        "observation_times_run0_s": {
            name: summary["strategies"][name]["observation_times_s"][0] for name in STRATEGIES
        },
        "paper": summary["paper"],
        "acceptance": {
            "1_seed_images_le_60pct": summary["comparison"]["seed_images_fraction"] <= 0.6,
            "1_seed_position_std_le_1p3x": summary["comparison"]["seed_vs_every_step_position_std"]
            <= 1.3,
            "2_improved_lower_position_std": summary["comparison"]["improved_vs_seed_position_std"]
            < 1.0,
        },
        "seconds": {"total": study.seconds, "per_run": study.seconds / args.runs},
        "figure": str(FIGURE.relative_to(ROOT)),
        "machine": {
            "processor": platform.processor(),
            "cpu_count": os.cpu_count(),
            "numpy": np.__version__,
            "torch": torch.__version__,
        },
    }
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
