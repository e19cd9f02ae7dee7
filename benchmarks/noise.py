"""Observing-conditions noise: Monte Carlo checks and what the 0.5 m defaults give.

Unbiasedness: ``--runs`` independent sets (seeds 0, 1, …) of 10⁴ exposures of a constant
V = 11 source observed between 20° and 90° elevation (elevations from seed 2024) under the
defaults (``lightcurve/data/telescopes/half_metre.toml``), 1 s and 10 s exposures; per set the
offset of the mean extinction-corrected magnitude from the truth in units of its standard error,
``z`` — as measured, and after removing the second-order bias of a magnitude,
``(2.5/ln 10) σ_F²/2`` with ``σ_F`` the relative flux error — the same for the mean flux,
and the extinction coefficient fitted to the uncorrected magnitudes against airmass. The
bias-free ``z`` should be standard normal.

Spread: the SNR of the simulated fluxes (mean/std over 10⁴ draws, seed 11) against the
CCD equation's SNR, bright (scintillation-limited) to faint (background-limited).

Defaults: expected SNR, magnitude error and saturation of the 0.5 m telescope at 1 s and
10 s, zenith to 20° elevation (site altitude 2000 m).

    python -m benchmarks.noise [--runs 20]
"""

from __future__ import annotations

import argparse
import json
import math
from typing import Any

import numpy as np
import pandas as pd

from benchmarks._machine import machine_info
from lightcurve.io.observations import Observations, validate_table
from lightcurve.photometry.conditions import load_conditions
from lightcurve.photometry.noise import ObservingNoise
from lightcurve.sky.sites import Site

N = 10_000
ALTITUDE_M = 2000.0


def placeholder_geometry(
    elevation_deg: Any, site: Site | None = None, source: str = "benchmark", **columns: Any
) -> Observations:
    """Rows at the given elevations with placeholder Sun/observer vectors (km).

    The noise models read only the elevation, the exposure and the site, so a table of
    elevations is enough to exercise them (also used by
    ``tests/lightcurve/photometry/test_noise.py``).

    Parameters
    ----------
    elevation_deg : (n,) array_like
        Elevation of the object at each row (degrees).
    site : Site, optional
        Recorded in the file header (``site``).
    source : str
        Name of the table in messages.
    **columns
        Further columns, e.g. ``exposure_s`` (s).
    """
    elevation = np.asarray(elevation_deg, dtype=float)
    table = pd.DataFrame(
        {
            "mjd": 60000.0 + np.arange(elevation.size) / 86400.0,
            "sun_x": 1.496e8,
            "sun_y": 0.0,
            "sun_z": 0.0,
            "obs_x": 0.0,
            "obs_y": 3.6e4,
            "obs_z": 0.0,
            "elevation_deg": elevation,
            **columns,
        }
    )
    meta = {"site": site.label} if site is not None else {}
    return Observations(validate_table(table, source, meta, require_magnitudes=False), meta, source)


def _z(values: np.ndarray, truth: float) -> float:
    return float((values.mean() - truth) / (values.std() / math.sqrt(values.size)))


def unbiasedness(runs: int, exposure_s: float) -> dict[str, object]:
    conditions = load_conditions("half_metre", [f"site.altitude_m={ALTITUDE_M}"])
    raw = load_conditions(
        "half_metre", [f"site.altitude_m={ALTITUDE_M}", "photometry.extinction_corrected=false"]
    )
    elevation = np.random.default_rng(2024).uniform(20.0, 90.0, N)
    geometry = placeholder_geometry(elevation, exposure_s=exposure_s)
    truth = np.full(N, 11.0)
    budget = conditions.budget(truth, elevation, exposure_s, ALTITUDE_M)
    bias = float(np.mean(0.5 * 2.5 / math.log(10.0) / budget.snr**2))
    z, z_debiased, z_flux, k_fit = [], [], [], []
    for seed in range(runs):
        mags = ObservingNoise(conditions).measure(truth, geometry, np.random.default_rng(seed))
        mags = mags.magnitude
        z.append(_z(mags, 11.0))
        z_debiased.append(_z(mags - bias, 11.0))
        z_flux.append(_z(10 ** (-0.4 * (mags - 11.0)), 1.0))
        observed = ObservingNoise(raw).measure(truth, geometry, np.random.default_rng(seed))
        k_fit.append(np.polyfit(observed.columns["airmass"], observed.magnitude, 1)[0])

    def summary(values: list[float]) -> dict[str, float]:
        return {
            "mean": float(np.mean(values)),
            "std": float(np.std(values, ddof=1)),
            "max_abs": float(np.max(np.abs(values))),
            "within_1": int(np.sum(np.abs(values) < 1)),
        }

    return {
        "source_mag": 11.0,
        "exposure_s": exposure_s,
        "exposures_per_run": N,
        "runs": runs,
        "seeds": f"0..{runs - 1}",
        "mag_err_median": float(np.median(budget.magnitude_error)),
        "second_order_bias_mag": bias,
        "z_magnitude": summary(z),
        "z_magnitude_minus_bias": summary(z_debiased),
        "z_flux": summary(z_flux),
        "k_true": conditions.site.extinction_mag_per_airmass,
        "k_fit_mean": float(np.mean(k_fit)),
        "k_fit_std": float(np.std(k_fit, ddof=1)),
    }


def spread() -> list[dict[str, float]]:
    conditions = load_conditions("half_metre", [f"site.altitude_m={ALTITUDE_M}"])
    rows = []
    for magnitude, elevation, exposure in (
        (8.5, 60.0, 1.0),
        (12.0, 45.0, 10.0),
        (16.0, 30.0, 10.0),
    ):
        geometry = placeholder_geometry(np.full(N, elevation), exposure_s=exposure)
        budget = conditions.budget(
            np.array([magnitude]), np.array([elevation]), exposure, ALTITUDE_M
        )
        measured = ObservingNoise(conditions).measure(
            np.full(N, magnitude), geometry, np.random.default_rng(11)
        )
        flux = 10 ** (-0.4 * (measured.magnitude - magnitude))
        rows.append(
            {
                "mag": magnitude,
                "elevation_deg": elevation,
                "exposure_s": exposure,
                "snr_ccd_equation": float(budget.snr[0]),
                "snr_simulated": float(np.nanmean(flux) / np.nanstd(flux)),
                "scintillation_share": float(
                    (budget.scintillation[0] * budget.source_e[0]) ** 2
                    / budget.variance(budget.source_e)[0]
                ),
            }
        )
    return rows


def defaults_table() -> list[dict[str, object]]:
    conditions = load_conditions("half_metre")
    magnitudes = np.arange(6.0, 19.0, 1.0)
    rows = []
    for exposure in (1.0, 10.0):
        for elevation in (90.0, 45.0, 20.0):
            budget = conditions.budget(
                magnitudes, np.full(magnitudes.size, elevation), exposure, ALTITUDE_M
            )
            saturated = budget.peak_e + budget.sky_e + budget.dark_e >= budget.saturation_e
            rows.append(
                {
                    "exposure_s": exposure,
                    "elevation_deg": elevation,
                    "airmass": round(float(budget.airmass[0]), 3),
                    "mag_err": {
                        f"{m:g}": round(float(e), 4)
                        for m, e in zip(magnitudes, budget.magnitude_error, strict=True)
                    },
                    "brightest_unsaturated_mag": float(magnitudes[~saturated][0]),
                }
            )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20)
    args = parser.parse_args()
    print(
        json.dumps(
            {
                "unbiasedness": [unbiasedness(args.runs, t) for t in (1.0, 10.0)],
                "spread": spread(),
                "defaults": defaults_table(),
                "machine": machine_info(),
            },
            indent=1,
        )
    )


if __name__ == "__main__":
    main()
