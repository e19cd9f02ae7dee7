"""Argument types and options shared by the command modules (vectors, inertia, progress,
observation files and output folders, scenario studies)."""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from lightcurve.commands._source import literal

if TYPE_CHECKING:  # numpy is imported where a value is parsed: the top-level parser
    import numpy as np  # (``lightcurve --version``, ``--threads``) stays free of it


def float_vector(*sizes: int) -> Callable[[str], np.ndarray]:
    """Argparse type for comma-separated floats with one of the given lengths.

    Parameters
    ----------
    *sizes : int
        Accepted numbers of components.

    Returns
    -------
    callable
        Converts ``"1,2,3"`` to a float array, or raises :class:`argparse.ArgumentTypeError`.
    """

    def parse(text: str) -> np.ndarray:
        import numpy as np

        try:
            values = np.array([float(v) for v in text.split(",")])
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"expected {' or '.join(map(str, sizes))} comma-separated numbers, got {text!r}"
            ) from None
        if values.size not in sizes:
            raise argparse.ArgumentTypeError(
                f"expected {' or '.join(map(str, sizes))} comma-separated numbers, "
                f"got {values.size} in {text!r}"
            )
        if not np.all(np.isfinite(values)):
            raise argparse.ArgumentTypeError(f"values must be finite, got {text!r}")
        return values

    return parse


def positive_int(text: str) -> int:
    """Argparse type for a count of at least 1 (``--runs``)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


#: Largest accepted ``| |q| − 1 |`` of a quaternion typed by hand (rounded components).
QUATERNION_NORM_TOLERANCE = 0.01


def adjustment_list(text: str) -> tuple[str, ...]:
    """``--estimate``: comma-separated model adjustments, or ``none`` (the names are checked
    with the rest of the request, see :class:`lightcurve.inversion.InversionOptions`)."""
    if text.strip().lower() == "none":
        return ()
    names = tuple(dict.fromkeys(part.strip() for part in text.split(",") if part.strip()))
    if not names:
        raise argparse.ArgumentTypeError(f"expected adjustments or 'none', got {text!r}")
    return names


def unit_quaternion(text: str) -> np.ndarray:
    """Argparse type for a unit quaternion ``q1,q2,q3,q4`` (scalar last).

    Components rounded by hand are accepted and normalised (norm within
    :data:`QUATERNION_NORM_TOLERANCE` of 1); anything further off is an error, so that a
    wrong value (``1,2,3,4``) is not silently turned into some rotation.
    """
    q = float_vector(4)(text)
    norm = math.sqrt(float(q @ q))
    if not math.isfinite(norm) or abs(norm - 1.0) > QUATERNION_NORM_TOLERANCE:
        raise argparse.ArgumentTypeError(
            f"expected a unit quaternion q1,q2,q3,q4 (scalar last), got norm {norm:.4g} in {text!r}"
        )
    return q / norm


def inertia_tensor(text: str) -> np.ndarray:
    """Argparse type for ``Jxx,Jyy,Jzz[,Jxy,Jxz,Jyz]`` → symmetric 3×3 tensor.

    The tensor is not checked for physical validity here; the attitude core's
    ``validate_inertia`` does that with a message naming the violated inequality.
    """
    import numpy as np

    values = float_vector(3, 6)(text)
    jxx, jyy, jzz = values[:3]
    jxy, jxz, jyz = values[3:] if values.size == 6 else (0.0, 0.0, 0.0)
    return np.array([[jxx, jxy, jxz], [jxy, jyy, jyz], [jxz, jyz, jzz]])


def add_scenario_arguments(
    parser: argparse.ArgumentParser,
    scenario_help: str,
    *,
    runs: int | None = None,
    seed: int | None = None,
    seed_help: str = "random seed",
) -> None:
    """The arguments of a scenario study: ``SCENARIO``, ``--out DIR`` and optionally
    ``--runs`` and ``--seed``.

    Parameters
    ----------
    parser : argparse.ArgumentParser
    scenario_help : str
        Help of the positional scenario TOML file.
    runs : int, optional
        Default of ``--runs`` (Monte Carlo runs); None: no ``--runs`` option.
    seed : int, optional
        Default of ``--seed``; None: no ``--seed`` option.
    seed_help : str
        Help of ``--seed``.
    """
    parser.add_argument("scenario", type=Path, help=scenario_help)
    add_output_folder(parser)
    if runs is not None:
        parser.add_argument("--runs", type=positive_int, default=runs, help="Monte Carlo runs")
    if seed is not None:
        parser.add_argument("--seed", type=int, default=seed, help=seed_help)


def brdf_parameters(items: Sequence[str]) -> dict[str, float]:
    """``--param KEY=VALUE`` strings → BRDF parameters.

    Raises
    ------
    ValueError
        An item that is not ``key=number``.
    """
    params = {}
    for item in items:
        key, sep, value = item.partition("=")
        try:
            if not sep or not key.strip():
                raise ValueError
            params[key.strip()] = float(value)
        except ValueError:
            raise ValueError(f"--param: expected key=value with a number, got {item!r}") from None
    return params


def add_observation_files(parser: argparse.ArgumentParser) -> None:
    """Add the positional ``FILE …``: one or more observation files (``args.files``)."""
    parser.add_argument("files", nargs="+", metavar="FILE", help="observation files")


def add_output_folder(parser: argparse.ArgumentParser) -> None:
    """Add the required ``--out DIR``: the output folder (``args.out``, a path)."""
    parser.add_argument("--out", type=Path, required=True, metavar="DIR", help="output folder")


def add_band_options(parser: argparse.ArgumentParser, effect: str) -> None:
    """Add ``--band NAME`` and ``--magnitude-system vega|ab`` (``args.band``,
    ``args.magnitude_system``); ``effect`` says what the band does in this command."""
    parser.add_argument(
        "--band",
        help=f"photometric band of the magnitudes (V, B, K; LSST u g r i z y): {effect}",
    )
    parser.add_argument(
        "--magnitude-system",
        choices=("vega", "ab"),
        default="vega",
        help="magnitude system of --band",
    )


def add_earthshine_option(parser: argparse.ArgumentParser) -> None:
    """Add ``--earthshine auto|on|off`` (``args.earthshine``): the Earth's reflected light in
    the model (:mod:`lightcurve.photometry.earthshine`)."""
    parser.add_argument(
        "--earthshine",
        choices=literal("lightcurve.photometry.earthshine", "EARTHSHINE_MODES"),
        default="auto",
        help="the light of a Lambertian Earth (albedo 0.29): auto adds it when the files have "
        "the obj_* columns and the object is below 27 970 km (where it can reach 1%% of the "
        "Sun's light); on needs the obj_* columns; off",
    )


def band_of(args: argparse.Namespace) -> tuple[str, str] | None:
    """``(band, system)`` of ``--band``/``--magnitude-system``, checked; None without
    ``--band``."""
    if args.band is None:
        return None
    from lightcurve.photometry.bands import sun_magnitude

    sun_magnitude(args.band, args.magnitude_system)  # an unknown band fails here
    return args.band, args.magnitude_system


def add_false_alarm_option(parser: argparse.ArgumentParser, help_text: str) -> None:
    """Add ``--false-alarm``: the glint detector's false-alarm probability (default 1e-3)."""
    parser.add_argument("--false-alarm", type=float, default=1e-3, help=help_text)


def add_progress_option(parser: argparse.ArgumentParser, what: str) -> None:
    """``--progress/--no-progress``: a tqdm bar of ``what`` on stderr.

    Without either flag the bar shows when stderr is a terminal and ``-q`` was not given
    (:func:`show_progress`).
    """
    parser.add_argument(
        "--progress",
        action=argparse.BooleanOptionalAction,
        default=None,
        help=f"progress bar of {what} on stderr (default: when stderr is a terminal and no -q)",
    )


def show_progress(args: argparse.Namespace) -> bool:
    """Whether to draw a progress bar: ``--progress``/``--no-progress``, else a TTY without -q."""
    if getattr(args, "progress", None) is not None:
        return bool(args.progress)
    return sys.stderr.isatty() and not getattr(args, "quiet", 0)


def progress_bar(args: argparse.Namespace, total: int, desc: str, unit: str) -> Any:
    """A tqdm bar on stderr (disabled unless :func:`show_progress`); use as a context manager."""
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit=unit, disable=not show_progress(args), file=sys.stderr)
