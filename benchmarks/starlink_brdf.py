"""Fit every reflectance model to the Starlink v1.5 laboratory BRDF tables; plot data vs fit.

Data: ``data/starlink/chassis_brdf.csv`` and ``solar_array_brdf.csv`` (Fankhauser, Askari &
Tyson 2023, 532 nm, in-plane scans at incidence zenith 5°, 41.4°, 60°, 75°). The rows at
scatter zenith ±90° hold the value 1e-4 sr⁻¹ in every scan, a floor of the instrument at the
horizon rather than a measurement; they are excluded. Each model is fitted in log10 space
(`brdf.fit`), Ashikhmin–Shirley isotropically (``nv`` tied to ``nu``: in-plane data do not
constrain anisotropy).

Every model is fitted under the same rule (docs/brdf.md, "Fitting lab tables"): each band of
distance from the mirror direction (≤ 1°, 1–3°, 3–10°, 10–30°, 30–90°, > 90°) of each
incidence gets equal total weight (`brdf.mirror_band_weights`), and the tilt of the sample
normal in the plane of incidence, an alignment offset of the lab set-up, is fitted with the
material (``fit_tilt``). Its 1σ is given twice: from the fit's Jacobian, and from a
leave-one-incidence-out jackknife (robust to residuals correlated along a scan). For
comparison each model is also fitted unweighted with no tilt (``plain``).

Prints JSON (weighted and plain RMS log10 residuals per model and per incidence, the residuals
at the points within 1° of the mirror direction, the fitted tilt, parameters with 1σ, how much
better the two-lobe model fits than the best one-lobe model under the same treatment, timings,
machine info) and writes the polar plots ``docs/figures/starlink_<material>_brdf.png`` and
``docs/figures/starlink_<material>_mirror.png``.

Usage (from the repository root): ``python -m benchmarks.starlink_brdf [--figures DIR]
[--starts N]``
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import scipy

import brdf
from benchmarks._machine import machine_info

ROOT = Path(__file__).resolve().parent.parent
MATERIALS = {"chassis": "chassis_brdf.csv", "solar_array": "solar_array_brdf.csv"}
FIT_OPTIONS = {"ashikhmin-shirley": {"tied": {"nv": "nu"}}}
STYLES = {
    "lambert": ("tab:gray", ":"),
    "phong": ("tab:blue", "-"),
    "cook-torrance": ("tab:red", "-"),
    "ashikhmin-shirley": ("tab:green", "--"),
    "lommel-seeliger": ("tab:purple", "-."),
    "two-lobe": ("tab:cyan", "-"),
}
ONE_LOBE = ("phong", "cook-torrance", "ashikhmin-shirley")
MIRROR_DEG = 1.0  # "near the mirror direction": within this angle of it
LOG_FLOOR = -3.5  # plot radius 0 is 10^LOG_FLOOR sr⁻¹


def load(name: str) -> tuple[brdf.BRDFTable, int]:
    """The table without the ±90° floor rows, and how many rows were dropped."""
    table = brdf.read_starlink_table(ROOT / "data" / "starlink" / MATERIALS[name])
    keep = np.abs(table.zenith_out) < 90.0
    return table.select(keep), int((~keep).sum())


def per_incidence_rms(table: brdf.BRDFTable, result: brdf.FitResult) -> dict[str, float]:
    incidence = table.zenith_in[result.used]
    return {
        f"{angle:g}": float(np.sqrt(np.mean(result.residuals[incidence == angle] ** 2)))
        for angle in np.unique(incidence)
    }


mirror_distance_deg = brdf.mirror_distance_deg


def fit(
    model_name: str, table: brdf.BRDFTable, starts: int, treated: bool = True
) -> brdf.FitResult:
    """``model_name`` fitted under the benchmark's rule (band weights, fitted tilt) or plainly."""
    options = dict(FIT_OPTIONS.get(model_name, {}))
    if treated:
        options.update(weights=brdf.mirror_band_weights(table), fit_tilt=True)
    return brdf.fit(model_name, table, starts=starts, **options)


def jackknife_tilt(model_name: str, table: brdf.BRDFTable, starts: int) -> float:
    """Leave-one-incidence-out jackknife 1σ (deg) of the fitted tilt."""
    incidences = np.unique(table.zenith_in)
    tilts = np.array(
        [
            fit(model_name, table.select(table.zenith_in != angle), starts).tilt
            for angle in incidences
        ]
    )
    count = tilts.size
    return float(np.sqrt((count - 1) / count * np.sum((tilts - tilts.mean()) ** 2)))


def untilted(table: brdf.BRDFTable, result: brdf.FitResult) -> dict[str, float]:
    """Fit statistics of ``result``'s material with the sample normal on ``z`` (no tilt)."""
    light, view = table.directions()
    used = result.used
    model = result.brdf()(
        np.array([0.0, 0.0, 1.0]), light[used], view[used], tangent=np.array([1.0, 0.0, 0.0])
    )
    residuals = np.log10(np.maximum(model, 1e-12)) - np.log10(table.value[used])
    weights = brdf.mirror_band_weights(table)[used]
    near = mirror_distance_deg(table)[used] <= MIRROR_DEG + 1e-9
    return {
        "rms_dex": float(np.sqrt(np.sum(weights * residuals**2) / np.sum(weights))),
        "rms_dex_unweighted": float(np.sqrt(np.mean(residuals**2))),
        "near_mirror_max_abs_dex": float(np.max(np.abs(residuals[near]))),
        "near_mirror_rms_dex": float(np.sqrt(np.mean(residuals[near] ** 2))),
    }


def near_mirror(table: brdf.BRDFTable, result: brdf.FitResult) -> dict[str, float]:
    """Residuals at the used points within `MIRROR_DEG` of the mirror direction."""
    near = mirror_distance_deg(table)[result.used] <= MIRROR_DEG + 1e-9
    residual = result.residuals[near]
    return {
        "points": int(near.sum()),
        "max_abs_dex": float(np.max(np.abs(residual))),
        "rms_dex": float(np.sqrt(np.mean(residual**2))),
        "rms_dex_elsewhere": float(np.sqrt(np.mean(result.residuals[~near] ** 2))),
    }


def model_curve(
    model: brdf.BRDF, incidence_deg: float, zenith_out_deg: np.ndarray, tilt_deg: float = 0.0
) -> np.ndarray:
    table = brdf.BRDFTable.from_columns(
        {
            "zenith_in": np.full_like(zenith_out_deg, incidence_deg),
            "azimuth_in": np.full_like(zenith_out_deg, -180.0),
            "zenith_out": zenith_out_deg,
            "azimuth_out": np.zeros_like(zenith_out_deg),
            "value": np.ones_like(zenith_out_deg),
        }
    )
    light, view = table.directions()
    angle = np.radians(tilt_deg)
    normal = np.array([np.sin(angle), 0.0, np.cos(angle)])
    return model(normal, light, view, tangent=np.array([np.cos(angle), 0.0, -np.sin(angle)]))


def radius(values: np.ndarray) -> np.ndarray:
    return np.clip(np.log10(np.maximum(values, 1e-30)) - LOG_FLOOR, 0.0, None)


def plot(name: str, table: brdf.BRDFTable, fits: dict[str, brdf.FitResult], path: Path) -> None:
    """Polar plots (angle = signed scatter zenith, radius = log10 BRDF) of data and fits."""
    incidences = np.unique(table.zenith_in)
    columns = 2
    rows_of_plots = -(-len(incidences) // columns)
    figure, axes = plt.subplots(
        rows_of_plots,
        columns,
        subplot_kw={"projection": "polar"},
        figsize=(9.0, 3.6 * rows_of_plots + 1.2),
        squeeze=False,
    )
    top = max(np.log10(table.value.max()), 1.0) - LOG_FLOOR + 0.3
    for axis, incidence in zip(axes.ravel(), incidences, strict=False):
        rows = table.zenith_in == incidence
        # 0.05° steps, 0.002° within 1° of the mirror direction (the narrow lobe).
        zenith_fine = np.union1d(
            np.linspace(-89.5, 89.5, 3581), incidence + np.linspace(-1.0, 1.0, 1001)
        )
        axis.set_theta_zero_location("N")
        axis.set_theta_direction(-1)
        axis.set_thetamin(-90)
        axis.set_thetamax(90)
        axis.set_ylim(0, top)
        ticks = np.arange(np.ceil(LOG_FLOOR), np.floor(top + LOG_FLOOR) + 1, 2)
        axis.set_yticks(ticks - LOG_FLOOR, [f"$10^{{{int(t)}}}$" for t in ticks], fontsize=7)
        for model_name, result in fits.items():
            colour, style = STYLES[model_name]
            values = model_curve(result.brdf(), incidence, zenith_fine, result.tilt)
            axis.plot(
                np.radians(zenith_fine),
                radius(values),
                color=colour,
                linestyle=style,
                linewidth=1.0,
                label=f"{model_name} ({result.rms:.2f} dex)",
            )
        axis.plot(
            np.radians(table.zenith_out[rows]),
            radius(table.value[rows]),
            "k.",
            markersize=2.5,
            label="lab data (532 nm)",
        )
        axis.annotate(
            "",
            xy=(np.radians(-incidence), top),
            xytext=(0, 0),
            arrowprops={"arrowstyle": "<-", "color": "orange"},
        )
        axis.set_title(f"incidence {incidence:g}°", fontsize=9, pad=-6)
        axis.tick_params(axis="x", labelsize=7)
    handles, labels = axes.ravel()[0].get_legend_handles_labels()
    figure.legend(handles, labels, loc="lower center", ncol=3, fontsize=8, frameon=False)
    figure.suptitle(
        f"Starlink v1.5 {name.replace('_', ' ')}: in-plane BRDF (sr⁻¹, log radius) vs "
        "scatter zenith; orange arrow = Sun; fits with fitted sample tilt",
        fontsize=10,
    )
    figure.subplots_adjust(bottom=0.12, top=0.9, hspace=0.05, wspace=0.15)
    save(figure, path)


def plot_mirror(
    name: str, table: brdf.BRDFTable, fits: dict[str, brdf.FitResult], path: Path
) -> None:
    """BRDF within ±4° of the mirror direction per incidence: data, best one-lobe, two-lobe."""
    incidences = np.unique(table.zenith_in)
    figure, axes = plt.subplots(1, len(incidences), figsize=(3.0 * len(incidences), 3.4))
    offsets = np.linspace(-4.0, 4.0, 4001)
    for axis, incidence in zip(np.atleast_1d(axes), incidences, strict=True):
        rows = (table.zenith_in == incidence) & (np.abs(table.zenith_out - incidence) <= 4.0)
        for model_name, result in fits.items():
            colour, style = STYLES[model_name]
            values = model_curve(result.brdf(), incidence, incidence + offsets, result.tilt)
            axis.semilogy(
                offsets,
                values,
                color=colour,
                linestyle=style,
                linewidth=1.0,
                label=f"{model_name} ({result.rms:.2f} dex)",
            )
        axis.semilogy(
            table.zenith_out[rows] - incidence, table.value[rows], "k.", label="lab data (532 nm)"
        )
        axis.axvspan(-MIRROR_DEG, MIRROR_DEG, color="0.9", zorder=0)
        axis.set_title(f"incidence {incidence:g}°", fontsize=9)
        axis.set_xlabel("scatter zenith − mirror zenith (deg)", fontsize=8)
        axis.tick_params(labelsize=7)
    np.atleast_1d(axes)[0].set_ylabel("BRDF (sr⁻¹)", fontsize=8)
    handles, labels = np.atleast_1d(axes)[0].get_legend_handles_labels()
    figure.legend(handles, labels, loc="lower center", ncol=len(labels), fontsize=7, frameon=False)
    figure.suptitle(
        f"Starlink v1.5 {name.replace('_', ' ')}: near the mirror direction (shaded: within "
        f"{MIRROR_DEG:g}°)",
        fontsize=10,
    )
    figure.subplots_adjust(bottom=0.27, top=0.86, wspace=0.3, left=0.06, right=0.99)
    save(figure, path)


def save(figure: plt.Figure, path: Path) -> None:
    """Write ``figure`` to ``path`` atomically (PNG) and close it."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.NamedTemporaryFile(dir=path.parent, suffix=".png", delete=False) as handle:
        temporary = Path(handle.name)
    try:
        figure.savefig(temporary, dpi=110)
        os.replace(temporary, path)
    finally:
        temporary.unlink(missing_ok=True)
        plt.close(figure)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--figures", type=Path, default=ROOT / "docs" / "figures")
    parser.add_argument("--starts", type=int, default=5, help="fit starting points per model")
    args = parser.parse_args(argv)
    report: dict = {
        "machine": {**machine_info(), "scipy": scipy.__version__},
        "residual": "log10(model/data), dex",
        "materials": {},
    }
    for name in MATERIALS:
        table, dropped = load(name)
        fits, entries = {}, {}
        for model_name in brdf.available():
            start = time.perf_counter()
            result = fit(model_name, table, args.starts)
            elapsed = time.perf_counter() - start
            plain = fit(model_name, table, args.starts, treated=False)
            fits[model_name] = result
            entries[model_name] = {
                "rms_dex": result.rms,
                "rms_dex_unweighted": result.rms_unweighted,
                "rms_dex_per_incidence": per_incidence_rms(table, result),
                "median_abs_dex": float(np.median(np.abs(result.residuals))),
                "max_abs_dex": float(np.max(np.abs(result.residuals))),
                "near_mirror": near_mirror(table, result),
                "tilt_deg": result.tilt,
                "tilt_sigma_deg": result.tilt_sigma,
                "params": result.params,
                "sigma": result.uncertainties,
                "success": result.success,
                "message": result.message,
                "seconds": elapsed,
                "plain": {
                    "rms_dex": plain.rms,
                    "near_mirror": near_mirror(table, plain),
                    "params": plain.params,
                },
            }
        best = min(entries, key=lambda m: entries[m]["rms_dex"])
        best_one_lobe = min(ONE_LOBE, key=lambda m: entries[m]["rms_dex"])
        for model_name in (best_one_lobe, "two-lobe"):
            entries[model_name]["tilt_sigma_deg_jackknife"] = jackknife_tilt(
                model_name, table, args.starts
            )
        # The material alone (preset: no tilt) on the lab geometry as tabulated.
        entries["two-lobe"]["untilted"] = untilted(table, fits["two-lobe"])
        figure = args.figures / f"starlink_{name}_brdf.png"
        plot(name, table, fits, figure)
        mirror_figure = args.figures / f"starlink_{name}_mirror.png"
        plot_mirror(name, table, {m: fits[m] for m in (best_one_lobe, "two-lobe")}, mirror_figure)

        best_plain = min(ONE_LOBE, key=lambda m: entries[m]["plain"]["rms_dex"])
        report["materials"][name] = {
            "rows_used": int(fits["lambert"].used.sum()),
            "rows_dropped_horizon_floor": dropped,
            "weighting": "equal total weight per mirror-distance band per incidence, bands "
            f"{list(brdf.fitting.MIRROR_BANDS_DEG)} deg; tilt fitted",
            "models": entries,
            "best": best,
            "lambert_over_best_rms": entries["lambert"]["rms_dex"] / entries[best]["rms_dex"],
            "best_one_lobe": best_one_lobe,
            "best_one_lobe_over_two_lobe_rms": entries[best_one_lobe]["rms_dex"]
            / entries["two-lobe"]["rms_dex"],
            "best_one_lobe_over_two_lobe_rms_unweighted": min(
                entries[m]["rms_dex_unweighted"] for m in ONE_LOBE
            )
            / entries["two-lobe"]["rms_dex_unweighted"],
            "plain_best_one_lobe": best_plain,
            "plain_best_one_lobe_over_two_lobe_rms": entries[best_plain]["plain"]["rms_dex"]
            / entries["two-lobe"]["plain"]["rms_dex"],
            "figures": [
                str(path.relative_to(ROOT) if path.is_relative_to(ROOT) else path)
                for path in (figure, mirror_figure)
            ],
        }
    json.dump(report, sys.stdout, indent=2)
    print()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
