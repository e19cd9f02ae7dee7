"""Write a geometry file for an Earth-orbiting object seen from a ground site.

The object moves on a circular orbit (--geo LONGITUDE for a geostationary slot, or
--radius/--inclination/--raan/--arg-latitude) or follows its TLEs (--tle FILE [--norad N]:
SGP4, the element set nearest in epoch per row); the Sun comes from astropy's built-in
ephemeris and the site (--site NAME or LAT,LON,ALT_M) rotates with the Earth (offline IERS
data). Epochs span --start/--duration/--cadence, or (with --tle) are those of an existing
observation or photometry file (--epochs-from FILE, whose other columns are kept). Over a
span only epochs with the object above --min-elevation and the site in darkness (Sun below
--max-sun-elevation) are kept, and epochs in the Earth's umbra are dropped (--umbra flag
keeps them; with --epochs-from they are kept unless --umbra drop). The file has the
observation-file columns without mag/mag_err (GCRS vectors, km; UTC epochs), the range,
elevation, azimuth and airmass at the site and, for TLEs, the shadow state, sunlit fraction
and phase angle; the object's geocentric GCRS position obj_x, obj_y, obj_z (km) and velocity
obj_vx, obj_vy, obj_vz (km/s) are written on both routes (attitude profiles need them). The
file can be passed to `lightcurve simulate`.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from lightcurve.commands._satellite_args import (
    add_shadow_options,
    add_site,
    add_tle_options,
    warnings_to_stderr,
)

NAME = "geometry"
HELP = "write a geometry file (circular orbit or TLEs + ground site) for simulate"
ORDER = 15

_SPAN_DEFAULTS = {"min_elevation": 10.0, "max_sun_elevation": -12.0}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--start", help="first epoch, ISO-8601 UTC (required without --epochs-from)"
    )
    parser.add_argument("--duration", type=float, help="seconds (required without --epochs-from)")
    parser.add_argument("--cadence", type=float, default=1.0, help="seconds")
    parser.add_argument(
        "--epochs-from",
        metavar="FILE",
        help="with --tle: the epochs (column 'epoch' or 'mjd', UTC) of an observation or "
        "photometry file (CSV, text or Parquet), instead of --start/--duration",
    )
    orbit = parser.add_mutually_exclusive_group(required=True)
    orbit.add_argument("--geo", type=float, metavar="LONGITUDE", help="geostationary, deg east")
    orbit.add_argument("--radius", type=float, help="circular orbit radius, km")
    orbit.add_argument("--tle", metavar="FILE", help="TLE file (two- or three-line records)")
    add_tle_options(parser)
    parser.add_argument("--inclination", type=float, default=0.0, help="deg")
    parser.add_argument("--raan", type=float, default=0.0, help="deg")
    parser.add_argument("--arg-latitude", type=float, default=0.0, help="deg at --start")
    add_site(parser, default="Mount Lemmon")
    parser.add_argument(
        "--min-elevation",
        type=float,
        help="deg (default: 10 over a span; none with --epochs-from)",
    )
    parser.add_argument(
        "--max-sun-elevation",
        type=float,
        help="deg (default: -12 over a span; none with --epochs-from)",
    )
    add_shadow_options(parser, None, "TLEs; default: drop over a span, flag with --epochs-from")
    parser.add_argument("--name", help="object name for the header (default: from the TLE)")
    parser.add_argument(
        "--out", required=True, metavar="FILE", help="output file (.csv or .parquet)"
    )


def _span(args: argparse.Namespace) -> np.ndarray:
    """UTC microseconds since MJD 0 of the epochs of --start/--duration/--cadence."""
    import pandas as pd

    from lightcurve.io.observations import MJD_EPOCH

    if args.start is None or args.duration is None:
        raise ValueError("give --start and --duration (or --epochs-from with --tle)")
    if not (args.duration > 0 and args.cadence > 0):
        raise ValueError("--duration and --cadence must be positive seconds")
    try:
        start = pd.Timestamp(args.start, tz="UTC")
    except ValueError as exc:
        raise ValueError(f"--start: cannot parse {args.start!r} as ISO-8601 ({exc})") from None
    start_us = (start - MJD_EPOCH) // pd.Timedelta(microseconds=1)
    steps = np.arange(0.0, args.duration, args.cadence)
    return start_us + np.round(steps * 1e6)


def _circular(args: argparse.Namespace) -> int:
    from lightcurve import io
    from lightcurve.sky.ephemeris import CircularOrbit, orbit_geometry
    from lightcurve.sky.epochs import MICROSECONDS_PER_DAY
    from lightcurve.sky.sites import get_site

    if args.epochs_from:
        raise ValueError("--epochs-from needs --tle")
    mjd = _span(args) / MICROSECONDS_PER_DAY
    site = get_site(args.site)
    if args.geo is not None:
        orbit = CircularOrbit.geostationary(args.geo, mjd[0])
    else:
        orbit = CircularOrbit(args.radius, args.inclination, args.raan, args.arg_latitude, mjd[0])
    min_elevation = _default(args.min_elevation, "min_elevation")
    max_sun = _default(args.max_sun_elevation, "max_sun_elevation")
    name = args.name or "object"
    geometry = orbit_geometry(orbit, site, mjd, name, min_elevation, max_sun)
    io.write(geometry, args.out)
    print(f"{args.out}: {len(geometry)} epochs" + (f" of {args.name}" if args.name else ""))
    return 0


def _default(value: float | None, key: str) -> float:
    return _SPAN_DEFAULTS[key] if value is None else value


def _tle(args: argparse.Namespace) -> int:
    import pandas as pd

    from lightcurve import io
    from lightcurve.io.observations import (
        GEOMETRY_COLUMNS,
        OBJECT_COLUMNS,
        OBSERVER_COLUMNS,
        SUN_COLUMNS,
        Observations,
        mjd_to_datetime,
        validate_table,
    )
    from lightcurve.sky.epochs import MICROSECONDS_PER_DAY, epoch_strings, read_epochs
    from lightcurve.sky.satellite_geometry import from_tle
    from lightcurve.sky.shadow_earth import shadow_events
    from lightcurve.sky.sites import get_site
    from lightcurve.sky.tle import read_tles, select_object

    tles = select_object(read_tles(args.tle), args.norad)
    site = get_site(args.site)
    if args.epochs_from:
        if args.start is not None or args.duration is not None:
            raise ValueError("give either --epochs-from or --start/--duration")
        carried, meta, micro = read_epochs(args.epochs_from)
        carried = carried.drop(
            columns=[
                c
                for c in (*SUN_COLUMNS, *OBSERVER_COLUMNS, *GEOMETRY_COLUMNS, *OBJECT_COLUMNS)
                if c in carried
            ]
        )
        min_elevation, max_sun = args.min_elevation, args.max_sun_elevation
        umbra = args.umbra or "flag"
    else:
        carried, meta, micro = None, {}, _span(args)
        min_elevation = _default(args.min_elevation, "min_elevation")
        max_sun = _default(args.max_sun_elevation, "max_sun_elevation")
        umbra = args.umbra or "drop"
    mjd = micro / MICROSECONDS_PER_DAY
    with warnings_to_stderr(NAME):
        geometry = from_tle(tles, site, mjd, args.max_tle_age, args.shadow_model)
    elevation = geometry.horizontal[0]
    keep = np.ones(len(mjd), dtype=bool)
    counts = {}
    if carried is not None and np.any(elevation < 0):
        row = int(np.flatnonzero(elevation < 0)[0]) + 1
        raise ValueError(
            f"{args.epochs_from}, row {row}: the object is below the horizon "
            f"({elevation[row - 1]:.1f} deg) at this epoch: wrong site, epochs or TLE?"
        )
    if min_elevation is not None:
        if min_elevation < 0:
            raise ValueError("--min-elevation must be >= 0 deg (the object must be visible)")
        counts[f"below {min_elevation:g} deg elevation"] = ~(elevation >= min_elevation) & keep
        keep &= elevation >= min_elevation
    if max_sun is not None:
        dark = geometry.sun_elevation_deg <= max_sun
        counts[f"with the Sun above {max_sun:g} deg"] = ~dark & keep
        keep &= dark
    shadow = geometry.shadow
    if umbra == "drop":
        counts["in the umbra"] = shadow.in_umbra & keep
        keep &= ~shadow.in_umbra
    if not keep.any():
        raise ValueError(
            "no epoch is left: " + ", ".join(f"{int(m.sum())} {why}" for why, m in counts.items())
        )
    events = shadow_events(geometry.mjd, geometry.object_gcrs, geometry.sun_gcrs, args.shadow_model)
    geometry = geometry.subset(keep)
    table = geometry.table()
    table.insert(0, "epoch", epoch_strings(micro[keep]))
    if carried is not None:
        table = pd.concat([table, carried.loc[keep].reset_index(drop=True)], axis=1)
    name = args.name or meta.get("object") or tles[0].name or f"NORAD {tles[0].norad}"
    meta = dict(meta)
    meta.update(
        {
            "object": name,
            "frame": "GCRS",
            "site": site.label,
            "target": "satellite",
            "norad": str(tles[0].norad),
            "geometry": f"SGP4 from {len(tles)} element set(s) in {Path(args.tle).name}",
            "shadow_model": args.shadow_model,
        }
    )
    dropped_umbra = counts.get("in the umbra")
    if dropped_umbra is not None and dropped_umbra.any():
        meta["dropped_umbra"] = str(int(dropped_umbra.sum()))
    canonical = validate_table(table, args.out, meta, require_magnitudes=False)
    io.write(Observations(canonical, meta), args.out)
    dropped = ", ".join(f"{int(m.sum())} {why}" for why, m in counts.items() if m.any())
    penumbra = int(np.sum(table["shadow"] == "penumbra"))
    print(
        f"{args.out}: {len(table)} epochs of {name}"
        + (f" ({penumbra} in the penumbra)" if penumbra else "")
        + (f"; dropped {dropped}" if dropped else "")
    )
    for event in events[:8]:
        when = mjd_to_datetime(np.array([event.mjd]))[0]
        print(f"  {event.kind}: {when:%Y-%m-%dT%H:%M:%S.%f}"[:-3] + " UTC")
    return 0


def run(args: argparse.Namespace) -> int:
    if args.tle is None:
        if args.norad is not None:
            raise ValueError("--norad needs --tle")
        return _circular(args)
    return _tle(args)
