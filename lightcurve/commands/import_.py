"""Import a photometry table as an observation file.

TABLE is plain text (comma, semicolon or whitespace separated, with or without a header
row, `#` comments) with a time column (--time-format iso|jd|mjd|unix, --time-scale
utc|tt|tdb) and a magnitude column (--mag-column, with --err-column or one --mag-err for
all rows). The geometry comes from the object's TLEs (--tle FILE [--norad N]) or from
topocentric coordinates recorded with each measurement: elevation, azimuth (from north
through east) and range (--alt-az-range-columns A,Z,R; --range-kind height when R is the
height above the WGS84 ellipsoid) or right ascension, declination (GCRS/J2000 axes) and
range (--ra-dec-range-columns RA,DEC,R); angles in degrees, distances in km. Columns are
named by header or by 1-based position. Every bad value is reported with its row, column and
line (or dropped with --drop-bad-rows); the output is a validated observation file, sorted
by time, with the Earth-shadow state, sunlit fraction, phase angle, range, elevation,
azimuth and airmass alongside.
"""

from __future__ import annotations

import argparse

from lightcurve.commands._args import add_band_options, band_of
from lightcurve.commands._satellite_args import (
    add_shadow_options,
    add_site,
    add_tle_options,
    warnings_to_stderr,
)
from lightcurve.commands._source import literal

NAME = "import"
HELP = "import a photometry table (times, magnitudes, TLEs or topocentric data) as observations"
ORDER = 12


def _three(text: str) -> tuple[str, str, str]:
    parts = tuple(p.strip() for p in text.split(","))
    if len(parts) != 3 or not all(parts):
        raise argparse.ArgumentTypeError(f"expected three comma-separated columns, got {text!r}")
    return parts


def add_arguments(parser: argparse.ArgumentParser) -> None:
    time_formats = literal("lightcurve.sky.epochs", "TIME_FORMATS")
    time_scales = literal("lightcurve.sky.epochs", "TIME_SCALES")
    delimiters = literal("lightcurve.io.tables", "DELIMITERS")
    parser.add_argument("table", metavar="TABLE", help="photometry table (text)")
    parser.add_argument(
        "--time-column", required=True, metavar="C", help="name or 1-based position"
    )
    parser.add_argument(
        "--time-format", required=True, choices=time_formats, help="how the time column is written"
    )
    parser.add_argument(
        "--time-scale", choices=time_scales, default="utc", help="time scale of the times"
    )
    parser.add_argument("--mag-column", required=True, metavar="C", help="magnitudes, mag")
    errors = parser.add_mutually_exclusive_group(required=True)
    errors.add_argument("--err-column", metavar="C", help="1-sigma magnitude errors, mag")
    errors.add_argument("--mag-err", type=float, metavar="SIGMA", help="one 1-sigma error, mag")
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--tle", metavar="FILE", help="TLE file of the object")
    source.add_argument(
        "--alt-az-range-columns",
        type=_three,
        metavar="A,Z,R",
        help="elevation and azimuth (deg, azimuth from north through east) and range (km)",
    )
    source.add_argument(
        "--ra-dec-range-columns",
        type=_three,
        metavar="RA,DEC,R",
        help="topocentric right ascension, declination (deg, GCRS/J2000 axes), range (km)",
    )
    add_tle_options(parser)
    parser.add_argument(
        "--range-kind",
        choices=("slant", "height"),
        default="slant",
        help="the R column of --alt-az-range-columns: the distance from the site (slant) "
        "or the height above the WGS84 ellipsoid (height), km",
    )
    add_site(parser)
    parser.add_argument(
        "--delimiter", choices=("auto", *delimiters), default="auto", help="column separator"
    )
    header = parser.add_mutually_exclusive_group()
    header.add_argument(
        "--header",
        dest="header",
        action="store_true",
        default=None,
        help="the first row is a header",
    )
    header.add_argument(
        "--no-header",
        dest="header",
        action="store_false",
        help="the first row is data (default: detected)",
    )
    parser.add_argument("--decimal", choices=(".", ","), default=".", help="decimal mark")
    add_shadow_options(parser, "flag", "")
    parser.add_argument(
        "--drop-bad-rows", action="store_true", help="drop rows with bad values and list them"
    )
    parser.add_argument(
        "--allow-duplicate-epochs",
        action="store_true",
        help="accept several rows at one time (e.g. several objects in one table)",
    )
    parser.add_argument("--name", help="object name for the header")
    add_band_options(
        parser,
        "recorded in the header: the inversion takes the Sun's magnitude in it (Willmer 2018)",
    )
    parser.add_argument(
        "--out", required=True, metavar="FILE", help="output file (.csv or .parquet)"
    )


def run(args: argparse.Namespace) -> int:
    from lightcurve import io
    from lightcurve.importing import Topocentric, import_photometry
    from lightcurve.io.tables import read_table
    from lightcurve.sky.epochs import TimeColumn
    from lightcurve.sky.sites import get_site

    table = read_table(args.table, args.delimiter, args.header, args.decimal)
    tles = None
    topocentric = None
    if args.tle:
        from lightcurve.sky.tle import read_tles, select_object

        tles = select_object(read_tles(args.tle), args.norad)
    else:
        if args.norad is not None:
            raise ValueError("--norad needs --tle")
        if args.alt_az_range_columns:
            topocentric = Topocentric("alt-az", args.alt_az_range_columns, args.range_kind)
        else:
            topocentric = Topocentric("ra-dec", args.ra_dec_range_columns, args.range_kind)
    with warnings_to_stderr(NAME):
        observations = import_photometry(
            table,
            args.time_column,
            TimeColumn(args.time_format, args.time_scale),
            args.mag_column,
            get_site(args.site),
            err_column=args.err_column,
            mag_err=args.mag_err,
            tles=tles,
            topocentric=topocentric,
            max_tle_age_days=args.max_tle_age,
            shadow_model=args.shadow_model,
            umbra=args.umbra,
            drop_bad_rows=args.drop_bad_rows,
            allow_duplicate_epochs=args.allow_duplicate_epochs,
            name=args.name,
            band=band_of(args),
        )
    io.write(observations, args.out)
    states = observations.table["shadow"].value_counts()
    shadowed = ", ".join(
        f"{int(states[s])} in the {s}" for s in ("penumbra", "umbra") if s in states
    )
    meta = observations.meta
    print(
        f"{args.out}: {len(observations)} measurements of {observations.name} from "
        f"{len(table)} rows"
        + (f" ({shadowed})" if shadowed else "")
        + (f"; dropped {meta['dropped_umbra']} in the umbra" if "dropped_umbra" in meta else "")
    )
    if observations.dropped:
        print(f"dropped {len(observations.dropped)} bad row(s):")
        for problem in observations.dropped[:20]:
            print(f"  row {problem.row}, column '{problem.column}': {problem.message}")
        if len(observations.dropped) > 20:
            print(f"  … and {len(observations.dropped) - 20} more")
    return 0
