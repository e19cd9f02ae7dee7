"""TLE geometry: speed for 10⁵ epochs, and accuracy against skyfield.

Speed: the full geometry of ``lightcurve geometry --tle`` (SGP4, TEME/ITRS/GCRS rotations,
Sun, site, Earth shadow, phase angle, horizon coordinates, airmass) for 10⁵ epochs of the ISS
at 1 Hz from Zimmerwald, best of three; the baseline is the straightforward astropy chain
(``TEME → ITRS`` and ``TEME → GCRS`` of the SGP4 positions, ``EarthLocation.get_gcrs``,
``get_body("sun")``) on 10⁴ of the epochs, measured in the same run, per epoch.

Accuracy: topocentric direction and range against skyfield's independent SGP4 → ITRS →
topocentric chain (:mod:`lightcurve.sky.tle_reference`) for 11 LEO, MEO, GEO, Molniya and HEO
element sets of ``data/tle/catalogue.tle``, 10⁴ random epochs within two days of each TLE
epoch (seed 2024), from Kislovodsk, Siding Spring and Haleakala.

    python -m benchmarks.tle_geometry [--skip-accuracy]
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np

from benchmarks._machine import machine_info
from lightcurve.sky.satellite_geometry import from_tle
from lightcurve.sky.sites import get_site
from lightcurve.sky.tle import read_tles, select_object

CATALOGUE = Path(__file__).resolve().parents[1] / "data" / "tle" / "catalogue.tle"
ACCURACY_OBJECTS = (25544, 28057, 43477, 28129, 39191, 28868, 24208, 41105, 8195, 21897, 27540)
SEED = 2024


def _ours(tles, site, mjd) -> float:
    start = time.perf_counter()
    geometry = from_tle(tles, site, mjd, max_age_days=None)
    geometry.table()
    geometry.sun_elevation_deg  # noqa: B018 - the darkness filter of the command
    return time.perf_counter() - start


def _astropy_chain(tle, site, mjd) -> float:
    """The straightforward chain: every rotation and the Sun evaluated by astropy."""
    from lightcurve.sky.frames import astropy_offline

    u = astropy_offline()
    from astropy.coordinates import (
        GCRS,
        ITRS,
        TEME,
        CartesianRepresentation,
        EarthLocation,
        get_body,
    )
    from astropy.time import Time

    start = time.perf_counter()
    whole = np.floor(mjd)
    _, r, _ = tle.satrec.sgp4_array(whole + 2_400_000.5, mjd - whole)
    t = Time(mjd, format="mjd", scale="utc")
    teme = TEME(CartesianRepresentation(r.T * u.km), obstime=t)
    teme.transform_to(ITRS(obstime=t))
    teme.transform_to(GCRS(obstime=t))
    location = EarthLocation.from_geodetic(
        site.longitude_deg * u.deg, site.latitude_deg * u.deg, site.altitude_m * u.m
    )
    location.get_gcrs(t)
    get_body("sun", t)
    return time.perf_counter() - start


def speed() -> dict:
    iss = select_object(read_tles(CATALOGUE), 25544)[2]
    site = get_site("Zimmerwald")
    mjd = iss.epoch_mjd + np.arange(100_000) / 86_400.0
    _ours([iss], site, mjd[:100])  # imports and IERS tables
    ours = min(_ours([iss], site, mjd) for _ in range(3))
    ours_small = min(_ours([iss], site, mjd[:10_000]) for _ in range(3))
    baseline = _astropy_chain(iss, site, mjd[:10_000])
    return {
        "epochs": len(mjd),
        "seconds": ours,
        "budget_seconds": 5.0,
        "baseline": "astropy TEME->ITRS, TEME->GCRS, site and Sun at every epoch",
        "baseline_epochs": 10_000,
        "baseline_seconds": baseline,
        "ours_seconds_same_10k_epochs": ours_small,
        "speedup_per_epoch_vs_baseline": (baseline / 10_000) / (ours / len(mjd)),
    }


def accuracy() -> dict:
    from lightcurve.sky.tle_reference import compare_topocentric, skyfield_timescale

    ts = skyfield_timescale()
    catalogue = read_tles(CATALOGUE)
    sites = [get_site(name) for name in ("Kislovodsk", "Siding Spring", "Haleakala")]
    rng = np.random.default_rng(SEED)
    per_object = {}
    for norad in ACCURACY_OBJECTS:
        tle = select_object(catalogue, norad)[-1]
        mjd = tle.epoch_mjd + rng.uniform(-2.0, 2.0, 10_000)
        angle, distance = compare_topocentric(tle, sites, mjd, ts)
        per_object[tle.label] = {
            "max_angle_arcsec": float(angle.max()),
            "max_range_m": float(distance.max()),
        }
    return {
        "epochs_per_object": 10_000,
        "sites": [site.name for site in sites],
        "objects": per_object,
        "max_angle_arcsec": max(v["max_angle_arcsec"] for v in per_object.values()),
        "max_range_m": max(v["max_range_m"] for v in per_object.values()),
        "seed": SEED,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--skip-accuracy", action="store_true")
    args = parser.parse_args()
    result = {"benchmark": "tle_geometry", "speed": speed()}
    if not args.skip_accuracy:
        result["accuracy"] = accuracy()
    result["load_average"] = os.getloadavg()
    result["machine"] = machine_info()
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
