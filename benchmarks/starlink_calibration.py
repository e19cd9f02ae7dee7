"""Starlink v1.5 calibrated on the Pomenis observations, cross-validated by night. Prints JSON.

    python -m benchmarks.starlink_calibration [--folds 5] [--seed 0] [--splits 4] [--every 1]
        [--sets NAME,…] [--starts 6] [--out FILE]

The built-in ``starlink_v1_5`` shape (the two-surface model of Fankhauser, Askari & Tyson
2023: chassis to nadir, a solar array that turns about the vertical to face the Sun,
lab-fitted two-lobe materials) flown by the nadir profile, with the Earth's light (the
satellites are at ~550 km), is calibrated with
:func:`lightcurve.photometry.calibration.calibrate` on the 1173 Pomenis observations (79
nights at Mount Lemmon) for these parameter sets:

``offset``
    the magnitude offset alone (the albedo–area scale);
``offset_array``
    the offset and the array's pointing offset (its joint offset from facing the Sun);
``lobes``
    the offset, both materials' broad-lobe weight and width, and the array's narrow lobe
    (weight and width);
``all``
    the offset and every BRDF parameter of both materials;
``all_array``
    as ``all``, with the array's pointing offset;
``all_without_earthshine``
    as ``all``, the Earth's light left out: what it is worth after calibration.

Each is cross-validated by night (``--folds``, nights shuffled with ``--seed``) and, for
the two-sided check of a calibration made on some nights and used on others, split
``--splits`` times into random halves of the nights (seeded): calibrated on one half,
predicted on the other. The baseline is the unfitted prediction of the lab materials,
measured in the same run. Nominal 1σ of the observations: 0.1 mag; soft-L1 loss at 3σ.
``--every N`` keeps every N-th observation and ``--sets`` names the parameter sets run (a
quick run). ``calibration_cpu_s`` is the
process time of one calibration on all the observations.
"""

from __future__ import annotations

import argparse
import time
from typing import Any

import numpy as np

from benchmarks._machine import machine_info
from benchmarks._report import emit_report
from lightcurve.datasets.starlink import MOUNT_LEMMON, pomenis_geometry, read_pomenis
from lightcurve.photometry.calibration import (
    calibrate,
    cross_validate,
    model_magnitude,
    night_index,
)
from lightcurve.photometry.profiles import profile_states
from shapes import get_library

_LOBES = [
    "chassis.rb",
    "chassis.ab",
    "solar_array.rb",
    "solar_array.ab",
    "solar_array.rn",
    "solar_array.mn",
]
_ALL = ["chassis.*", "solar_array.*"]
#: Name → options of :func:`calibrate` (besides the robust loss and the shadows).
PARAMETER_SETS: dict[str, dict[str, Any]] = {
    "offset": {},
    "offset_array": {"joint_offsets": ["array"]},
    "lobes": {"parameters": _LOBES},
    "all": {"parameters": _ALL},
    "all_array": {"parameters": _ALL, "joint_offsets": ["array"]},
    "all_without_earthshine": {"parameters": _ALL, "earthshine": "off"},
}


def _halves(model, q, observations, nights, options, splits: int, seed: int) -> list[dict]:
    """Calibrated on a random half of the nights, predicted on the other half."""
    rng = np.random.default_rng(seed)
    unique = np.unique(nights)
    out = []
    for _ in range(splits):
        first = np.isin(nights, rng.permutation(unique)[: len(unique) // 2])
        result = cross_validate(
            model,
            q,
            observations,
            np.where(first, 0, 1),
            folds=2,
            seed=seed,
            shadows="none",
            **options,
        )
        out.append({k: result[k] for k in ("cv_rms_mag", "cv_bias_mag")})
    return out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--folds", type=int, default=5)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--splits", type=int, default=4)
    parser.add_argument("--every", type=int, default=1)
    parser.add_argument("--sets", default=",".join(PARAMETER_SETS))
    parser.add_argument("--starts", type=int, default=6, help="starts of every calibration")
    parser.add_argument("--out", default=None)
    args = parser.parse_args(argv)

    observations, _ = pomenis_geometry(read_pomenis().iloc[:: args.every])
    model = get_library().load("starlink_v1_5", articulated=True)
    q = profile_states(observations, "nadir", yaw_steering=True)[:, :4]
    nights = night_index(observations.mjd, MOUNT_LEMMON.longitude_deg)
    start = time.perf_counter()
    unfitted = observations.magnitudes - model_magnitude(model, q, observations, shadows="none")
    baseline = {
        "rms_mag": float(np.sqrt(np.mean(unfitted**2))),
        "mean_mag": float(np.mean(unfitted)),
        "std_mag": float(np.std(unfitted)),
        "runtime_s": time.perf_counter() - start,
    }
    report: dict[str, Any] = {
        "benchmark": "starlink_calibration",
        "observations": len(observations),
        "nights": len(np.unique(nights)),
        "folds": args.folds,
        "seed": args.seed,
        "unfitted_prediction": baseline,
        "parameter_sets": {},
    }
    for name in args.sets.split(","):
        options = PARAMETER_SETS[name]
        start = time.process_time()
        options = {**options, "starts": args.starts}
        fit = calibrate(model, q, observations, shadows="none", **options)
        fit_time = time.process_time() - start
        result = cross_validate(
            model,
            q,
            observations,
            nights,
            folds=args.folds,
            seed=args.seed,
            shadows="none",
            **options,
        )
        halves = _halves(model, q, observations, nights, options, args.splits, args.seed)
        report["parameter_sets"][name] = {
            "train_rms_mag": fit.train_rms_mag,
            "cv_rms_mag": result["cv_rms_mag"],
            "cv_bias_mag": result["cv_bias_mag"],
            "per_fold": result["folds"],
            "halves": halves,
            "halves_minus_cv_rms_mag": [h["cv_rms_mag"] - result["cv_rms_mag"] for h in halves],
            "parameters": fit.parameters,
            "earthshine": fit.earthshine,
            "calibration_cpu_s": fit_time,
            "cv_rms_over_unfitted_rms": result["cv_rms_mag"] / baseline["rms_mag"],
        }
    report["machine"] = machine_info()
    emit_report(report, args.out)


if __name__ == "__main__":
    main()
