"""Starlink v1.5: predicted vs measured brightness of the 1173 Pomenis observations.

The two-surface model (chassis to nadir, solar array turned to the Sun) with the materials
fitted to the laboratory BRDF tables (``brdf/data/materials.toml``), the Sun from astropy, and the
satellite position from the observed altitude, azimuth and height. Nothing is fitted to the
brightness observations. Prints JSON with the residual statistics (measured − predicted,
mag) for the two-lobe materials (the presets) and, in the same run, for the earlier one-lobe
(Cook–Torrance) fits of the same lab tables and for the two-lobe materials with the light of
a Lambertian Earth added (its share of the flux reported), and writes
``docs/figures/starlink_pomenis.png`` (two-lobe materials).

    python -m benchmarks.starlink
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from benchmarks._machine import machine_info
from lightcurve.datasets.starlink import MATERIALS, ONE_LOBE_MATERIALS, predict_pomenis

FIGURE = Path(__file__).resolve().parents[1] / "docs" / "figures" / "starlink_pomenis.png"


def statistics(residual: np.ndarray) -> dict[str, float]:
    return {
        "mean": float(np.mean(residual)),
        "std": float(np.std(residual)),
        "median": float(np.median(residual)),
        "median_absolute": float(np.median(np.abs(residual))),
        "rms": float(np.sqrt(np.mean(residual**2))),
    }


def plot(table, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.5))
    sc = ax1.scatter(table.predicted, table.measured, c=table.phase_angle_deg, s=6, cmap="viridis")
    lo, hi = np.percentile(np.r_[table.predicted, table.measured], [0.5, 99.5])
    ax1.plot([lo, hi], [lo, hi], "k--", lw=1, label="measured = predicted")
    ax1.set(
        xlabel="predicted magnitude",
        ylabel="measured AB magnitude",
        xlim=(lo, hi),
        ylim=(lo, hi),
        title="Starlink v1.5 at Mount Lemmon (Pomenis)",
    )
    ax1.invert_xaxis()
    ax1.invert_yaxis()
    ax1.legend(loc="lower right")
    fig.colorbar(sc, ax=ax1, label="phase angle (deg)")
    ax2.scatter(table.phase_angle_deg, table.residual, s=6)
    ax2.axhline(0, color="k", lw=1)
    ax2.set(
        xlabel="phase angle (deg)",
        ylabel="measured − predicted (mag)",
        title="residuals (no fit to these data)",
    )
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def residual_report(materials: tuple[str, str], earthshine: str = "off") -> tuple[dict, object]:
    """Residual statistics of the prediction with the given chassis and array presets,
    with the Earth's light (``"on"``) or without (``"off"``)."""
    start = time.perf_counter()
    table = predict_pomenis(materials=materials, earthshine=earthshine)
    runtime = time.perf_counter() - start
    finite = np.isfinite(table.predicted)
    residual = table.residual[finite].to_numpy()
    low_phase = (table.phase_angle_deg < 60)[finite].to_numpy()
    report = {
        "materials": list(materials),
        "predicted_finite": int(finite.sum()),
        "residual_mag": statistics(residual),
        "residual_mag_phase_below_60deg": statistics(residual[low_phase]),
        "residual_mag_phase_above_60deg": statistics(residual[~low_phase]),
        "correlation_measured_predicted": float(
            np.corrcoef(table.measured[finite], table.predicted[finite])[0, 1]
        ),
        "runtime_s": runtime,
    }
    if earthshine == "on":
        share = table.earthshine_fraction[finite].to_numpy()
        report["earthshine_fraction"] = {
            "median": float(np.median(share)),
            "p90": float(np.percentile(share, 90)),
            "max": float(np.max(share)),
        }
        report["earthshine_brightening_mag"] = {
            "median": float(np.median(-2.5 * np.log10(1.0 - share))),
            "p90": float(np.percentile(-2.5 * np.log10(1.0 - share), 90)),
        }
    return report, table[finite]


def main() -> None:
    two_lobe, table = residual_report(MATERIALS)
    one_lobe, _ = residual_report(ONE_LOBE_MATERIALS)
    with_earthshine, _ = residual_report(MATERIALS, earthshine="on")
    plot(table, FIGURE)
    print(
        json.dumps(
            {
                "benchmark": "starlink_pomenis",
                "observations": len(table),
                "two_lobe": two_lobe,
                "one_lobe": one_lobe,
                "two_lobe_with_earthshine": with_earthshine,
                "figure": str(FIGURE.relative_to(FIGURE.parents[2])),
                "machine": machine_info(),
            },
            indent=2,
        )
    )


if __name__ == "__main__":
    main()
