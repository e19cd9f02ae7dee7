"""Write a geometry file for an Earth-orbiting object seen from a ground site.

The object moves on a circular orbit (--geo LONGITUDE for a geostationary slot, or
--radius/--inclination/--raan/--arg-latitude); the Sun comes from astropy's built-in
ephemeris and the site rotates with the Earth (offline IERS data). Only epochs with the
object sunlit, above --min-elevation and the site in darkness (Sun below --max-sun-elevation)
are kept. The file has the observation-file columns without mag/mag_err and can be passed
to `lightcurve simulate`.
"""

from __future__ import annotations

import argparse

import numpy as np
import pandas as pd

from lightcurve import io
from lightcurve.ephemeris import CircularOrbit, Site, orbit_geometry
from lightcurve.observations import datetime_to_mjd

NAME = "geometry"
HELP = "write a geometry file (orbit + ground site) for simulate"
ORDER = 15


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--start", required=True, help="first epoch, ISO-8601 UTC")
    parser.add_argument("--duration", type=float, required=True, help="seconds")
    parser.add_argument("--cadence", type=float, default=1.0, help="seconds (default 1)")
    orbit = parser.add_mutually_exclusive_group(required=True)
    orbit.add_argument("--geo", type=float, metavar="LONGITUDE", help="geostationary, deg east")
    orbit.add_argument("--radius", type=float, help="circular orbit radius, km")
    parser.add_argument("--inclination", type=float, default=0.0, help="deg")
    parser.add_argument("--raan", type=float, default=0.0, help="deg")
    parser.add_argument("--arg-latitude", type=float, default=0.0, help="deg at --start")
    parser.add_argument(
        "--site",
        default="32.4434,-110.7881,2790",
        metavar="LAT,LON,ALT_M",
        help="geodetic site (default Mount Lemmon)",
    )
    parser.add_argument("--min-elevation", type=float, default=10.0, help="deg (default 10)")
    parser.add_argument("--max-sun-elevation", type=float, default=-12.0, help="deg (default -12)")
    parser.add_argument("--name", default="object", help="object name for the header")
    parser.add_argument("--out", required=True, help="output file (.csv or .parquet)")


def run(args: argparse.Namespace) -> int:
    if not (args.duration > 0 and args.cadence > 0):
        raise ValueError("--duration and --cadence must be positive seconds")
    try:
        start = datetime_to_mjd(pd.DatetimeIndex([pd.Timestamp(args.start, tz="UTC")]))[0]
    except ValueError as exc:
        raise ValueError(f"--start: cannot parse {args.start!r} as ISO-8601 ({exc})") from None
    try:
        lat, lon, alt = (float(v) for v in args.site.split(","))
    except ValueError:
        raise ValueError(f"--site expects LAT,LON,ALT_M, got {args.site!r}") from None
    site = Site(lat, lon, alt)
    if args.geo is not None:
        orbit = CircularOrbit.geostationary(args.geo, start)
    else:
        orbit = CircularOrbit(args.radius, args.inclination, args.raan, args.arg_latitude, start)
    mjd = start + np.arange(0.0, args.duration, args.cadence) / 86400.0
    geometry = orbit_geometry(
        orbit, site, mjd, args.name, args.min_elevation, args.max_sun_elevation
    )
    io.write(geometry, args.out)
    print(f"{args.out}: {len(geometry)} epochs of {args.name}")
    return 0
