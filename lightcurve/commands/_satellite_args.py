"""Options shared by the commands that handle Earth satellites (`geometry --tle`, `import`)."""

from __future__ import annotations

import argparse
import sys
import warnings
from collections.abc import Iterator
from contextlib import contextmanager

from lightcurve.sky.shadow_earth import MODELS
from lightcurve.sky.tle import DEFAULT_MAX_AGE_DAYS


def add_site(parser: argparse.ArgumentParser, default: str | None = None) -> None:
    """``--site NAME|LAT,LON,ALT_M`` (required without a default)."""
    parser.add_argument(
        "--site",
        default=default,
        required=default is None,
        metavar="NAME|LAT,LON,ALT_M",
        help="observatory name (built-in table: docs/geometry.md) or geodetic deg,deg,m",
    )


def add_tle_options(parser: argparse.ArgumentParser) -> None:
    """``--norad`` and ``--max-tle-age`` (``--tle`` itself belongs to each command's group)."""
    parser.add_argument("--norad", help="catalogue number of the object in the TLE file")
    parser.add_argument(
        "--max-tle-age",
        type=float,
        default=DEFAULT_MAX_AGE_DAYS,
        metavar="DAYS",
        help="warn for epochs farther than this from their TLE's epoch, days",
    )


def add_shadow_options(
    parser: argparse.ArgumentParser, umbra_default: str | None, umbra_help: str
) -> None:
    """``--umbra drop|flag`` and ``--shadow-model conical|cylindrical``."""
    parser.add_argument(
        "--umbra",
        choices=("drop", "flag"),
        default=umbra_default,
        help="epochs with the object in the Earth's umbra: drop them, or keep them flagged "
        "in the 'shadow' column" + (f" ({umbra_help})" if umbra_help else ""),
    )
    parser.add_argument(
        "--shadow-model",
        choices=MODELS,
        default="conical",
        help="Earth-shadow model (conical: with penumbra)",
    )


@contextmanager
def warnings_to_stderr(command: str) -> Iterator[None]:
    """Print the warnings raised inside as ``lightcurve COMMAND: warning: …`` lines."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        yield
    for warning in caught:
        print(f"lightcurve {command}: warning: {warning.message}", file=sys.stderr)
