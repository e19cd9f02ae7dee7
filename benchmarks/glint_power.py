"""Detection power of the glint detector: injected flashes of known amplitude on pure noise.

Each trial is a 10-hour light curve at 60 s cadence (600 points) of Gaussian noise
(0.02 mag) with one Gaussian flash, ``m(t) = m₀ − A exp(−(t − t₀)²/(2 w²))``, of peak
brightening A (mag) and width ``w = 120 s``, at an epoch t₀ drawn uniformly over the curve
(ends included). A flash counts as found when the detector, at its default false-alarm level
(1e-3), reports a glint within three sampling intervals of t₀; glints elsewhere are counted
separately (false alarms on these curves). The noise and epochs come from a seeded generator,
so a run with another version of :mod:`lightcurve.analysis.glint` on the path (``PYTHONPATH``)
measures that version on the same trials: this is how the cost of a change of the threshold in
detection rate is shown.

    python -m benchmarks.glint_power [--trials 100] [--seed 0]
"""

from __future__ import annotations

import argparse
import inspect
import json
import time

import numpy as np
import pandas as pd

from benchmarks._machine import machine_info
from lightcurve.analysis.glint import detect_glints
from lightcurve.io.observations import Observations, validate_table

AMPLITUDES_MAG = (0.06, 0.08, 0.10, 0.12, 0.15, 0.20)
NOISE_MAG = 0.02
CADENCE_S = 60.0
POINTS = 600
WIDTH_S = 120.0
FALSE_ALARM = 1e-3


def fixed_geometry_curve(
    times_s: np.ndarray, mag: np.ndarray, mag_err: float, source: str
) -> Observations:
    """A light curve with constant Sun and observer vectors (km), starting at MJD 61000.

    The glint detector reads only the magnitudes and their errors; the geometry columns are
    there to make the table a valid observation file (also used by
    ``tests/lightcurve/analysis/test_glint.py``).

    Parameters
    ----------
    times_s : (n,) array_like
        Epochs (s after the first).
    mag : (n,) array_like
        Magnitudes.
    mag_err : float
        1σ error of every magnitude (mag).
    source : str
        Name of the table in messages.
    """
    table = pd.DataFrame(
        {
            "mjd": 61000.0 + np.asarray(times_s, dtype=float) / 86400.0,
            "mag": mag,
            "mag_err": mag_err,
            "sun_x": 1.5e8,
            "sun_y": 0.0,
            "sun_z": 0.0,
            "obs_x": 0.0,
            "obs_y": 3.6e4,
            "obs_z": 0.0,
        }
    )
    return Observations(validate_table(table, source), {})


def flash_curve(rng: np.random.Generator, amplitude: float) -> tuple[Observations, float]:
    """One noisy curve with a flash of peak ``amplitude`` (mag) and the flash's epoch (s)."""
    t = np.arange(POINTS) * CADENCE_S
    epoch = rng.uniform(t[0], t[-1])
    mag = (
        12.0
        - amplitude * np.exp(-0.5 * ((t - epoch) / WIDTH_S) ** 2)
        + rng.normal(0.0, NOISE_MAG, POINTS)
    )
    return fixed_geometry_curve(t, mag, NOISE_MAG, "injected flash"), epoch


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=100, help="curves per amplitude")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    rows = []
    seconds = 0.0
    for amplitude in AMPLITUDES_MAG:
        found = elsewhere = 0
        for _ in range(args.trials):
            curve, epoch = flash_curve(rng, amplitude)
            start = time.process_time()
            glints = detect_glints(curve, false_alarm=FALSE_ALARM).glints
            seconds += time.process_time() - start
            near = [abs(g.time_s - epoch) <= 3 * CADENCE_S for g in glints]
            found += any(near)
            elsewhere += len(near) - sum(near)
        rows.append(
            {
                "amplitude_mag": amplitude,
                "amplitude_sigma": amplitude / NOISE_MAG,
                "detection_rate": found / args.trials,
                "glints_elsewhere": elsewhere,
            }
        )
    result = {
        "benchmark": "glint_power",
        "seed": args.seed,
        "trials_per_amplitude": args.trials,
        "points_per_curve": POINTS,
        "cadence_s": CADENCE_S,
        "noise_mag": NOISE_MAG,
        "flash_width_s": WIDTH_S,
        "false_alarm": FALSE_ALARM,
        "detector_source": inspect.getsourcefile(detect_glints),
        "amplitudes": rows,
        "cpu_seconds_per_curve": seconds / (args.trials * len(AMPLITUDES_MAG)),
        "machine": machine_info(),
    }
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
