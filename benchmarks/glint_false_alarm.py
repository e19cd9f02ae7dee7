"""False-alarm rate of the glint detector on glint-free light curves that bend like real ones.

Each curve is one night of a GEO object seen from a ground site (60 s cadence, dark sky,
object above 10°, out of the Earth's shadow): a flat Lambertian panel fixed in inertial space
(random normal) plus a Lambertian sphere, in random proportions, with 0.02 mag Gaussian
noise (``--noise-mag`` and ``--cadence`` change both). The panel fades as the observer's line
of sight turns towards its plane (the terminator of the panel), the sphere follows the phase
angle over the night; neither has a specular lobe, so any detection is a false alarm. Curves
are kept when the noiseless curve spans 0.3–4 mag (realistic curvature, not straight trends)
and the panel stays lit and seen.
The site (latitude ±40°), the object's longitude (±40° from the site's), the date (outside
the eclipse seasons) and the mixture are drawn from a seeded generator.

For each nominal per-curve false-alarm level FA the fraction of curves with any detection
is reported (a curve has a detection at FA when its largest brightening, in units of its σ,
exceeds the detector's threshold for FA: one baseline serves every level), with its 95 %
Clopper–Pearson upper bound, for the local-cubic baseline (the default), and in the same
run for the local quadratic and the running straight line (``degree`` 2 and 1).

With ``--flat`` the same nights are also run with a constant magnitude plus the same noise
(pure noise: the detector's threshold is calibrated for exactly this case, so the measured
rates check it; the detector is scale-free there, so only the first noise level is run).
Several ``--noise-mag`` values run the same nights and the same unit noise at each level.

    python -m benchmarks.glint_false_alarm [--curves 200] [--seed 0] [--flat]
        [--noise-mag 0.02 [0.01 ...]] [--cadence 60] [--baseline all|local_cubic|...]
"""

from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np
import pandas as pd
from scipy.stats import beta

from benchmarks._machine import machine_info
from lightcurve.analysis.glint import detect_glints, detection_threshold
from lightcurve.io.observations import Observations, datetime_to_mjd
from lightcurve.sky.ephemeris import CircularOrbit, Site, orbit_geometry

LEVELS = (1e-3, 1e-2, 0.05, 0.2)
NOISE_MAG = 0.02
CADENCE_S = 60.0
BASELINES = {"local_cubic": 3, "local_quadratic": 2, "straight_line": 1}
DEFAULT_BASELINE = "local_cubic"
MAX_NIGHTS = 1000  # night geometries drawn per accepted curve before giving up


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _night(rng: np.random.Generator, cadence: float) -> Observations | None:
    """Geometry of one night (up to 10 h around local midnight, every ``cadence`` s) of a
    random GEO object."""
    lat = rng.uniform(-40.0, 40.0)
    lon = rng.uniform(-180.0, 180.0)
    # Days of the year outside the eclipse seasons (±25 d around the equinoxes).
    day = rng.choice(np.r_[np.arange(105, 240), np.arange(290, 330), np.arange(0, 55)])
    date = pd.Timestamp("2026-01-01", tz="UTC") + pd.Timedelta(days=int(day))
    # MJD days start at 0 h UTC; local (mean solar) midnight at east longitude ``lon`` comes
    # ``lon/15`` hours earlier.
    midnight = datetime_to_mjd(pd.DatetimeIndex([date]))[0] - lon / 360.0
    mjd = midnight + np.arange(-5 * 3600.0, 5 * 3600.0, cadence) / 86400.0
    orbit = CircularOrbit.geostationary(lon + rng.uniform(-40.0, 40.0), mjd[0])
    try:
        return orbit_geometry(orbit, Site(lat, lon, 0.0, "site"), mjd, "geo")
    except ValueError:  # never visible that night: draw again
        return None


def glint_free_night(
    rng: np.random.Generator, cadence: float = CADENCE_S
) -> tuple[Observations, np.ndarray, float]:
    """One accepted glint-free night: noiseless curve, unit Gaussian noise, span (mag).

    The noisy curve at noise level σ is ``magnitudes + σ · noise``; the flat curve is the
    noiseless mean plus the same noise. Nights with fewer than 200 minutes of sampling are
    drawn again.
    """
    for _ in range(MAX_NIGHTS):
        geometry = _night(rng, cadence)
        if geometry is None or len(geometry.times) * cadence < 200 * 60.0:
            continue
        sun = _unit(geometry.sun_vectors)
        view = _unit(geometry.observer_vectors)
        alpha = np.arccos(np.clip(np.sum(sun * view, axis=1), -1, 1))
        sphere = (2 / (3 * math.pi**2)) * (np.sin(alpha) + (math.pi - alpha) * np.cos(alpha))
        for _ in range(50):  # objects for this night until one bends as required
            normal = _unit(rng.normal(size=3))
            panel = np.clip(sun @ normal, 0, None) * np.clip(view @ normal, 0, None) / math.pi
            weight = rng.uniform(0.0, 1.0)
            if np.min(panel) <= 0:
                continue
            mag = -2.5 * np.log10(weight * panel + (1 - weight) * sphere)
            span = float(np.ptp(mag))
            if not 0.3 <= span <= 4.0:
                continue
            noise = rng.standard_normal(len(mag))
            table = geometry.table.assign(mag=mag, mag_err=1.0)
            return Observations(table, geometry.meta), noise, span
    raise RuntimeError(f"no night of {MAX_NIGHTS} drawn gave an acceptable glint-free curve")


def noisy_curve(night: Observations, noise: np.ndarray, noise_mag: float, flat: bool):
    """The night's curve (``flat``: its mean magnitude) plus ``noise_mag · noise``."""
    mag = night.magnitudes
    if flat:
        mag = np.full(len(mag), float(np.mean(mag)))
    table = night.table.assign(mag=mag + noise_mag * noise, mag_err=noise_mag)
    return Observations(table, night.meta)


def upper_bound(hits: int, n: int, confidence: float = 0.95) -> float:
    """One-sided Clopper–Pearson upper bound on a rate from ``hits`` of ``n`` trials."""
    return 1.0 if hits >= n else float(beta.ppf(confidence, hits + 1, n - hits))


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--curves", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--flat",
        action="store_true",
        help="also the same nights made flat (constant magnitude plus the same noise)",
    )
    parser.add_argument(
        "--baseline",
        choices=["all", *BASELINES],
        default="all",
        help="baselines to run (default: all three)",
    )
    parser.add_argument(
        "--noise-mag",
        type=float,
        nargs="+",
        default=[NOISE_MAG],
        help="Gaussian σ (mag); several values run the same nights and unit noise at each",
    )
    parser.add_argument("--cadence", type=float, default=CADENCE_S, help="sampling interval (s)")
    args = parser.parse_args(argv)
    baselines = {name: d for name, d in BASELINES.items() if args.baseline in ("all", name)}
    reference = DEFAULT_BASELINE if DEFAULT_BASELINE in baselines else args.baseline
    # Pure noise is scale-free: the flat curves are run at the first noise level only.
    cases = [("curved", sigma) for sigma in args.noise_mag]
    cases += [("flat", args.noise_mag[0])] if args.flat else []
    rng = np.random.default_rng(args.seed)
    hits = {case: {name: dict.fromkeys(LEVELS, 0) for name in baselines} for case in cases}
    spans, points = [], []
    cpu = dict.fromkeys(baselines, 0.0)
    cpu_nights = 0.0
    for _ in range(args.curves):
        start = time.process_time()
        night, noise, span = glint_free_night(rng, args.cadence)
        cpu_nights += time.process_time() - start
        spans.append(span)
        points.append(len(night.times))
        for case in cases:
            curve = noisy_curve(night, noise, case[1], flat=case[0] == "flat")
            for name, degree in baselines.items():
                start = time.process_time()
                detection = detect_glints(curve, false_alarm=LEVELS[-1], degree=degree)
                cpu[name] += time.process_time() - start
                peak = float(np.max(detection.excess_sigma))
                for level in LEVELS:
                    threshold = detection_threshold(level, len(curve.times), dof=detection.dof)
                    hits[case][name][level] += peak > threshold
    n = args.curves
    runs = [
        {
            "curve_kind": kind,
            "noise_mag": sigma,
            "levels": [
                {
                    "false_alarm": level,
                    "allowed_curves": level * n,
                    **{
                        name: {
                            "curves": hits[kind, sigma][name][level],
                            "rate": hits[kind, sigma][name][level] / n,
                            "rate_upper_95": upper_bound(hits[kind, sigma][name][level], n),
                        }
                        for name in baselines
                    },
                    "holds": hits[kind, sigma][reference][level] <= level * n,
                }
                for level in LEVELS
            ],
        }
        for kind, sigma in cases
    ]
    result = {
        "benchmark": "glint_false_alarm",
        "seed": args.seed,
        "curves": n,
        "cadence_s": args.cadence,
        "points_per_curve": {"min": int(np.min(points)), "median": float(np.median(points))},
        "curve_span_mag": {
            "min": float(np.min(spans)),
            "median": float(np.median(spans)),
            "max": float(np.max(spans)),
        },
        "default_baseline": DEFAULT_BASELINE,
        "holds_refers_to": reference,
        "runs": runs,
        "cpu_seconds_per_curve": {
            "night": cpu_nights / n,
            **{name: cpu[name] / (n * len(cases)) for name in baselines},
        },
        "machine": machine_info(),
    }
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
